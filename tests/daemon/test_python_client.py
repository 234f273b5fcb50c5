#!/usr/bin/python3
"""The Python package `descatter` against descatterd on the simulated lab (no mocks).
Usage: test_python_client.py DESCATTERD PYTHON_BUILD_DIR DOCS_PYTHON_MD

Independent checks:
- in one result, the max/min estimator's closed form holds between the payloads as decoded
  (transmissive = max - min, scattered = 2 min for a = 1/2, b = 0), which a byte-order, dtype
  or framing error would break; the arrays are writable and the client's own;
- each error arrives as the class of its stable code (bad_argument, unknown_command,
  unauthorized, a failed set), and a failed set reaches subscribers as a FailedEvent with the
  same reason; a camera that vanishes shows as DeviceEvents;
- seq gaps: a subscriber that reads too slowly sees `lost` on the events after a gap, and the
  sum of its gaps is the daemon's own count of results dropped for it, each result's `skipped`
  its gap;
- leaving a subscription's `with` unsubscribes (the daemon's subscriber count), a silent peer
  times out (descatter.Timeout) within the timeout and a timed-out subscription stays usable;
- save_phases: the raw frames come back as arrays whose per-pixel max, min and mean after the
  dark frame is subtracted are the daemon's max, min and mean planes, and max - min its
  transmissive (maxmin), computed here with numpy from the frames alone;
- release() closes the devices (state "released", captures raise DeviceError naming acquire),
  acquire() opens them again and captures work; the same through the asyncio client;
- cancel() from a second client ends a capture another thread waits on (Cancelled, the set
  counted cancelled with fewer frames than it asked for), and a Timeout in a capture cancels it
  in the daemon before it is raised (status idle, nothing acquired after);
- TCP with a token; the asyncio client; every example of docs/python.md runs."""
import asyncio
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time

DAEMON, PYDIR, DOC = sys.argv[1], sys.argv[2], sys.argv[3]
sys.path.insert(0, PYDIR)
import numpy as np  # noqa: E402

import descatter  # noqa: E402
import descatter.aio  # noqa: E402

failures = []


def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what, flush=True)
    if not cond:
        failures.append(what)


class Daemon:
    def __init__(self, tmp, name, extra_conf=""):
        self.sock = os.path.join(tmp, name + ".sock")
        conf = os.path.join(tmp, name + ".conf")
        with open(conf, "w") as f:
            f.write("[camera]\nbackend=sim\n[illuminator]\nbackend=sim\n" + extra_conf)
        self.proc = subprocess.Popen([DAEMON, "--config", conf, "--socket", self.sock, "--no-socket-activation"],
                                     stdout=subprocess.DEVNULL)
        deadline = time.time() + 120
        while True:
            try:
                with descatter.Client(self.sock, timeout=5) as c:
                    if c.status()["ready"]:
                        break
            except (OSError, descatter.DescatterError):
                pass
            assert self.proc.poll() is None, "descatterd exited"
            assert time.time() < deadline, "descatterd not ready"
            time.sleep(0.1)

    def client(self, **kw):
        return descatter.Client(self.sock, **kw)

    def stop(self):
        self.proc.terminate()
        return self.proc.wait(30)


