#!/usr/bin/python3
"""The sampling precondition in descatterd (issue 12, "Estimators"): the daemon separates with
the projected period, so that pixels no phase lights fully are flagged `undersampled`, and it
warns when maxmin or robust meet sine stripes. Usage: test_daemon_sampling.py BINDIR PYTHONDIR SCENE

Expectation from geometry alone: square stripes of period 16 px and duty 1/4 are 4 px wide; at
N = 4 phase steps are 4 px, so a 1-px pixel [x - 1/2, x + 1/2] lies inside some phase's stripe
only when its centre is within 1.5 px of that stripe's centre: 3 of every 4 columns. Exactly a
quarter of the pixels are never fully lit (flagged); at N = 8 (steps of 2 px) none is. The
phase check is on: the scene's wire grid has a pitch of twice the stripe period, the texture
that made a single frame's phase miss by 17.6 deg (sine) and 12.5 deg (duty 0.25), and every
frame must still verify (none dropped, none passed unverified)."""
import os
import subprocess
import sys
import tempfile
import time

BIN, PYDIR, SCENE = sys.argv[1:4]
sys.path.insert(0, PYDIR)
import descatter  # noqa: E402

DAEMON = os.path.join(BIN, "descatterd")
failures = []


def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what, flush=True)
    if not cond:
        failures.append(what)


def scene_with(path, illuminator):
    out, skip = [], False
    for line in open(SCENE).read().splitlines():
        if line.startswith("["):
            skip = line == "[illuminator]"
            if skip:
                out.append("[illuminator]\n" + illuminator)
                continue
        if not skip:
            out.append(line)
    with open(path, "w") as f:
        f.write("\n".join(out) + "\n")


def daemon(tmp, name, illuminator):
    scene = os.path.join(tmp, name + ".scene")
    scene_with(scene, illuminator)
    conf = os.path.join(tmp, name + ".conf")
    with open(conf, "w") as f:
        f.write(f"[camera]\nbackend=sim\n[illuminator]\nbackend=sim\n[sim]\nscene={scene}\n")
    sock = os.path.join(tmp, name + ".sock")
    log = os.path.join(tmp, name + ".log")
    proc = subprocess.Popen([DAEMON, "--config", conf, "--socket", sock, "--no-socket-activation"],
                            stdout=open(log, "w"), stderr=subprocess.STDOUT)
    deadline = time.time() + 120
    while True:
        try:
            with descatter.Client(sock) as c:
                if c.status()["ready"]:
                    return proc, sock, log
        except (OSError, descatter.DescatterError):
            pass
        assert proc.poll() is None and time.time() < deadline, "descatterd not ready"
        time.sleep(0.2)


def stop(proc):
    proc.terminate()
    return proc.wait(30)


def main():
    with tempfile.TemporaryDirectory(prefix="ds-sampling-") as tmp:
        proc, sock, log = daemon(tmp, "narrow", "pattern=square\nperiod-px=16\nduty=0.25\nirradiance=0.5\n")
        try:
            with descatter.Client(sock) as c:
                for n, want in ((4, 0.25), (8, 0.0)):
                    r = c.capture(phases=n, estimator="maxmin", verify_phase=True)
                    check(r.meta["frames"]["dropped"] == 0, f"N = {n}: no frame rejected: {r.meta['frames']}")
                    check(r.meta["frames"]["unverified"] == 0, f"N = {n}: every frame verified")
                    sep = r.meta["separation"]
                    pixels = r.transmissive.size
                    got = sep["flagged"]["undersampled"] / pixels
                    check(abs(got - want) < 0.01, f"N = {n}: undersampled fraction {got:.4f} (geometry: {want})")
                    mask_frac = float(((r.mask & 64) != 0).mean())
                    check(abs(mask_frac - got) < 1e-9, f"N = {n}: the mask's bit 64 marks the same pixels")
        finally:
            check(stop(proc) == 0, "descatterd exits cleanly")

        proc, sock, log = daemon(tmp, "sine", "pattern=sine\nperiod-px=16\nirradiance=0.5\n")
        try:
            with descatter.Client(sock) as c:
                for estimator in ("maxmin", "sine", "sine"):
                    r = c.capture(phases=8, estimator=estimator, verify_phase=True)
                    check(r.meta["frames"]["dropped"] == 0, f"sine stripes, {estimator}: no frame rejected")
                    check(r.meta["frames"]["unverified"] == 0, f"sine stripes, {estimator}: every frame verified")
        finally:
            check(stop(proc) == 0, "descatterd exits cleanly")
        text = open(log).read()
        warned = [line for line in text.splitlines() if "assumes square stripes" in line]
        check(len(warned) == 1 and "maxmin" in warned[0], f"maxmin on sine stripes warned once: {warned}")
    if failures:
        print(f"{len(failures)} failure(s)")
        sys.exit(1)


main()
