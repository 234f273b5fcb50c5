#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (+ ASan/UBSan) and runs each for a bounded time.
#   tools/fuzz.sh [SECONDS_PER_TARGET]   (default 60; CI runs 20)
# New inputs go to a scratch corpus seeded from tests/fuzz/corpus/<name>; a crash fails the
# run and leaves its input in build-fuzz/crashes/<name>/ — fix the bug, then copy the input
# into tests/fuzz/corpus/<name>/ so the ordinary test suite replays it forever.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$here"
seconds=${1:-60}
CC=clang CXX=clang++ cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DDESCATTER_FUZZ=ON -DDESCATTER_SANITIZE=ON >/dev/null
targets=$(cd tests/fuzz && ls fuzz_*.c | sed 's/^fuzz_//; s/\.c$//')
built=()
for t in $targets; do
  if cmake --build build-fuzz --target "fuzz-$t" -j "$(nproc)" >/dev/null 2>build-fuzz/build-$t.log; then
    built+=("$t")
  else
    echo "fuzz.sh: fuzz-$t does not build:" >&2; cat build-fuzz/build-$t.log >&2; exit 1
  fi
done
status=0
for t in "${built[@]}"; do
  work=build-fuzz/corpus/$t; crashes=build-fuzz/crashes/$t
  mkdir -p "$work" "$crashes"
  cp -n tests/fuzz/corpus/$t/* "$work/" 2>/dev/null || true
  echo "== fuzz-$t for ${seconds}s =="
  if ! ASAN_OPTIONS=detect_leaks=1 build-fuzz/tests/fuzz/fuzz-$t -max_total_time="$seconds" \
        -max_len=65536 -artifact_prefix="$crashes/" -print_final_stats=1 "$work" 2>build-fuzz/fuzz-$t.log; then
    echo "fuzz.sh: fuzz-$t found a crash (input in $crashes):" >&2
    tail -40 build-fuzz/fuzz-$t.log >&2
    status=1
  else
    grep -E "stat::number_of_executed_units|stat::peak_rss_mb" build-fuzz/fuzz-$t.log || true
  fi
done
exit $status