def basics(d):
    with d.client() as c:
        hello = c.hello()
        check(hello["protocol"] == 1 and hello["version"] == descatter.__version__,
              f"hello: protocol 1, version {descatter.__version__}")
        r = c.capture(phases=4, dark_frame=False, outputs=["transmissive", "scattered", "mask", "max", "min", "mean"])
        t, s, mx, mn = r.transmissive, r.scattered, r.images["max"], r.images["min"]
        check(t.dtype == np.float32 and r.mask.dtype == np.uint8 and t.shape == (r.meta["height"], r.meta["width"]),
              "payload dtypes and shapes as announced")
        check(np.allclose(t, mx - mn, rtol=1e-5, atol=1e-3) and np.allclose(s, 2 * mn, rtol=1e-5, atol=1e-3),
              "maxmin closed form between the decoded payloads")
        meta, images = r
        check(meta is r.meta and images is r.images, "a Result unpacks as (meta, images)")
        before = mx.copy()
        t[:] = -1
        check(t.flags.writeable and (t == -1).all() and np.array_equal(mx, before), "arrays are writable and separate")
        check(r.meta["producer"]["version"] == descatter.__version__ and r.meta["producer"]["git"] == hello["git"], "the result names the daemon's version")
        r16 = c.capture(phases=4, format="u16")
        check(r16.transmissive.dtype == np.dtype("<u2"), "format u16")
        try:
            c.capture(phases=1)
            check(False, "phases=1 refused")
        except descatter.BadArgument as e:
            check(e.code == "bad_argument" and "phases" in e.message and isinstance(e, ValueError),
                  "phases=1: BadArgument naming phases")
        try:
            c.call("no-such-command")
            check(False, "an unknown command refused")
        except descatter.UnknownCommand as e:
            check(e.code == "unknown_command", "unknown command: UnknownCommand")
        cal = c.calibrate(phases=4)
        check(isinstance(cal, dict) and cal["n_phases"] == 4 and cal["period_px"] > 2
              and cal["config"].startswith("[illuminator]\n"), "calibrate: the measured pattern and its config lines")
        try:
            c.calibrate(phases=2)
            check(False, "calibrate phases=2 refused")
        except descatter.BadArgument as e:
            check("phases" in e.message, "calibrate phases=2: BadArgument naming phases")
        try:
            c.capture(phasez=4)
            check(False, "a misspelt argument refused")
        except TypeError:
            check(True, "a misspelt argument is refused before sending")
        check(c.status()["sets_done"] >= 2, "the connection stays usable after refusals")
        check("socket=" in c.config()["text"], "config returns the effective configuration")


def subscriptions(d):
    with d.client() as c, d.client() as watcher:
        with c.subscribe() as sub:
            check(watcher.status()["clients"]["subscribers"] == 1, "subscribed")
            try:
                sub.next(timeout=0.3)
                check(False, "an idle subscription times out")
            except descatter.Timeout:
                check(True, "an idle subscription times out (descatter.Timeout)")
            c.start(phases=4, dark_frame=False)
            seqs = []
            for ev in sub.results():
                seqs.append(ev.seq)
                check(set(ev.images) == {"transmissive", "scattered", "mask"}, f"result event seq {ev.seq}")
                if len(seqs) == 3:
                    break
            st = c.status()  # a reply while results flow: the events are kept, not dropped
            ev = sub.next(timeout=60)
            check(ev.kind == "result" and ev.seq == seqs[-1] + 1 + ev.lost, "events read during a call are kept")
            c.stop()
            check(st["continuous"] and seqs == sorted(seqs), "continuous results in order")
        check(watcher.status()["clients"]["subscribers"] == 0, "leaving the with block unsubscribed")


def seq_gaps(tmp):
    d = Daemon(tmp, "slow", "[daemon]\nmax-queued-bytes=1000000\n")
    try:
        with d.client() as c:
            sub = c.subscribe()
            c.start(phases=2, dark_frame=False, verify_phase=False)
            events = []
            with d.client() as other:
                # Not reading until the daemon has dropped what does not fit, however slowly a
                # loaded or sanitized daemon completes sets.
                deadline = time.monotonic() + 120
                while other.status()["clients"]["results_dropped"] == 0 and time.monotonic() < deadline:
                    time.sleep(0.2)
                other.stop()
                while True:
                    try:
                        events.append(sub.next(timeout=2))
                    except descatter.Timeout:
                        break
                # A gap shows on the next event that arrives: one more result carries it.
                other.capture(phases=2)
                events.append(sub.next(timeout=60))
            st = c.status()
            lost = sum(e.lost for e in events)
            check(lost > 0 and lost == sub.lost_total, f"a slow subscriber sees gaps: {lost} lost of {len(events) + lost}")
            check(lost == st["clients"]["results_dropped"], "its gaps are the daemon's count of dropped results")
            check(all(b.seq - a.seq == 1 + b.lost for a, b in zip(events, events[1:])), "seq steps are 1 + lost")
            # Only results are published here, so the results a result says were skipped are its gap.
            check(all(e.skipped == e.lost for e in events if isinstance(e, descatter.ResultEvent)),
                  "a result's skipped is its seq gap")
            sub.close()
    finally:
        check(d.stop() == 0, "descatterd exits cleanly")


