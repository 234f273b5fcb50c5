"""What the Python tests of tests/daemon share: a list of failed checks, child processes that
cannot outlive the test, descatter-labsim as a child, a subscription read by hand, the share of still pixels the motion bit
flags and the checks of its noise model. Import it after putting this folder on sys.path; a
test reports `failures` at its end, so it sees every check, its own and those made here."""
import ctypes
import json
import signal
import os
import socket
import subprocess
import threading
import time

failures = []


def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what, flush=True)
    if not cond:
        failures.append(what)


def die_with_parent():
    ctypes.CDLL(None).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG: nothing outlives the test


def spawn(argv, **kw):
    return subprocess.Popen(argv, preexec_fn=die_with_parent, **kw)


def stop_process(proc, what):
    """Terminates proc (killed after 60 s) and checks that it exits cleanly."""
    if proc.poll() is None:
        proc.terminate()
        try:
            code = proc.wait(60)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
            code = None
    else:
        code = proc.returncode
    check(code == 0, f"{what} exits cleanly ({code})")


def wait_ready_on_labsim(descatter, proc, sock, log, name, labsim):
    """Waits (120 s at most) until descatterd `proc` answers ready on `sock`, and checks that its
    camera is labsim's; `descatter` is the Python client module, `log` the daemon's output."""
    deadline = time.time() + 120
    while True:
        try:
            with descatter.Client(sock) as c:
                st = c.status()
                if st["ready"]:
                    serial = st["devices"]["camera"].get("serial")
                    check(serial == labsim.serial, f"{name}: the daemon's camera is labsim's ({serial})")
                    return
        except (OSError, descatter.DescatterError):
            pass
        assert proc.poll() is None, "descatterd exited: " + open(log).read()[-2000:]
        assert time.time() < deadline, "descatterd not ready: " + open(log).read()[-2000:]
        time.sleep(0.2)


class Labsim:
    """descatter-labsim (the binary `labsim`) on 127.0.0.1 showing one scene: its camera on UDP
    3956 with a serial of this process's own (so the daemon's camera is this labsim's), its
    Modbus TCP port from its ready line."""

    def __init__(self, labsim, tmp, scene, serial_prefix, env=None):
        self.log_path = os.path.join(tmp, "labsim-" + os.path.basename(scene) + ".log")
        self.serial = f"{serial_prefix}{os.getpid() % 100000:05d}"
        self.proc = spawn([labsim, "--scene", scene, "--camera-address", "127.0.0.1", "--camera-serial", self.serial,
                           "--modbus", "127.0.0.1:0"],
                          stdout=subprocess.PIPE, stderr=open(self.log_path, "w"), text=True, env=env)
        self.port = None
        for line in self.proc.stdout:
            if "ready camera=" in line:
                self.port = int(line.split(" modbus=127.0.0.1:")[1].split()[0])
                break
        assert self.port, "descatter-labsim did not get ready: " + open(self.log_path).read()[-2000:]
        # What it prints later is drained, so that a full pipe never blocks it.
        self.drain = threading.Thread(target=lambda: [None for _ in self.proc.stdout], daemon=True)
        self.drain.start()

    def stop(self):
        stop_process(self.proc, "descatter-labsim")
        self.drain.join(10)
        self.proc.stdout.close()


class RawSubscriber:
    """A subscription read by hand: every event's header kept, its payloads read and counted,
    so that a torn message shows as a header that does not parse."""

    def __init__(self, path):
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.sock.settimeout(120)
        self.sock.connect(path)
        self.f = self.sock.makefile("rb")
        self.sock.sendall(b'{"id": 1, "cmd": "subscribe"}\n')
        reply = json.loads(self.f.readline())
        assert reply["ok"] and reply["result"]["subscribed"], reply
        self.next_seq = reply["result"]["next_seq"]
        self.events = []

    def read(self):
        line = self.f.readline()
        assert line.endswith(b"\n"), f"the connection ended inside a line: {line[:80]!r}"
        h = json.loads(line)  # a torn message would leave payload bytes here
        want = sum(p["bytes"] for p in h.get("payloads", []))
        got = len(self.f.read(want)) if want else 0
        assert got == want, f"{got} payload bytes of {want}"
        self.events.append(h)
        return h

    def read_result(self):
        while True:
            h = self.read()
            if h.get("event") == "result":
                return h

    def results(self):
        return [h for h in self.events if h.get("event") == "result"]

    def close(self):
        self.f.close()
        self.sock.close()


def set_id(h):
    return h["body"]["set_id"]


def check_no_speed(settings):
    """A capture with no speed declared: the result states no speed and no motion term, and
    assumes a still scene."""
    op = settings["operating_point"]
    print(f"     no speed: {settings['estimator']} N={settings['phases']}, predicted {op['predicted_error']:.4f}")
    check(op["motion"]["speed_px_s"] is None and op["motion"]["term"] is None,
          "no speed declared: none stated, no term")
    check("still_scene" in op["assumed"] and "motion" not in op["contains"],
          "no speed declared: a still scene assumed")
    return op


def flagged_fraction(client, sock, captures, frame_results):
    """The share of pixels the motion bit flags over `captures` sets, then over `frame_results`
    per-frame results (the sliding window of continuous mode), 8 phases of sine each; with the
    last result's settings. `client` is the descatter Python package."""
    flagged = total = 0
    with client.Client(sock) as c:
        for _ in range(captures):
            r = c.capture(phases=8, estimator="sine", outputs=["mask"])
            check(r.meta["separation"]["motion_checked"], "the motion bit was judged")
            flagged += r.meta["separation"]["flagged"]["motion"]
            total += r.meta["width"] * r.meta["height"]
    per_set = (flagged / total, r.meta["settings"])
    flagged = total = 0
    with client.Client(sock) as sub, client.Client(sock) as c:
        with sub.subscribe() as events:
            c.start(phases=8, estimator="sine", results="per-frame")
            try:
                got = 0
                for ev in events.results():
                    meta = ev.result.meta
                    check(meta["separation"]["motion_checked"], "per-frame: the motion bit was judged")
                    flagged += meta["separation"]["flagged"]["motion"]
                    total += meta["width"] * meta["height"]
                    got += 1
                    if got == frame_results:
                        break
            finally:
                c.stop()
    return per_set, (flagged / total, meta["settings"])


def check_noise_model(runs_without, runs_with):
    """The motion bit's noise model against one frame's median noise, from `flagged_fraction`'s
    runs without and with [camera] gain-dn-per-e = 0.25 and read-noise-dn = 1.5: per set and per
    frame, only the runs with the keys state the model, flag at most 3e-3 of the still pixels
    (the design's rate is 1e-3), and flag fewer than the runs without, which flag more than that
    (the median of the differences under-reads the bright pixels' shot noise)."""
    for mode, (without, s0), (with_model, s1) in zip(("per set", "per frame"), runs_without, runs_with):
        check("gain_dn_per_e" not in s0, f"{mode}: no noise model stated without the keys")
        check(s1.get("gain_dn_per_e") == 0.25 and s1.get("read_noise_dn") == 1.5,
              f"{mode}: the result states the noise model")
        print(f"     {mode}: still pixels flagged: {without:.2e} with one frame's median noise, {with_model:.2e} "
              f"with the noise model", flush=True)
        check(with_model <= 3e-3, f"{mode}: noise model: at most 3e-3 of still pixels flagged ({with_model:.2e})")
        check(without > 3e-3 and without > with_model,
              f"{mode}: without it, more are flagged ({without:.2e} > {with_model:.2e})")
