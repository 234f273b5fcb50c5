#!/usr/bin/python3
"""The Python client as a lab installs it: pip into a fresh venv outside the source tree, then
capture, stream and cancel against descatterd on the simulated lab from that venv.
Usage: test_python_venv.py DESCATTERD DESCATTERCTL SOURCE_DIR

Independent checks (third-party tools: venv, pip, importlib.metadata, mypy):
- `python3 -m venv --system-site-packages` + `pip install --no-build-isolation --no-index
  daemon/python` succeeds offline, and the venv imports descatter from its own site-packages
  (not the source tree or build/python) with py.typed next to it;
- the version is the project's: CMakeLists.txt's project(VERSION), descatter.__version__ and
  the metadata pip recorded (importlib.metadata) are one string;
- mypy --strict, on a typed user script against the installed package, flags only its
  misspelt capture keyword (the package is typed and its parameters explicit);
- a misspelt keyword is a TypeError before anything is sent (a listening socket receives no
  byte);
- a capture's payloads obey max/min's closed form (transmissive = max - min), a stream brings
  results with rising seq, cancel() from a second client ends a capture with Cancelled;
- repr(Result) is one short line; `async with connect()` and `async with await connect()` both
  work."""
import os
import re
import shutil
import subprocess
import sys
import tempfile

DAEMON, CTL, SRC = sys.argv[1], sys.argv[2], sys.argv[3]
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from live_daemon import LiveDaemon  # noqa: E402

# Runs inside the venv: everything it checks is printed as "ok ..." or raises.
CLIENT_SCRIPT = r'''
import asyncio, importlib.metadata, os, socket, sys, threading
import numpy as np
import descatter, descatter.aio

site = sys.argv[1]
assert os.path.realpath(descatter.__file__).startswith(os.path.realpath(site)), descatter.__file__
assert os.path.exists(os.path.join(os.path.dirname(descatter.__file__), "py.typed"))
print("version", descatter.__version__, importlib.metadata.version("descatter"))

# A misspelt keyword never reaches the wire: a socket that only listens gets no byte.
with socket.socket(socket.AF_UNIX) as srv:
    path = os.path.join(os.path.dirname(os.environ["DESCATTER_ADDRESS"]), "silent.sock")
    srv.bind(path)
    srv.listen(1)
    c = descatter.Client(path)
    peer, _ = srv.accept()
    for call in (lambda: c.capture(phase=8), lambda: c.start(phases=4, exposure=100),
                 lambda: c.calibrate(estimator="sine")):
        try:
            call()
            raise AssertionError("no TypeError")
        except TypeError as e:
            print("ok TypeError:", e)
    peer.setblocking(False)
    try:
        got = peer.recv(100)
    except BlockingIOError:
        got = b""
    assert got == b"", got
    c.close()
    peer.close()
print("ok nothing sent")

with descatter.Client() as c:
    r = c.capture(phases=4, estimator="maxmin", dark_frame=False,
                  outputs=["transmissive", "scattered", "mask", "max", "min"])
    t, mx, mn = r.transmissive, r.images["max"], r.images["min"]
    assert t is not None and t.shape == mx.shape
    err = float(np.max(np.abs(t - (mx - mn))))
    assert err <= 1e-3 * max(1.0, float(np.max(mx))), err
    print("ok capture: transmissive = max - min to", err)
    text = repr(r)
    assert len(text) < 200 and "\n" not in text and "set" in text, text
    print("ok repr:", text)

    with c.subscribe() as sub:
        c.start(phases=4, dark_frame=False)
        seqs = []
        for ev in sub.results():
            seqs.append(ev.seq)
            assert ev.result.transmissive is not None
            if len(seqs) == 3:
                break
        c.stop()
    assert all(isinstance(s, int) for s in seqs) and seqs == sorted(seqs) and len(set(seqs)) == 3, seqs
    print("ok stream:", seqs)

    with descatter.Client() as other:
        out, started = [], threading.Event()

        def capture():
            try:
                out.append(c.capture(phases=64, averages=16, on_progress=lambda ev: started.set()))
            except descatter.Cancelled as e:
                out.append(e)
        th = threading.Thread(target=capture)
        th.start()
        assert started.wait(120)
        reply = other.cancel()
        th.join()
        assert isinstance(out[0], descatter.Cancelled) and reply["cancelled"] == 1, (out, reply)
        print("ok cancel:", reply)


async def aio():
    async with descatter.aio.connect() as c:
        st = await c.status()
        r = await c.capture(phases=4, dark_frame=False)
        assert r.transmissive is not None
    async with await descatter.aio.connect() as c2:
        st2 = await c2.status()
    print("ok async with connect():", st["state"], st2["state"])
asyncio.run(aio())
'''