def failures_and_devices(tmp):
    # The simulated camera vanishes after 12 frames (and comes back when reopened): the set it
    # vanishes in fails, and the daemon reports the device going and coming back.
    d = Daemon(tmp, "vanishing", "[sim]\nfaults=disconnect-after=12\n")
    try:
        with d.client() as c, d.client() as listener, listener.subscribe() as sub:
            error = None
            for _ in range(6):
                try:
                    c.capture(phases=4, timeout=120)
                except descatter.DescatterError as e:
                    error = e
                    break
            check(error is not None and type(error) is descatter.ERRORS.get(error.code)
                  and error.code in ("failed", "device_error"),
                  f"the set the camera vanished in raises the class of its code ({error!r})")
            events = []
            while not {"failed", "device"} <= {e.kind for e in events}:
                try:
                    events.append(sub.next(timeout=30))
                except descatter.Timeout:
                    break
            failed = [e for e in events if isinstance(e, descatter.FailedEvent)]
            devices = [e for e in events if isinstance(e, descatter.DeviceEvent)]
            check(failed and error is not None and failed[0].reason == error.message,
                  f"subscribers get a FailedEvent with the same reason: {[e.kind for e in events]}")
            check(devices and all(e.message for e in devices), f"and DeviceEvents: {[e.message for e in devices]}")
    finally:
        check(d.stop() == 0, "descatterd exits cleanly")


def silent_peer(tmp):
    path = os.path.join(tmp, "silent.sock")
    srv = socket.socket(socket.AF_UNIX)
    srv.bind(path)
    srv.listen(1)
    held = []
    threading.Thread(target=lambda: held.append(srv.accept()), daemon=True).start()
    c = descatter.Client(path, timeout=0.5)
    t0 = time.monotonic()
    try:
        c.status()
        check(False, "a silent peer times out")
    except descatter.Timeout as e:
        check(isinstance(e, TimeoutError) and time.monotonic() - t0 < 5, "a silent peer: Timeout after the timeout")
    c.close()
    srv.close()


def tcp(tmp):
    port = socket.socket()
    port.bind(("127.0.0.1", 0))
    p = port.getsockname()[1]
    port.close()
    tok = os.path.join(tmp, "token")
    token = "python-client-token-0123"
    with open(tok, "w") as f:
        f.write(token)
    d = Daemon(tmp, "tcp", f"[daemon]\ntcp-listen=127.0.0.1:{p}\ntcp-token-file={tok}\n")
    try:
        try:
            descatter.Client(f"tcp:127.0.0.1:{p}").status()
            check(False, "TCP without a token refused")
        except descatter.Unauthorized:
            check(True, "TCP without a token: Unauthorized")
        try:
            descatter.Client(f"tcp:127.0.0.1:{p}", token="wrong-token-wrong-token")
            check(False, "a wrong token refused")
        except descatter.Unauthorized:
            check(True, "a wrong token: Unauthorized at connect")
        with descatter.Client(f"tcp:127.0.0.1:{p}", token=token) as c:
            check(c.capture(phases=4).transmissive is not None, "TCP with the token captures")
    finally:
        check(d.stop() == 0, "descatterd exits cleanly")


