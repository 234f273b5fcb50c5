#!/usr/bin/python3
"""Issue 37's features end to end over the loopback lab: descatterd driving descatter-labsim's
GigE Vision camera (Aravis) and Modbus TCP illuminator, run through netns_run.sh (UDP 3956 on
127.0.0.1 is labsim's alone). The same features on the in-process simulator: daemon/motion-speed,
daemon/motion-noise-model, daemon/slow-subscriber.
Usage: test_labsim_motion_results.py BINDIR PYDIR SRCDIR speed|noise|slow

speed: tests/daemon/motion-bar.scene (a still bar of transmittance 0.2 across the whole height
under sine stripes in clear air), the operating model limited to M = 1 at the pilot's exposure,
so that a set's N frames are evenly spaced from first to last over the result's `set_span_ms`:
- each declared speed (capture's speed_px_s, descatterctl --speed-px-s, [acquisition]
  speed-px-s after a reload) is stated in `operating_point.motion` with a term, and the
  prediction is the still one and the term in quadrature;
- the term agrees with the bar's sharp edges evaluated here numerically, written from the model
  (daemon/operating/motion_term.h) and not from its code: the transmission profile shifted by
  linear interpolation to each frame's place relative to the set's middle, its squared departure
  averaged over the frames against the light, times kappa, the estimator's mean square edge
  error over the 1/4 the departure averages to (sine 1/12 + 1/(2 pi^2), max/min 3/8). The optics
  blur the edges by about a pixel, which lowers the departure only: within [0.85, 1.02] where
  the set's ends move 4 px or more;
- a faster speed never chooses a larger N with the same estimator, and the fastest chooses fewer
  phases than the still scene.

noise: the same scene, shot-noise limited (K = 0.25 DN/e-, read noise 6 e- = 1.5 DN: the
scene's sensor defaults, which labsim's frames carry as Mono16 as they are), still, the motion bit
on at N = 8, in captures and in per-frame results: with [camera] gain-dn-per-e = 0.25 and
read-noise-dn = 1.5 (the scene's sensor) at most 3e-3 of the pixels are flagged (the design's
rate is 1e-3) and the result states the model; without them one frame's median noise
under-reads the bright pixels and more than 3e-3 are flagged.

slow: per-frame results at labsim's frame rate to two slow subscribers, one read by hand here
(a line, then exactly the payload bytes it announces), one `descatterctl stream --delay-ms`:
- each result's set id steps from the previous one received by 1 + its `skipped`, so the sum of
  (1 + skipped) over the results after the first is the span of their set ids; once the stream
  stopped and the newest result arrived, received plus skipped is status `frame_results`;
- `descatterctl stream` prints each result's `skipped`, and its printed set ids step alike;
- while the hand-read subscriber pauses over 40 results, status `clients.queued_bytes` stays
  within two results per subscriber (the one being written and the newest), and after the pause
  it gets, within what was already on its way, a result as new as the daemon had published when
  the pause ended."""
import json
import math
import os
import re
import signal
import subprocess
import sys
import tempfile
import time

BIN, PYDIR, SRC, MODE = sys.argv[1:5]
sys.path.insert(0, PYDIR)
import descatter  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from daemon_checks import (Labsim, RawSubscriber, check, check_no_speed, check_noise_model, failures,  # noqa: E402
                           flagged_fraction, set_id, spawn, stop_process, wait_ready_on_labsim)

DAEMON = os.path.join(BIN, "descatterd")
CTL = os.path.join(BIN, "descatterctl")
LABSIM = os.path.join(BIN, "descatter-labsim")
BAR = os.path.join(SRC, "tests", "daemon", "motion-bar.scene")
# motion-bar.scene: 128 px wide, the bar from x = 40, 24 px wide, transmittance 0.2.
WIDTH, BAR_X, BAR_W, BAR_T = 128, 40, 24, 0.2
# The estimators' mean square error for a sharp edge crossing a pixel during a long set (the
# model's derivation in daemon/operating/motion_term.h); the departure itself averages to 1/4.
EDGE_MSE = {"sine": 1 / 12 + 1 / (2 * math.pi ** 2), "maxmin": 3 / 8}
PAUSE_RESULTS = 40



