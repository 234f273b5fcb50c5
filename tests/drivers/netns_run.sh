#!/bin/sh
# Runs a command in a private network namespace with only loopback up, when this machine allows
# it (root, `unshare -n`, `ip`), else as is. UDP 127.0.0.1:3956 then belongs to the test alone:
# a GigE Vision camera left running by something else cannot answer in its place. Loopback also
# gets 127.0.0.2, for a second camera (a GigE Vision camera serves on an interface address).
# Usage: netns_run.sh COMMAND [ARGS...]
if [ "$(id -u)" -eq 0 ] && command -v unshare >/dev/null 2>&1 && command -v ip >/dev/null 2>&1 &&
   unshare -n ip link set lo up 2>/dev/null; then
  exec unshare -n sh -c 'ip link set lo up && ip addr add 127.0.0.2/8 dev lo && exec "$@"' netns_run "$@"
fi
exec "$@"
