#!/bin/sh
# descatter-labsim against programs written elsewhere: mbpoll reads and writes its registers over
# Modbus TCP and over Modbus RTU (on one end of a socat pty pair, mbpoll on the other; and on the
# pty labsim creates itself), arv-tool-0.8 reads its camera's features, arv-camera-test-0.8
# streams frames from it.
# Usage: labsim_tools.sh LABSIM SCENE. Binds UDP 3956 (ctest RESOURCE_LOCK gige_port_3956).
set -eu
labsim=$1
scene=$2
tmp=$(mktemp -d)
serial="DSLS$(($$ % 100000))"
pid=
socat_pid=
cleanup() {
  [ -n "$pid" ] && kill -TERM "$pid" 2>/dev/null || true
  [ -n "$socat_pid" ] && kill -TERM "$socat_pid" 2>/dev/null || true
  rm -rf "$tmp"
}
trap cleanup EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

# A serial line: two ptys joined by socat, as a USB-RS485 adapter pair would be.
socat pty,raw,echo=0,link="$tmp/ttyA" pty,raw,echo=0,link="$tmp/ttyB" 2>"$tmp/socat.err" &
socat_pid=$!
for _ in $(seq 1 100); do
  [ -e "$tmp/ttyA" ] && [ -e "$tmp/ttyB" ] && break
  sleep 0.05
done
[ -e "$tmp/ttyB" ] || fail "socat made no pty pair: $(cat "$tmp/socat.err")"

"$labsim" --scene "$scene" --camera-address 127.0.0.1 --camera-serial "$serial" \
  --modbus 127.0.0.1:0 --modbus-rtu "rtu:$tmp/ttyA?baud=19200&parity=E" >"$tmp/out" 2>"$tmp/err" &
pid=$!
for _ in $(seq 1 100); do
  grep -q ready "$tmp/out" 2>/dev/null && break
  kill -0 "$pid" 2>/dev/null || fail "labsim exited: $(cat "$tmp/err")"
  sleep 0.1
done
port=$(sed -n 's/.*ready camera=127.0.0.1 modbus=127.0.0.1:\([0-9]*\).*/\1/p' "$tmp/out")
[ -n "$port" ] || fail "no ready line: $(cat "$tmp/out")"
echo "labsim ready, modbus port $port"

# --- mbpoll: input registers from 0 (PDU addressing), then write PHASE=2, ENABLE=1. ----------
mb() { mbpoll -m tcp -p "$port" -0 -1 -o 1 "$@"; } # host, then values to write
mb -t 3 -r 0 -c 9 127.0.0.1 >"$tmp/in" || fail "mbpoll read: $(cat "$tmp/in")"
grep -q '^\[0\]:[[:space:]]*17491$' "$tmp/in" || fail "MAGIC is not 0x4453 (17491): $(cat "$tmp/in")"
grep -q '^\[3\]:[[:space:]]*65535' "$tmp/in" || fail "APPLIED_PHASE is not off after power-up"
# The projector can change its period and light every stripe at once: CAPABILITIES has
# PERIOD_ADJUSTABLE (1) and ALL_ON (2), 2.00 .. 655.35 px.
grep -q '^\[6\]:[[:space:]]*3$' "$tmp/in" || fail "CAPABILITIES is not PERIOD_ADJUSTABLE|ALL_ON (3): $(cat "$tmp/in")"
grep -q '^\[7\]:[[:space:]]*200$' "$tmp/in" || fail "PERIOD_MIN_CENTIPX is not 200: $(cat "$tmp/in")"
grep -q '^\[8\]:[[:space:]]*65535' "$tmp/in" || fail "PERIOD_MAX_CENTIPX is not 65535: $(cat "$tmp/in")"
mb -t 4 -r 0 127.0.0.1 2 1 >"$tmp/w" || fail "mbpoll write: $(cat "$tmp/w")"
sleep 0.1 # settle time is 3 ms
mb -t 3 -r 2 -c 3 127.0.0.1 >"$tmp/in2" || fail "mbpoll read back"
grep -q '^\[2\]:[[:space:]]*17$' "$tmp/in2" || fail "STATUS is not READY|ENABLED (17): $(cat "$tmp/in2")"
grep -q '^\[3\]:[[:space:]]*2$' "$tmp/in2" || fail "APPLIED_PHASE is not 2: $(cat "$tmp/in2")"
grep -q '^\[4\]:[[:space:]]*1$' "$tmp/in2" || fail "APPLY_COUNT is not 1: $(cat "$tmp/in2")"
# A value out of range (NUM_PHASES = 1) is refused and changes nothing.
mb -t 4 -r 2 127.0.0.1 1 >"$tmp/bad" 2>&1 && fail "NUM_PHASES=1 was accepted"
mb -t 4 -r 2 127.0.0.1 >"$tmp/np"
grep -q '^\[2\]:[[:space:]]*4$' "$tmp/np" || fail "NUM_PHASES changed: $(cat "$tmp/np")"
# PERIOD_CENTIPX: 9.00 px is taken (an adjustable projector); 1.50 px is below PERIOD_MIN_CENTIPX
# and refused with exception 03, leaving 900.
mb -t 4 -r 4 127.0.0.1 900 >"$tmp/pw" 2>&1 || fail "mbpoll PERIOD_CENTIPX=900: $(cat "$tmp/pw")"
mb -t 4 -r 4 127.0.0.1 150 >"$tmp/pbad" 2>&1 && fail "PERIOD_CENTIPX=150 was accepted"
grep -qi "illegal data value" "$tmp/pbad" || fail "no exception 03 for PERIOD_CENTIPX=150: $(cat "$tmp/pbad")"
mb -t 4 -r 4 127.0.0.1 >"$tmp/pr"
grep -q '^\[4\]:[[:space:]]*900$' "$tmp/pr" || fail "PERIOD_CENTIPX is not 900: $(cat "$tmp/pr")"
echo "mbpoll: ok"