class Daemon:
    """descatterd on labsim's camera and illuminator; `conf` is appended to its configuration
    ([camera] extra lines in `camera`)."""

    def __init__(self, tmp, name, labsim, conf, camera=""):
        self.sock = os.path.join(tmp, name + ".sock")
        self.conf = os.path.join(tmp, name + ".conf")
        self.text = ("[camera]\nbackend=aravis\naddress=127.0.0.1\npixel-format=Mono16\nexposure-us=2000\n"
                     "grab-timeout-ms=2000\n" + camera +
                     f"[illuminator]\nbackend=modbus\nmodbus-uri=tcp://127.0.0.1:{labsim.port}\n"
                     "modbus-timeout-ms=300\npattern=sine\nperiod-px=8\n" + conf)
        with open(self.conf, "w") as f:
            f.write(self.text)
        self.log = os.path.join(tmp, name + ".log")
        self.proc = spawn([DAEMON, "--config", self.conf, "--socket", self.sock, "--no-socket-activation"],
                          stdout=open(self.log, "w"), stderr=subprocess.STDOUT)
        wait_ready_on_labsim(descatter, self.proc, self.sock, self.log, name, labsim)

    def status(self):
        with descatter.Client(self.sock) as c:
            return c.status()

    def ctl(self, *args, timeout=120):
        return subprocess.run([CTL, "--address", self.sock, *args], capture_output=True, text=True, timeout=timeout)

    def stop(self):
        stop_process(self.proc, "descatterd")


def model_file(tmp, name, phases):
    path = os.path.join(tmp, name)
    with open(path, "w") as f:
        f.write("[operating-model]\nscale=1\nphases=" + ";".join(map(str, phases)) +
                "\naverages=1;\nexposure-factors=1;\nfitted-on=test\n")
    return path


def shifted(profile, s):
    """profile (one row of transmission) moved by s px along x, by linear interpolation between
    its samples, the border held."""
    n = len(profile)
    out = []
    for x in range(n):
        u = min(max(x - s, 0.0), n - 1.0)
        i = min(int(math.floor(u)), n - 2)
        f = u - i
        out.append((1 - f) * profile[i] + f * profile[i + 1])
    return out


def bar_term(estimator, n, span_ms, speed):
    """The motion term of the bar as sharp edges: n frames evenly spaced over span_ms, the set's
    middle the truth. Rows are alike (the bar spans the height): one row stands for all."""
    row = [BAR_T if BAR_X <= x < BAR_X + BAR_W else 1.0 for x in range(WIDTH)]
    light = sum(t * t for t in row)
    dep = 0.0
    for k in range(n):
        s = speed * (k / (n - 1) - 0.5) * span_ms / 1e3
        dep += sum((a - b) ** 2 for a, b in zip(shifted(row, s), row))
    return math.sqrt(EDGE_MSE[estimator] / 0.25 * dep / n / light)


def check_motion(s, v, what):
    """The motion block of one automatic result's settings for declared speed v; returns
    (estimator, N)."""
    op = s["operating_point"]
    m = op["motion"]
    est, n = s["estimator"], s["phases"]
    print(f"     {what}: {est} N={n}, predicted {op['predicted_error']:.4f} (still {m['predicted_error_still']:.4f}, "
          f"motion {m['term']}), span {m['set_span_ms']:.2f} ms", flush=True)
    check(m["speed_px_s"] == v and m["term"] is not None and m["term"] > 0, f"{what}: the speed and a term are stated")
    check("motion" in op["contains"] and "still_scene" not in op["assumed"], f"{what}: the prediction contains motion")
    both = math.hypot(m["predicted_error_still"], m["term"])
    check(abs(op["predicted_error"] - both) <= 1e-9 * both, f"{what}: predicted_error = hypot(still, term)")
    check(s["averages"] == 1 and n >= 3, f"{what}: M = 1 as the model allows")
    check(est in EDGE_MSE, f"{what}: an estimator with a motion model ({est})")
    if est in EDGE_MSE and v * m["set_span_ms"] / 2e3 >= 4:
        want = bar_term(est, n, m["set_span_ms"], v)
        ratio = m["term"] / want
        print(f"     {what}: term {m['term']:.4f}, sharp edges {want:.4f}, ratio {ratio:.3f}")
        check(0.85 <= ratio <= 1.02, f"{what}: the term is the bar's sharp edges ({ratio:.3f})")
    return est, n


