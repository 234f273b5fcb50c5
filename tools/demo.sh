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
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
# The build tree's programs find the scenes and the operating model in etc/ (installed ones in
# their data dir).
export DESCATTER_DATA_DIR="$here/etc"
run=$(mktemp -d)
trap 'kill "$pid" 2>/dev/null || true; wait "$pid" 2>/dev/null || true; rm -rf "$run"' EXIT

sock="$run/descatterd.sock"
"$build/bin/descatterd" --sim --socket "$sock" --no-socket-activation >"$run/daemon.log" 2>&1 &
pid=$!
ctl() { "$build/bin/descatterctl" --address "$sock" "$@"; }

# Ready when `status` says so (the simulated devices render their scattering kernels first).
for _ in $(seq 600); do
  if ctl status 2>/dev/null | grep -q '"ready" : true'; then break; fi
  kill -0 "$pid" 2>/dev/null || { cat "$run/daemon.log"; echo "demo: descatterd exited" >&2; exit 1; }
  sleep 0.2
done
echo "== descatterd on the simulated lab =="
ctl hello
echo "== capture: 8 phases, max/min estimator =="
ctl capture --phases 8 --out "$out/capture"
echo "== capture: 8 phases, sine estimator =="
ctl capture --phases 8 --estimator sine --quiet --out "$out/capture-sine"
ctl status | grep -E '"(sets_done|acquired|folded|dropped|set)"' || true
kill -TERM "$pid"; wait "$pid" || true

echo "== offline: descatter-sim render + descatterctl separate =="
scene="$here/etc/scenes/milk-disc.scene"
"$build/bin/descatter-sim" render "$scene" --phases 8 --out "$out/phases"
"$build/bin/descatterctl" separate "$out/phases" --out "$out/separated"
echo
echo "demo: images in $out:"
(cd "$out" && ls capture/*.png capture/*.tiff separated/* | sed 's/^/  /')
