#!/usr/bin/env bash
# The Debian packages of build-deb/ installed on this machine with apt-get, then used as a lab
# would, with the source tree out of reach (a private mount namespace lays an empty tmpfs over
# it, so nothing can fall back on etc/ or build/): tools/package_smoke.sh. The packages are
# purged at the end, as a check of their removal and to leave the machine as it was.
#   tools/package_test.sh DEBDIR
set -euo pipefail
debdir=$(cd "$1" && pwd)
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
sudo=()
[ "$(id -u)" -eq 0 ] || sudo=(sudo)
names=(descatter-data descatterd descatter-tools python3-descatter)
debs=()
for n in "${names[@]}"; do
  debs+=("$(ls "$debdir/${n}"_*.deb)")
done

purge() {
  "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get purge -y -qq "${names[@]}" >/dev/null 2>&1 || true
}
trap purge EXIT
echo "package test: apt-get install ${debs[*]##*/}"
"${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends --reinstall \
  "${debs[@]}" >"$debdir/install.log" 2>&1 || { cat "$debdir/install.log"; exit 1; }

describe=$(git -C "$here" describe --always --dirty --tags)
# The smoke test is read before the tree disappears; it runs with a clean environment.
"${sudo[@]}" unshare -m bash -c 'mount -t tmpfs none "$1" && shift && exec "$@"' _ "$here" \
  env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin LANG=C.UTF-8 HOME=/root \
      SOURCE_TREE="$here" EXPECTED_GIT="$describe" bash -s <"$here/tools/package_smoke.sh"

purge
trap - EXIT
for n in "${names[@]}"; do
  if dpkg-query -W -f='${Status}' "$n" 2>/dev/null | grep -q installed; then
    echo "package test: FAIL $n still installed after purge" >&2
    exit 1
  fi
done
[ ! -e /etc/descatterd/descatterd.conf ] || { echo "package test: FAIL purge left /etc/descatterd" >&2; exit 1; }
echo "package test: ok   purged"