def speed_checks(tmp):
    labsim = Labsim(LABSIM, tmp, BAR, "DSLM")
    model = model_file(tmp, "bar-model.conf", [3, 4, 6, 8, 12, 16, 24, 32])
    d = Daemon(tmp, "speed", labsim, f"[acquisition]\noperating-model={model}\n")
    try:
        with descatter.Client(d.sock) as c:
            still = c.capture(time_budget_ms=3000).meta["settings"]
            check_no_speed(still)
            chosen = []
            for v in (2, 5, 10, 20, 40, 1280, 2560):
                s = c.capture(time_budget_ms=3000, speed_px_s=v).meta["settings"]
                chosen.append((v, *check_motion(s, v, f"{v} px/s")))
            for i in range(len(chosen)):
                for j in range(i + 1, len(chosen)):
                    if chosen[i][1] == chosen[j][1]:
                        check(chosen[j][2] <= chosen[i][2],
                              f"{chosen[j][0]} px/s chooses no larger N than {chosen[i][0]} px/s "
                              f"({chosen[j][2]} vs {chosen[i][2]}, {chosen[i][1]})")
            check(chosen[-1][2] < still["phases"],
                  f"the fastest speed chooses fewer phases than a still scene ({chosen[-1][2]} < {still['phases']})")

        out = os.path.join(tmp, "ctl-out")
        r = d.ctl("capture", "--time-budget-ms", "3000", "--speed-px-s", "640", "--out", out)
        check(r.returncode == 0, "descatterctl capture --speed-px-s: " + r.stderr.strip()[-300:])
        sidecars = [n for n in os.listdir(out) if n.startswith("set-") and n.endswith(".json")] \
            if r.returncode == 0 else []
        if sidecars:
            check_motion(json.load(open(os.path.join(out, sidecars[0])))["settings"], 640, "descatterctl, 640 px/s")
        else:
            check(False, "descatterctl capture --speed-px-s wrote a sidecar")

        # The configuration's speed, taken on reload (the key is live).
        with open(d.conf, "w") as f:
            f.write(d.text + "speed-px-s=640\n")
        d.proc.send_signal(signal.SIGHUP)
        with descatter.Client(d.sock) as c:
            deadline = time.time() + 60
            while "speed-px-s=640" not in c.config()["text"].replace(" ", "") and time.time() < deadline:
                time.sleep(0.2)
            s = c.capture(time_budget_ms=3000).meta["settings"]
            check_motion(s, 640, "[acquisition] speed-px-s = 640")
    finally:
        d.stop()
        labsim.stop()


def noise_checks(tmp):
    labsim = Labsim(LABSIM, tmp, BAR, "DSLM")
    try:
        conf = "[acquisition]\ndetect-motion=true\n"
        d = Daemon(tmp, "median", labsim, conf)
        try:
            runs_without = flagged_fraction(descatter, d.sock, 4, 16)
        finally:
            d.stop()
        d = Daemon(tmp, "model", labsim, conf, camera="gain-dn-per-e=0.25\nread-noise-dn=1.5\n")
        try:
            runs_with = flagged_fraction(descatter, d.sock, 4, 16)
        finally:
            d.stop()
    finally:
        labsim.stop()
    check_noise_model(runs_without, runs_with)


def check_steps(what, ids, skipped):
    """Set ids of the results a subscriber received against their `skipped`: each steps from the
    previous by 1 + skipped; so sum (1 + skipped) after the first is the span."""
    bad = [(a, b, k) for a, b, k in zip(ids, ids[1:], skipped[1:]) if b - a != 1 + k]
    check(not bad, f"{what}: each set id steps by 1 + skipped ({len(bad)} do not: {bad[:5]})")
    span = ids[-1] - ids[0]
    total = sum(1 + k for k in skipped[1:])
    check(total == span, f"{what}: sum of (1 + skipped) {total} = span of set ids {span} "
          f"({len(ids)} results, {sum(skipped)} skipped)")


