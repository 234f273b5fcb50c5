#!/usr/bin/env bash
# One entry point for a fresh Debian 12 machine:
#   tools/lab.sh demo   install what is missing, build, run the main job
#   tools/lab.sh test   install what is missing, build plain and sanitized, run every test
#   tools/lab.sh deps   only install what is missing
# Idempotent: packages already present are not touched, builds are incremental.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$here"
jobs=$(nproc 2>/dev/null || echo 2)

packages=(
  build-essential cmake pkg-config
  libglib2.0-dev libjson-glib-dev libsystemd-dev
  libaravis-dev aravis-tools aravis-tools-cli libusb-1.0-0-dev
  libmodbus-dev mbpoll socat python3-pymodbus python3-serial python3-serial-asyncio
  libgpiod-dev gpiod
  libopencv-dev
  python3-numpy python3-matplotlib
  clang libclang-rt-14-dev valgrind
  libtiff-dev libhdf5-dev libsoup-3.0-dev
  chromium python3-h5py python3-prometheus-client python3-websocket python3-tifffile
  scdoc groff-base systemd           # man pages, their check, systemd-analyze verify
)

install_deps() {
  local missing=()
  for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  echo "lab.sh: installing ${missing[*]}"
  local sudo=()
  [ "$(id -u)" -eq 0 ] || sudo=(sudo)
  "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -qq
  "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}"
}

build() { # build DIR [cmake args...]
  local dir=$1; shift
  cmake -S . -B "$dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo "$@" >/dev/null
  cmake --build "$dir" -j "$jobs"
}

case "${1:-}" in
  deps) install_deps ;;
  demo)
    install_deps
    build build -DDESCATTER_WERROR=ON
    exec tools/demo.sh build out
    ;;
  test)
    install_deps
    # Sanitized suite first, the plain one last so that its summary closes the output.
    build build-asan -DDESCATTER_SANITIZE=ON -DDESCATTER_WERROR=ON
    echo "== test suite under AddressSanitizer + UndefinedBehaviorSanitizer =="
    (cd build-asan && ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
       ctest --output-on-failure -j "$jobs" -LE "nosan|bench")
    echo "== fuzzing: each libFuzzer target for 20 s (tools/fuzz.sh 600 for a long run) =="
    tools/fuzz.sh 20
    build build -DDESCATTER_WERROR=ON
    echo "== test suite, plain build =="
    cd build && ctest --output-on-failure -j "$jobs"
    ;;
  *) echo "usage: tools/lab.sh demo|test|deps" >&2; exit 2 ;;
esac