def asyncio_client(d):
    async def run():
        async with await descatter.aio.connect(d.sock) as c:
            progress = []
            r, st = await asyncio.gather(c.capture(phases=4, on_progress=progress.append), c.status())
            check(r.transmissive.shape == (r.meta["height"], r.meta["width"]) and st["state"],
                  "asyncio: a capture and a status in flight together")
            check([p.phase for p in progress] == list(range(len(progress))) and progress[-1].phases == 4,
                  "asyncio: progress events reach the capture's caller")
            try:
                await c.capture(phases=1)
                check(False, "asyncio: phases=1 refused")
            except descatter.BadArgument:
                check(True, "asyncio: BadArgument")
            async with await c.subscribe() as sub:
                await c.start(phases=4, dark_frame=False)
                ev = await sub.next(timeout=60)
                await c.stop()
                check(isinstance(ev, descatter.ResultEvent) and ev.images["transmissive"].flags.writeable,
                      "asyncio: subscription results")
            check((await c.status())["clients"]["subscribers"] == 0, "asyncio: async with unsubscribed")
            # A phase of 64 frames is far more than 0.3 s of silence: the Timeout cancels first.
            try:
                await c.capture(phases=64, averages=64, timeout=0.3)
                check(False, "asyncio: a capture with timeout=0.3 s times out")
            except descatter.Timeout as e:
                check(e.cancel_reply is not None and e.cancel_reply["cancelled"] == 1,
                      f"asyncio: the Timeout cancelled the capture: {e.cancel_reply} {e.cancel_error}")
            st = await c.status()
            check(st["state"] == "idle" and st["pending"] == 0, f"asyncio: idle after the Timeout ({st['state']})")
            check((await c.cancel())["cancelled"] == 0, "asyncio: cancel() with nothing running cancels nothing")
    asyncio.run(run())


def raw_frames_and_release(d):
    with d.client() as c:
        r = c.capture(phases=4, estimator="maxmin", dark_frame=True, save_phases=True,
                      outputs=["transmissive", "scattered", "mask", "max", "min", "mean"])
        frames = r.raw_frames
        check([p for p, _, _ in frames] == [0, 1, 2, 3] and all(a.dtype == np.uint16 and a.shape == r.mask.shape
                                                               for _, _, a in frames),
              "save_phases: one u16 frame per phase, in order")
        check(all(isinstance(i, int) for _, i, _ in frames), "save_phases: the camera's frame ids")
        check(r.black is not None and r.black.shape == r.mask.shape, "save_phases: the dark frame")
        raw = np.stack([a.astype(np.float64) for _, _, a in frames]) - r.black.astype(np.float64)
        check(np.array_equal(raw.max(0).astype(np.float32), r.images["max"]) and
              np.array_equal(raw.min(0).astype(np.float32), r.images["min"]) and
              np.allclose(raw.mean(0), r.images["mean"], rtol=1e-6, atol=1e-4),
              "save_phases: max, min, mean of the raw frames minus the dark frame are the daemon's planes")
        check(np.allclose(raw.max(0) - raw.min(0), r.transmissive, rtol=1e-6, atol=1e-3),
              "save_phases: max - min of the raw frames is the transmissive (maxmin)")
        check(c.capture(phases=4).raw_frames == [], "no raw frames unless asked for")
        rel = c.release()
        check(rel["state"] == "released" and c.status()["state"] == "released", "release: devices released")
        try:
            c.capture(phases=4)
            check(False, "a capture while released refused")
        except descatter.DeviceError as e:
            check("acquire" in e.message, f"a capture while released: DeviceError naming acquire ({e.message})")
        acq = c.acquire()
        check(acq["state"] == "idle" and c.capture(phases=4).transmissive is not None, "acquire: captures work again")

    async def run():
        async with await descatter.aio.connect(d.sock) as c:
            rel = await c.release()
            acq = await c.acquire()
            r = await c.capture(phases=4, save_phases=True)
            check(rel["state"] == "released" and acq["state"] == "idle" and len(r.raw_frames) == 4,
                  "asyncio: release, acquire, save_phases")
    asyncio.run(run())


def doc_examples(d):
    blocks = re.findall(r"```python\n(.*?)```", open(DOC).read(), re.S)
    check(len(blocks) >= 4, f"docs/python.md has its examples ({len(blocks)})")
    env = dict(os.environ, DESCATTER_ADDRESS=d.sock, PYTHONPATH=PYDIR)
    for i, code in enumerate(blocks):
        r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
        check(r.returncode == 0, f"docs/python.md example {i + 1} runs: {(r.stderr or r.stdout).strip()[-300:]}")