# A user's script as mypy --strict sees it with the installed package.
TYPED_BAD = '''import descatter
import descatter.aio
import numpy as np


def mean_transmissive(address: str) -> float:
    with descatter.Client(address) as c:
        r = c.capture(phase=8, exposure_us=2000.0, dark_frame=True)
        t = r.transmissive
        return float(np.mean(t)) if t is not None else 0.0


async def state(address: str) -> str:
    async with descatter.aio.connect(address) as a:
        r = await a.capture(phases=4, estimator="sine", outputs=["transmissive"])
        print(repr(r), r.set_id)
        return str((await a.status())["state"])
'''

failures = []


def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what, flush=True)
    if not cond:
        failures.append(what)


def run(cmd, **kw):
    r = subprocess.run(cmd, capture_output=True, text=True, **kw)
    return r


def main():
    project = re.search(r"project\(descatter VERSION ([0-9.]+)", open(os.path.join(SRC, "CMakeLists.txt")).read())
    with tempfile.TemporaryDirectory(prefix="descatter-venv-") as tmp:
        assert not os.path.realpath(tmp).startswith(os.path.realpath(SRC))
        venv = os.path.join(tmp, "venv")
        r = run(["/usr/bin/python3", "-m", "venv", "--system-site-packages", venv])
        check(r.returncode == 0, f"venv created: {r.stderr[-500:]}")
        # pip builds in the folder it is given: a copy keeps the source tree clean.
        pkg = os.path.join(tmp, "python")
        shutil.copytree(os.path.join(SRC, "daemon", "python"), pkg,
                        ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__", "CMakeLists.txt"))
        py = os.path.join(venv, "bin", "python")
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PIP_INDEX_URL")}
        r = run([py, "-m", "pip", "install", "--no-build-isolation", "--no-index", "--disable-pip-version-check",
                 pkg], env=env)
        check(r.returncode == 0, f"pip install: {(r.stdout + r.stderr)[-1500:]}")
        site = run([py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], env=env).stdout.strip()

        # One mypy run (it is the slow part): the misspelt keyword is its only complaint, so the
        # rest of the script, typed against the installed package, passes --strict.
        path = os.path.join(tmp, "user_script.py")
        open(path, "w").write(TYPED_BAD)
        r = run([py, "-m", "mypy", "--strict", "--no-incremental", "--cache-dir", os.devnull, path], env=env, cwd=tmp)
        errors = [ln for ln in r.stdout.splitlines() if ": error:" in ln]
        check(r.returncode == 1 and len(errors) == 1 and
              errors[0].startswith("user_script.py:8:") and 'Unexpected keyword argument "phase"' in errors[0],
              f"mypy --strict on a user script against the venv's package flags capture(phase=8) only: {r.stdout}")

        d = LiveDaemon(DAEMON, CTL, tmp)
        try:
            env["DESCATTER_ADDRESS"] = d.sock
            r = run([py, "-c", CLIENT_SCRIPT, site], env=env, cwd=tmp, timeout=600)
            print(r.stdout, r.stderr[-3000:], flush=True)
            check(r.returncode == 0, "capture, stream, cancel and asyncio from the venv")
            versions = next((ln.split()[1:] for ln in r.stdout.splitlines() if ln.startswith("version ")), [])
            check(project is not None and versions == [project.group(1)] * 2,
                  f"version: CMakeLists.txt {project and project.group(1)}, __version__ and pip's metadata {versions}")
        finally:
            d.stop()
    if failures:
        print(f"{len(failures)} failure(s)")
        sys.exit(1)


if __name__ == "__main__":
    main()
