#!/usr/bin/env bash
# The main job on the simulated lab: descatterd on its built-in simulated devices, one capture
# through descatterctl, images written to OUT (default out/):
#   OUT/transmissive.tiff, scattered.tiff (float32), mask.png, *-preview.png (8-bit, to look at),
#   result.json (settings, frame accounting, timings)
# and an offline separation of a rendered phase set with `descatterctl separate`.
# Usage: tools/demo.sh BUILD_DIR [OUT]
set -euo pipefail
build=$(cd "${1:?usage: tools/demo.sh BUILD_DIR [OUT]}" && pwd)
out=${2:-out}
mkdir -p "$out"
out=$(cd "$out" && pwd)
# The demo's own folders from an earlier run go first: capture refuses to write into a folder
# that holds files, so a second `tools/lab.sh demo` would otherwise fail. Nothing else in OUT
# is touched.
rm -rf "$out/capture" "$out/capture-sine" "$out/phases" "$out/separated"
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
# No DESCATTER_DATA_DIR: the build tree's programs find the scenes and the operating model in
# etc/ of the source tree by themselves (the marker build/bin/descatter-source-data-dir).
run=$(mktemp -d)
trap 'kill "$pid" 2>/dev/null || true; wait "$pid" 2>/dev/null || true; rm -rf "$run"' EXIT

sock="$run/descatterd.sock"
"$build/bin/descatterd" --sim --socket "$sock" --no-socket-activation >"$run/daemon.log" 2>&1 &
pid=$!
ctl() { "$build/bin/descatterctl" --address "$sock" "$@"; }

# The socket first: a capture sent while the devices still open (the simulated devices render
# their scattering kernels first) waits in the daemon's queue and runs once they are open, or
# fails with `device_error` and the reason when they cannot open. So only the socket is awaited,
# every 0.1 s; the demo gives up after 30 s with the daemon's log.
deadline=$((SECONDS + 30))
until ctl status --json >/dev/null 2>&1; do
  kill -0 "$pid" 2>/dev/null || { cat "$run/daemon.log"; echo "demo: descatterd exited" >&2; exit 1; }
  if [ "$SECONDS" -ge "$deadline" ]; then
    cat "$run/daemon.log"
    echo "demo: descatterd has no socket after 30 s" >&2
    exit 1
  fi
  sleep 0.1
done
echo "== descatterd on the simulated lab =="
ctl hello
echo "== capture: 8 phases, max/min estimator =="
ctl capture --phases 8 --out "$out/capture" || { cat "$run/daemon.log"; exit 1; }
echo "== capture: 8 phases, sine estimator =="
ctl capture --phases 8 --estimator sine --quiet --out "$out/capture-sine"
ctl status | grep -E '^(sets|frames):'
kill -TERM "$pid"; wait "$pid" || true

echo "== offline: descatter-sim render + descatterctl separate =="
scene="$here/etc/scenes/milk-disc.scene"
"$build/bin/descatter-sim" render "$scene" --phases 8 --out "$out/phases"
"$build/bin/descatterctl" separate "$out/phases" --out "$out/separated"
echo
echo "demo: images in $out:"
(cd "$out" && ls capture/*.png capture/*.tiff separated/* | sed 's/^/  /')