# --- mbpoll -m rtu on the far end of the serial line (19200 8E1, the Modbus serial default). ----
grep -q "rtu=$tmp/ttyA" "$tmp/out" || fail "the ready line does not name the serial line: $(cat "$tmp/out")"
rtu() { timeout 10 mbpoll -m rtu -b 19200 -P even -a 1 -0 -1 -o 2 "$@"; }
rtu -t 3 -r 0 -c 6 "$tmp/ttyB" >"$tmp/rin" 2>&1 || fail "mbpoll rtu read: $(cat "$tmp/rin")"
grep -q '^\[0\]:[[:space:]]*17491$' "$tmp/rin" || fail "RTU: MAGIC is not 17491: $(cat "$tmp/rin")"
rtu -t 4 -r 0 "$tmp/ttyB" 3 1 >"$tmp/rw" 2>&1 || fail "mbpoll rtu write: $(cat "$tmp/rw")"
sleep 0.1
rtu -t 3 -r 2 -c 3 "$tmp/ttyB" >"$tmp/rin2" 2>&1 || fail "mbpoll rtu read back: $(cat "$tmp/rin2")"
grep -q '^\[3\]:[[:space:]]*3$' "$tmp/rin2" || fail "RTU: APPLIED_PHASE is not 3: $(cat "$tmp/rin2")"
grep -q '^\[4\]:[[:space:]]*3$' "$tmp/rin2" ||
  fail "RTU: APPLY_COUNT is not 3 (PHASE and PERIOD_CENTIPX over TCP, PHASE over RTU): $(cat "$tmp/rin2")"
# The controller's range check answers exception 03 over RTU as well ...
rtu -t 4 -r 2 "$tmp/ttyB" 1 >"$tmp/rbad" 2>&1 && fail "RTU: NUM_PHASES=1 was accepted"
grep -qi "illegal data value" "$tmp/rbad" || fail "RTU: no exception 03 for NUM_PHASES=1: $(cat "$tmp/rbad")"
# ... and a request for another unit on the line gets no answer at all.
rtu -a 9 -o 0.3 -t 3 -r 0 -c 1 "$tmp/ttyB" >"$tmp/runit" 2>&1 && fail "RTU: unit 9 answered: $(cat "$tmp/runit")"
grep -qi "timed out" "$tmp/runit" || fail "RTU: unit 9: expected a timeout: $(cat "$tmp/runit")"
echo "mbpoll -m rtu: ok"

# --- arv-tool: the camera's features as labsim serves them. ---------------------------------
timeout 20 arv-tool-0.8 -a 127.0.0.1 control DeviceID Width Height PixelFormat >"$tmp/ctl" 2>&1 ||
  fail "arv-tool control: $(cat "$tmp/ctl")"
grep -q "DeviceID = $serial" "$tmp/ctl" ||
  fail "the camera on 127.0.0.1 is not labsim's $serial (another device on UDP 3956?): $(cat "$tmp/ctl")"