def slow_checks(tmp):
    labsim = Labsim(LABSIM, tmp, BAR, "DSLM")
    d = Daemon(tmp, "slow", labsim, "[acquisition]\nphases=4\ndark-frame=false\n")
    try:
        with open("/proc/sys/net/core/wmem_default") as f:
            socket_buffer = int(f.read())
        slow = RawSubscriber(d.sock)
        stream = spawn([CTL, "--address", d.sock, "stream", "--delay-ms", "100"], stdout=subprocess.PIPE,
                       stderr=subprocess.PIPE, text=True)
        # Subscribed before the first result: waited for in the daemon's count (the hand-read one
        # and descatterctl's), not for a fixed time a loaded machine may need more than.
        deadline = time.time() + 60
        while d.status()["clients"]["subscribers"] < 2 and time.time() < deadline and stream.poll() is None:
            time.sleep(0.05)
        check(d.status()["clients"]["subscribers"] == 2, "descatterctl stream subscribed")
        r = d.ctl("start", "--results", "per-frame")
        check(r.returncode == 0, "start --results per-frame: " + r.stderr.strip())
        for _ in range(5):
            slow.read_result()
            time.sleep(0.15)
        size = sum(p["bytes"] for p in slow.results()[-1]["payloads"])
        f0 = d.status()["frame_results"]
        queued_max = 0
        deadline = time.time() + 60
        while True:
            st = d.status()
            queued_max = max(queued_max, st["clients"]["queued_bytes"])
            if st["frame_results"] >= f0 + PAUSE_RESULTS or time.time() > deadline:
                break
            time.sleep(0.05)
        published = st["frame_results"]
        check(published >= f0 + PAUSE_RESULTS, f"{PAUSE_RESULTS} results published during the pause "
              f"({published - f0})")
        # Two slow subscribers, each at most the result being written and the newest.
        bound = 2 * 2 * size + 65536
        print(f"     queue to clients during the pause: at most {queued_max} bytes; results of {size} bytes; "
              f"bound {bound}", flush=True)
        check(queued_max <= bound, f"the queue stays within two results per subscriber ({queued_max} <= {bound})")
        on_the_way = 2 + math.ceil(socket_buffer / size)
        after = [slow.read_result() for _ in range(on_the_way + 1)]
        ids = [set_id(h) for h in after]
        print(f"     after the pause ({published} published): sets {ids}, skipped {[h['skipped'] for h in after]}")
        check(max(ids) >= published, f"after the pause a result as new as set {published}, no backlog: {ids}")
        r = d.ctl("stop")
        check(r.returncode == 0, "stop: " + r.stderr.strip())
        deadline = time.time() + 60
        while d.status()["state"] != "idle" and time.time() < deadline:
            time.sleep(0.1)
        total = d.status()["frame_results"]
        while set_id(slow.results()[-1]) < total:
            slow.read_result()
        res = slow.results()
        check_steps("hand-read subscriber", [set_id(h) for h in res], [h["skipped"] for h in res])
        received = len(res) + sum(h["skipped"] for h in res)
        check(received == total, f"hand-read subscriber: received + skipped {received} = frame_results {total}")
        slow.close()

        # descatterctl stream at 100 ms a message: it has printed the results it read; the ones
        # still queued for it are not awaited.
        time.sleep(2)
        stream.send_signal(signal.SIGINT)
        out, err = stream.communicate(timeout=60)
        check(stream.returncode == 0, f"descatterctl stream ends on SIGINT ({stream.returncode}): {err.strip()[-300:]}")
        lines = [m for m in (re.fullmatch(r"result seq=(\d+) set=(\d+) lost=(\d+) skipped=(\d+)", x)
                             for x in out.splitlines()) if m]
        others = [x for x in out.splitlines() if x.startswith("result") and
                  not re.fullmatch(r"result seq=\d+ set=\d+ lost=\d+ skipped=\d+", x)]
        check(not others, f"descatterctl stream prints skipped= on every result line: {others[:3]}")
        check(len(lines) >= 5, f"descatterctl stream printed {len(lines)} results")
        if len(lines) >= 2:
            sets = [int(m.group(2)) for m in lines]
            skipped = [int(m.group(4)) for m in lines]
            check_steps("descatterctl stream", sets, skipped)
            check(sum(skipped) > 0, f"descatterctl stream at 100 ms a message skipped results ({sum(skipped)})")
    finally:
        d.stop()
        labsim.stop()


def main():
    with tempfile.TemporaryDirectory(prefix="ds-labsim-motion-") as tmp:
        {"speed": speed_checks, "noise": noise_checks, "slow": slow_checks}[MODE](tmp)
    if failures:
        print(f"{len(failures)} check(s) failed")
        sys.exit(1)
    print("all checks passed")


if __name__ == "__main__":
    main()
