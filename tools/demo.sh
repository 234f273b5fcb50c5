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

# Ready when the status document says so (the simulated devices render their scattering
# kernels first): its "ready" member parsed as JSON, not the text summary's wording. Polled
# every 0.2 s, so the demo goes on as soon as the devices are open; it gives up after 120 s
# with the daemon's log rather than capturing from a daemon that is not ready.
ready() {
  ctl status --json 2>/dev/null |
    /usr/bin/python3 -c 'import json, sys; sys.exit(0 if json.load(sys.stdin).get("ready") is True else 1)' \
      2>/dev/null
}
deadline=$((SECONDS + 120))
until ready; do
  kill -0 "$pid" 2>/dev/null || { cat "$run/daemon.log"; echo "demo: descatterd exited" >&2; exit 1; }
  if [ "$SECONDS" -ge "$deadline" ]; then
    cat "$run/daemon.log"
    echo "demo: descatterd not ready after 120 s: $(ctl status --json 2>&1 | grep not_ready_reason)" >&2
    exit 1
  fi
  sleep 0.2
done
echo "== descatterd on the simulated lab =="
ctl hello
echo "== capture: 8 phases, max/min estimator =="
ctl capture --phases 8 --out "$out/capture"
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
