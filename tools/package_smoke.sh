# The installed descatter packages, as a lab uses them (run by tools/package_test.sh as root, in
# a mount namespace where $SOURCE_TREE is an empty tmpfs; $EXPECTED_GIT is the tree's describe).
set -euo pipefail
tmp=$(mktemp -d)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
  rm -rf "$tmp"
}
trap cleanup EXIT
fail() { echo "package test: FAIL $*" >&2; exit 1; }
ok() { echo "package test: ok   $*"; }

[ -z "$(ls -A "$SOURCE_TREE")" ] || fail "the source tree is still visible"
ok "the source tree is out of reach ($SOURCE_TREE is empty)"
version=$(dpkg-query -W -f='${Version}' descatterd)
for p in descatterd descatterctl descatter-sim descatter-labsim; do
  out=$($p --version)
  [ "$out" = "$p $version ($EXPECTED_GIT)" ] || fail "$p --version: \"$out\", expected $version ($EXPECTED_GIT)"
done
ok "every program: --version $version ($EXPECTED_GIT)"
for page in descatterd.8 descatterd.conf.5 descatterctl.1 descatter-sim.1 descatter-labsim.1; do
  [ -s "/usr/share/man/man${page##*.}/$page.gz" ] || fail "man page $page missing"
done
ok "man pages"

descatterd --check >"$tmp/check.txt" || fail "descatterd --check on /etc/descatterd/descatterd.conf"
grep -q '^backend=sim$' "$tmp/check.txt" || fail "the installed configuration does not name its devices"
ok "descatterd --check on the installed /etc/descatterd/descatterd.conf"
verify=$(systemd-analyze verify --man=no descatterd.service descatterd.socket descatterd@rig1.service \
           descatterd@rig1.socket 2>&1) || fail "systemd-analyze verify: $verify"
[ -z "$verify" ] || fail "systemd-analyze verify: $verify"
ok "systemd-analyze verify on the installed units (service, socket, rig template)"
getent passwd descatterd >/dev/null || fail "no descatterd account (sysusers.d)"
id -nG descatterd | grep -qw gpio || fail "descatterd is not in group gpio"
[ "$(stat -c %U "${RUNTIME_DIR:-/run/descatterd}")" = descatterd ] || fail "/run/descatterd not owned by descatterd (tmpfiles.d)"
ok "account descatterd (groups: $(id -nG descatterd)), /run/descatterd (tmpfiles.d)"

wait_ready() { # ADDRESS
  for _ in $(seq 1 600); do
    if descatterctl --address "$1" status --json 2>/dev/null | grep -q '"ready" : true'; then return 0; fi
    sleep 0.2
  done
  fail "descatterd at $1 not ready"
}

# The service as its unit runs it: the account, the installed configuration, the default socket
# and data dir (nothing tells the programs where anything is).
install -d -o descatterd -g descatterd /var/cache/descatterd
# setpriv execs (runuser would stay the parent and turn SIGTERM into its own exit status).
setpriv --reuid=descatterd --regid=descatterd --init-groups env DESCATTER_CACHE_DIR=/var/cache/descatterd \
  descatterd --config /etc/descatterd/descatterd.conf --no-socket-activation >"$tmp/daemon.log" 2>&1 &
daemon=$!
pids+=("$daemon")
wait_ready /run/descatterd/descatterd.sock
status=$(descatterctl status)
echo "$status" | grep -q "^auto point:   operating model /usr/share/descatter/operating-model.conf" ||
  fail "the operating model is not the installed one: $status"
ok "descatterd runs as descatterd on /run/descatterd/descatterd.sock; status: $(echo "$status" | sed -n 2p)"
cd "$tmp"
descatterctl capture --phases 8 --quiet --out shot >/dev/null || fail "descatterctl capture"
for f in '*.json' '*transmissive.tiff' '*scattered.tiff'; do
  compgen -G "shot/$f" >/dev/null || fail "capture wrote no $f: $(ls shot)"
done
grep -q "\"git\" : \"$EXPECTED_GIT\"" shot/*.json || fail "the result does not name the build"
ok "descatterctl capture: $(ls shot | tr '\n' ' ')"
descatterctl capture --target-error 0.1 --quiet --out auto >/dev/null || fail "automatic capture"
grep -q '"operating_point"' auto/*.json || fail "the automatic capture recorded no operating point"
ok "descatterctl capture --target-error (the installed operating model)"
python3 - <<'EOF' || fail "the Python client"
import descatter, descatter.aio, numpy as np
with descatter.Client() as c:
    r = c.capture(phases=4)
    assert r.transmissive.shape == (r.meta["height"], r.meta["width"]) and r.transmissive.dtype == np.float32
    assert c.hello()["version"] == descatter.__version__
print("package test: ok   python3: import descatter, capture", r.set_id, "through", descatter.__file__)
EOF
kill -TERM "$daemon"
wait "$daemon" || fail "descatterd did not stop cleanly: $(tail -5 "$tmp/daemon.log")"
pids=()
ok "descatterd stopped cleanly on SIGTERM"

descatterd --sim --socket "$tmp/sim.sock" >"$tmp/sim.log" 2>&1 &
pids+=("$!")
wait_ready "$tmp/sim.sock"
descatterctl --address "$tmp/sim.sock" capture --phases 4 --quiet --out sim >/dev/null || fail "capture from descatterd --sim"
compgen -G "sim/*transmissive.tiff" >/dev/null || fail "descatterd --sim: no result"
ok "descatterd --sim + descatterctl capture"
descatterctl study --quick --quiet --out study || fail "descatterctl study --quick"
[ "$(wc -l <study/study.csv)" -gt 4 ] && [ -s study/pareto.md ] || fail "study wrote no results"
ok "descatterctl study --quick on the installed scenes: $(($(wc -l <study/study.csv) - 1)) points"
for f in error-vs-time-clear-grid error-vs-period-clear-grid examples-clear-grid; do
  [ -s "study/$f.png" ] && [ -s "study/$f.svg" ] || fail "descatterctl study drew no $f figure"
done
ok "descatterctl study drew its figures (PNG, SVG) with the installed helper"
descatter-sim describe /usr/share/descatter/scenes/milk-disc.scene >/dev/null || fail "descatter-sim describe"
ok "descatter-sim describe an installed scene"

if [ -d /run/systemd/system ]; then
  systemctl is-active --quiet descatterd.socket || fail "descatterd.socket is not active after install"
  descatterctl status >/dev/null || fail "descatterctl status through the socket unit"
  ok "systemd: descatterd.socket active, the service answers through it"
else
  ok "systemd is not PID 1 here: the units were verified, not started"
fi