def cancelled(tmp):
    d = Daemon(tmp, "cancel")
    out = []
    with d.client() as c:
        c.capture(phases=2)  # the kernels are cached: the next set starts at once
        started = threading.Event()

        def capture():
            try:
                c.capture(phases=64, averages=16, timeout=120, on_progress=lambda ev: started.set())
                out.append("result")
            except descatter.DescatterError as e:
                out.append(e)
            except ConnectionError as e:
                out.append(e)
        t = threading.Thread(target=capture)
        t.start()
        # The SIGTERM goes once the daemon has the capture (its first phase reported), not after
        # a fixed wait: on a loaded machine the request may not have arrived yet.
        check(started.wait(120), "the capture reports a phase")
        d.proc.send_signal(signal.SIGTERM)
        t.join(120)
    d.proc.wait(30)
    check(out and isinstance(out[0], descatter.Cancelled), f"SIGTERM during a capture: Cancelled ({out})")


def cancel_and_timeout(d):
    # cancel() from a second client while the first waits on a long capture (after its first
    # phase, so the set is under way): the capture raises Cancelled, the daemon is idle and
    # counts the set cancelled. Counts, not times: the set stopped short of its 64 x 16 frames.
    with d.client() as c, d.client() as other:
        before = other.status()
        started = threading.Event()
        out = []

        def capture():
            try:
                c.capture(phases=64, averages=16, timeout=120, on_progress=lambda ev: started.set())
                out.append("result")
            except descatter.DescatterError as e:
                out.append(e)
        t = threading.Thread(target=capture)
        t.start()
        check(started.wait(120), "the capture reports a phase")
        reply = other.cancel()
        t.join(120)
        check(out and isinstance(out[0], descatter.Cancelled), f"cancel(): the capture raises Cancelled ({out})")
        check(reply["cancelled"] == 1 and reply["state"] == "idle" and not reply["stream_stopped"],
              f"cancel() says what it cancelled: {reply}")
        after = other.status()
        acquired = after["frames"]["acquired"] - before["frames"]["acquired"]
        check(after["state"] == "idle" and after["sets_cancelled"] == before["sets_cancelled"] + 1
              and after["sets_done"] == before["sets_done"] and 0 < acquired < 64 * 16,
              f"the daemon cancelled the set part way ({acquired} frames)")
        check(after["frames"]["folded"] == before["frames"]["folded"], "no frame of it folded")

    # A Timeout in a capture (a phase of 64 frames is far more than 0.3 s of silence) cancels it
    # in the daemon before it is raised; the connection stays usable.
    with d.client() as c:
        before = c.status()
        try:
            c.capture(phases=64, averages=64, timeout=0.3)
            check(False, "a capture with timeout=0.3 s times out")
        except descatter.Timeout as e:
            check(e.cancel_reply is not None and e.cancel_reply["cancelled"] == 1 and e.cancel_error is None,
                  f"the Timeout cancelled the capture: {e.cancel_reply} {e.cancel_error}")
        after = c.status()
        acquired = after["frames"]["acquired"] - before["frames"]["acquired"]
        check(after["state"] == "idle" and after["sets_cancelled"] == before["sets_cancelled"] + 1
              and acquired < 64 * 64, f"after the Timeout the daemon is idle ({acquired} frames acquired)")
        time.sleep(0.3)
        check(c.status()["frames"]["acquired"] == after["frames"]["acquired"], "nothing acquired after the cancel")
        check(c.capture(phases=4).set_id > 0, "a capture after the Timeout works on the same connection")


def main():
    with tempfile.TemporaryDirectory() as tmp:
        d = Daemon(tmp, "sim")
        try:
            basics(d)
            subscriptions(d)
            asyncio_client(d)
            raw_frames_and_release(d)
            cancel_and_timeout(d)
            doc_examples(d)
        finally:
            check(d.stop() == 0, "descatterd exits cleanly")
        seq_gaps(tmp)
        failures_and_devices(tmp)
        silent_peer(tmp)
        tcp(tmp)
        cancelled(tmp)
    print(f"{len(failures)} failed" if failures else "python client: ok")
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