w=$(sed -n 's/^width=//p' "$scene")
h=$(sed -n 's/^height=//p' "$scene")
grep -q "Width = $w " "$tmp/ctl" || fail "Width is not the scene's $w: $(cat "$tmp/ctl")"
grep -q "Height = $h " "$tmp/ctl" || fail "Height is not the scene's $h: $(cat "$tmp/ctl")"
timeout 20 arv-tool-0.8 -a 127.0.0.1 features >"$tmp/feat" 2>&1 || fail "arv-tool features"
grep -q "TriggerSoftware" "$tmp/feat" || fail "no TriggerSoftware feature: $(cat "$tmp/feat")"
# Its pixel formats: listed, and each one set and read back with the payload it implies.
for f in Mono8 Mono10 Mono12 Mono16 Mono10p Mono12p Mono12Packed; do
  grep -q "EnumEntry *: '$f'" "$tmp/feat" || fail "PixelFormat does not list $f: $(cat "$tmp/feat")"
done
for fb in Mono8:8 Mono10:16 Mono12:16 Mono16:16 Mono10p:10 Mono12p:12 Mono12Packed:12; do
  f=${fb%%:*} bits=${fb#*:}
  timeout 20 arv-tool-0.8 -a 127.0.0.1 control "PixelFormat=$f" PayloadSize >"$tmp/pf" 2>&1 || fail "arv-tool PixelFormat=$f: $(cat "$tmp/pf")"
  grep -q "PixelFormat = $f\$" "$tmp/pf" || fail "PixelFormat=$f not taken: $(cat "$tmp/pf")"
  grep -q "PayloadSize = $((w * h * bits / 8))\$" "$tmp/pf" || fail "$f: payload is not $w x $h x $bits / 8: $(cat "$tmp/pf")"
done
timeout 20 arv-tool-0.8 -a 127.0.0.1 control PixelFormat=Mono16 >/dev/null 2>&1
echo "arv-tool: ok (pixel formats listed and set)"

# --- arv-camera-test: free-running stream for 3 s. ------------------------------------------
timeout -s INT 3 arv-camera-test-0.8 -n 127.0.0.1 -f 20 >"$tmp/stream" 2>&1 || true
n=$(sed -n 's/^n_completed_buffers *= *//p' "$tmp/stream")
[ -n "$n" ] && [ "$n" -gt 0 ] || fail "arv-camera-test completed no buffer: $(cat "$tmp/stream")"
grep -q "image width *= *$w" "$tmp/stream" || fail "arv-camera-test width: $(cat "$tmp/stream")"
echo "arv-camera-test: $n frames"

kill -TERM "$pid"
wait "$pid" || fail "labsim exit status $? after SIGTERM: $(cat "$tmp/err")"
pid=
echo "labsim: clean exit"

# --- the GVSP loss knob is seen by a client we did not write. --------------------------------
"$labsim" --scene "$scene" --camera-address 127.0.0.1 --camera-serial "$serial" \
  --modbus 127.0.0.1:0 --gvsp-lost-ratio 0.05 --modbus-rtu pty --modbus-rtu-link "$tmp/ttyLAB" \
  >"$tmp/out2" 2>"$tmp/err2" &
pid=$!
for _ in $(seq 1 100); do
  grep -q ready "$tmp/out2" 2>/dev/null && break
  kill -0 "$pid" 2>/dev/null || fail "labsim exited: $(cat "$tmp/err2")"
  sleep 0.1
done
timeout -s INT 3 arv-camera-test-0.8 -n 127.0.0.1 -f 20 >"$tmp/stream2" 2>&1 || true
missing=$(sed -n 's/^n_missing_packets *= *//p' "$tmp/stream2")
[ -n "$missing" ] && [ "$missing" -gt 0 ] || fail "--gvsp-lost-ratio 0.05: no missing packet: $(cat "$tmp/stream2")"
echo "arv-camera-test with 5% GVSP loss: $missing missing packets"
# labsim's own pty, through its link (any baud: a pty has none).
timeout 10 mbpoll -m rtu -b 115200 -P none -a 1 -0 -1 -o 2 -t 3 -r 0 -c 1 "$tmp/ttyLAB" >"$tmp/rpty" 2>&1 ||
  fail "mbpoll on labsim's pty: $(cat "$tmp/rpty")"
grep -q '^\[0\]:[[:space:]]*17491$' "$tmp/rpty" || fail "pty: MAGIC is not 17491: $(cat "$tmp/rpty")"
echo "mbpoll -m rtu on labsim's own pty: ok"
kill -TERM "$pid"
wait "$pid" || fail "labsim exit status $? after SIGTERM: $(cat "$tmp/err2")"
pid=
