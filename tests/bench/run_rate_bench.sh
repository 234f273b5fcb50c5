#!/bin/sh
# Runs a GigE Vision rate benchmark the way docs/benchmarks.md quotes it, as root:
#   - in a private network namespace (the fake camera binds UDP 127.0.0.1:3956);
#   - with real-time priority SCHED_RR 2 for the benchmark and everything it starts (ceiling
#     loop, daemon, and the fake camera's thread; DS_BENCH_CAMERA_PRIORITY=below gives that
#     thread priority 1: tests/bench/fake_rig.c), unless DS_BENCH_SCHED=other. On a shared,
#     loaded machine a receiving thread that waits for a CPU lets the UDP receive buffer
#     overflow (net.core.rmem_max caps it; 4 MiB on the development VM, less than a 4 MP
#     frame), and every lost packet then costs the stream's 100 ms frame retention: the rates
#     measure the queue for the CPU instead of the software. A quiet machine gives the same
#     figures either way;
#   - in a session of its own whose scheduling group (autogroup) gets nice DS_BENCH_NICE
#     (default -10), which is what shares the CPU between sessions when the priority is not
#     real-time (`nice` on the processes alone does not shield them from other sessions);
#   - as the unprivileged user nobody (run_unprivileged.sh), as the service runs.
#   - with net.core.rmem_max at least DS_BENCH_RMEM_MAX (default 67108864, what
#     systemd/60-descatter-gige.conf installs with the package) for the run, restored after:
#     Aravis asks for a receive buffer of one frame, which the kernel caps at rmem_max (4 MiB on
#     the development VM, half a 4 MP Mono16 frame), and the benchmark's "UDP receive-buffer
#     drops" showed that the transport losses were that buffer overflowing. The setting is the
#     host's (a network namespace cannot change it). DS_BENCH_RMEM_MAX=0 leaves it alone.
# It is a short run (minutes); RT throttling (kernel.sched_rt_runtime_us) still leaves the
# other users 5 % of each CPU while it runs.
# Usage: sudo tests/bench/run_rate_bench.sh build/tests/bench/bench-daemon-rate [ARGS...]
set -e
if [ "$(id -u)" -ne 0 ]; then
  echo "run_rate_bench.sh: needs root (network namespace, scheduling); run it with sudo" >&2
  exit 2
fi
here=$(cd "$(dirname "$0")" && pwd)
# The daemon finds the operating model in the source tree, as under ctest (tests/CMakeLists.txt,
# DS_TEST_ENV; daemon/operating/data_dir.h), not under the install prefix.
DESCATTER_DATA_DIR=${DESCATTER_DATA_DIR:-$(cd "$here/../../etc" && pwd)}
export DESCATTER_DATA_DIR
echo "run_rate_bench.sh: DESCATTER_DATA_DIR=$DESCATTER_DATA_DIR"
prog=$(cd "$(dirname "$1")" && pwd)/$(basename "$1")
shift
nice_value=${DS_BENCH_NICE:--10}
case ${DS_BENCH_SCHED:-rr} in
  rr) sched="chrt --rr 2" ;;
  other) sched="" ;;
  *) echo "run_rate_bench.sh: DS_BENCH_SCHED is rr or other" >&2; exit 2 ;;
esac
rmem_want=${DS_BENCH_RMEM_MAX:-67108864}
rmem_was=$(cat /proc/sys/net/core/rmem_max)
if [ "$rmem_want" -gt "$rmem_was" ]; then
  echo "run_rate_bench.sh: net.core.rmem_max $rmem_was -> $rmem_want for this run (restored after)"
  trap 'echo "$rmem_was" > /proc/sys/net/core/rmem_max' EXIT
  trap 'exit 130' INT TERM
  echo "$rmem_want" > /proc/sys/net/core/rmem_max
else
  echo "run_rate_bench.sh: net.core.rmem_max $rmem_was"
fi
$sched setsid -w unshare -n sh -c '
  ip link set lo up
  echo "run_rate_bench.sh: scheduling: $(chrt -p $$ | sed -n "1s/.*: //p"), priority $(chrt -p $$ | sed -n "2s/.*: //p")"
  if echo "$0" > /proc/self/autogroup 2>/dev/null; then
    echo "run_rate_bench.sh: scheduling group: $(cat /proc/self/autogroup)"
  fi
  exec "$@"' "$nice_value" "$here/run_unprivileged.sh" "$prog" "$@"
