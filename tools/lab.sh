#!/usr/bin/env bash
# One entry point for a fresh Debian 12 machine:
#   tools/lab.sh demo   install what is missing, build, run the main job
#   tools/lab.sh test   install what is missing, build plain and sanitized, run every test
#   tools/lab.sh deps   only install what is missing
#   tools/lab.sh package  build the Debian packages into build-deb/ (debhelper, lintian)
#   tools/lab.sh package-test  build them, install them with apt-get and test the installed
#                              system with the source tree hidden (tools/package_test.sh)
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
  python3-venv python3-setuptools python3-wheel python3-mypy   # pip install daemon/python, mypy
  clang libclang-rt-14-dev valgrind
  libtiff-dev libhdf5-dev libpng-dev libsoup-3.0-dev
  prometheus                         # a real server scraping /metrics in the tests (and promtool)
  chromium python3-h5py python3-prometheus-client python3-websocket python3-tifffile python3-silx
  scdoc groff-base systemd           # man pages, their check, systemd-analyze verify
  debhelper dh-python lintian        # the Debian packages (tools/lab.sh package)
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

package() { # the Debian packages, from a clean copy of the tracked tree, into build-deb/
  local version changelog out=build-deb
  version=$(sed -n 's/^project(descatter VERSION \([0-9.]*\).*/\1/p' CMakeLists.txt)
  changelog=$(dpkg-parsechangelog -S Version)
  if [ "$version" != "$changelog" ]; then
    echo "lab.sh: debian/changelog says $changelog, CMakeLists.txt $version: add a changelog entry" >&2
    return 1
  fi
  rm -rf "$out" && mkdir -p "$out/descatter-$version"
  git ls-files -z --cached --others --exclude-standard |
    tar --null -T - --ignore-failed-read -cf - 2>/dev/null | tar -xf - -C "$out/descatter-$version"
  echo "== Debian packages (build-deb/) =="
  (cd "$out/descatter-$version" &&
     DESCATTER_GIT_DESCRIBE=$(git -C "$here" describe --always --dirty --tags) \
     DEB_BUILD_OPTIONS="parallel=$jobs nocheck" dpkg-buildpackage -b -uc -us >../build.log 2>&1) ||
    { tail -40 "$out/build.log"; echo "lab.sh: dpkg-buildpackage failed (build-deb/build.log)" >&2; return 1; }
  ls "$out"/*.deb
  # Every tag lintian still reports is justified in debian/*.lintian-overrides.
  lintian --fail-on error,warning,info --display-info "$out"/*.changes
}

case "${1:-}" in
  deps) install_deps ;;
  package) install_deps && package ;;
  package-test) install_deps && package && tools/package_test.sh "$here"/build-deb ;;
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
    package
    echo "== the packages installed with apt-get, tested with the source tree hidden =="
    tools/package_test.sh "$here"/build-deb
    build build -DDESCATTER_WERROR=ON
    echo "== test suite, plain build =="
    cd build && ctest --output-on-failure -j "$jobs"
    ;;
  *) echo "usage: tools/lab.sh demo|test|deps|package|package-test" >&2; exit 2 ;;
esac
