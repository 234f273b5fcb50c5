#!/bin/sh
# Runs a command as the unprivileged user `nobody` when started as root: the service runs
# unprivileged, and as root Aravis receives GigE Vision through a packet socket whose 5 ms ring
# timeout would falsify rate figures. When nobody cannot reach the program (a build tree under
# a private home), it runs as is and says so; the benchmark then prints that it ran as root.
# Usage: run_unprivileged.sh COMMAND [ARGS...]
if [ "$(id -u)" -eq 0 ] && command -v setpriv >/dev/null 2>&1 && id nobody >/dev/null 2>&1; then
  as_nobody="setpriv --reuid=nobody --regid=$(id -g nobody) --clear-groups"
  if $as_nobody sh -c 'test -x "$0"' "$1" 2>/dev/null; then
    exec $as_nobody "$@"
  fi
  echo "run_unprivileged.sh: nobody cannot run $1; running as root" >&2
fi
exec "$@"
