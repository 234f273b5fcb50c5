#!/usr/bin/python3
"""A rig whose camera shows no stripes: Aravis's own stock fake camera (arv-fake-gv-camera-0.8,
Debian's aravis-tools), whose frames are a diagonal ramp that moves one pixel per frame whatever
the illuminator (descatter-labsim's Modbus controller) lights. Run through netns_run.sh (UDP
3956 on 127.0.0.1 is the fake camera's; labsim's own camera serves on 127.0.0.2).
Usage: test_no_stripes_rig.py BINDIR ARV_FAKE_GV_CAMERA SCENE

- `descatterctl calibrate` on the rig refuses the set, naming the period it searched and what it
  measured (the modulation that steps with the phases against what does not), as offline
  `descatterctl calibrate DIR` refuses the same frames saved by `capture --save-phases`; no
  configuration lines are printed (before: a period of 15.7 px in Mono16, 254 px in Mono8, and
  [illuminator] lines to paste).
- `descatterctl capture --target-error` is refused with the wire code `failed` (not
  `bad_argument`: the request was fine, the scene is not) and the reason: no stripes at the
  configured period."""
import json
import os
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from daemon_checks import check, failures, spawn  # noqa: E402

BIN, FAKE, SCENE = sys.argv[1:4]
CTL = os.path.join(BIN, "descatterctl")


def stop(proc):
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(30)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def ctl(sock, *args, timeout=180):
    return subprocess.run([CTL, "-a", sock, *args], capture_output=True, text=True, timeout=timeout)


class Rig:
    """The stock fake camera, labsim's Modbus illuminator and a descatterd using both."""

    def __init__(self, tmp, pixel_format):
        self.procs = []
        self.procs.append(spawn([FAKE, "-i", "127.0.0.1", "-s", "DSNOSTRIPES"], stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL))
        labsim = spawn([os.path.join(BIN, "descatter-labsim"), "--scene", SCENE, "--camera-address", "127.0.0.2",
                        "--modbus", "127.0.0.1:0"], stdout=subprocess.PIPE, text=True)
        self.procs.append(labsim)
        port = None
        for line in labsim.stdout:
            if "ready camera=" in line:
                port = int(line.split(" modbus=127.0.0.1:")[1].split()[0])
                break
        assert port, "descatter-labsim did not get ready"
        self.conf = os.path.join(tmp, f"{pixel_format}.conf")
        self.sock = os.path.join(tmp, f"{pixel_format}.sock")
        self.log_path = os.path.join(tmp, f"{pixel_format}.log")
        with open(self.conf, "w") as f:
            # A 512 x 256 region keeps the frames small; the ramp is the same.
            f.write(f"[camera]\nbackend=aravis\naddress=127.0.0.1\npixel-format={pixel_format}\n"
                    f"roi=0,0,512,256\n[illuminator]\nbackend=modbus\nmodbus-uri=tcp://127.0.0.1:{port}\n"
                    "[acquisition]\nphases=8\n")
        log = open(self.log_path, "w")
        self.daemon = spawn([os.path.join(BIN, "descatterd"), "--config", self.conf, "--socket", self.sock,
                             "--no-socket-activation"], stdout=log, stderr=subprocess.STDOUT)
        self.procs.append(self.daemon)
        deadline = time.time() + 120
        while True:
            r = ctl(self.sock, "status", "--json")
            if r.returncode == 0 and json.loads(r.stdout)["ready"]:
                st = json.loads(r.stdout)
                break
            assert self.daemon.poll() is None, "descatterd exited: " + open(self.log_path).read()[-2000:]
            assert time.time() < deadline, "descatterd not ready"
            time.sleep(0.2)
        check(st["devices"]["camera"].get("serial") == "DSNOSTRIPES",
              f"{pixel_format}: the daemon uses the stock fake camera ({st['devices']['camera'].get('serial')})")

    def close(self):
        for p in reversed(self.procs):
            stop(p)


def no_config_lines(text):
    return "[illuminator]" not in text and "period-px=" not in text and "--period" not in text


def calibrate(rig, pf, tmp):
    r = ctl(rig.sock, "calibrate", "--phases", "8")
    print(r.stdout + r.stderr)
    check(r.returncode != 0, f"{pf}: calibrate on the rig fails (exit {r.returncode})")
    # At the period the search found (the ramp's, Mono16), or at none (Mono8 at this width)
    check("failed:" in r.stderr and ("no stripes at the measured period" in r.stderr
                                     or "no stripes at any period from 2.5 to 256 px" in r.stderr),
          f"{pf}: ... with `failed` and no stripes at the period(s) it searched")
    check(("steps with the phases" in r.stderr and "standard errors where 5 are needed" in r.stderr)
          or "standard deviations of its noise, where 8 are needed" in r.stderr,
          f"{pf}: ... saying what it measured")
    check(no_config_lines(r.stdout + r.stderr), f"{pf}: ... and no configuration lines")
    r = ctl(rig.sock, "calibrate", "--phases", "8", "--period", "16")
    check(r.returncode != 0 and "no stripes at the given period 16 px" in r.stderr
          and no_config_lines(r.stdout + r.stderr), f"{pf}: calibrate --period 16 on the rig fails alike")
    # The same frames offline: saved by capture --save-phases, calibrated from the folder.
    out = os.path.join(tmp, pf + "-set")
    r = ctl(rig.sock, "capture", "--save-phases", "--no-verify", "-q", "-o", out)
    check(r.returncode == 0, f"{pf}: capture --save-phases --no-verify {r.stderr.strip()}")
    folders = [os.path.join(out, d) for d in os.listdir(out) if d.endswith("-phases")] if r.returncode == 0 else []
    if folders:
        r = subprocess.run([CTL, "calibrate", folders[0]], capture_output=True, text=True, timeout=120)
        print(r.stdout + r.stderr)
        check(r.returncode != 0 and "no stripes at the" in r.stderr and no_config_lines(r.stdout),
              f"{pf}: offline calibrate of the saved frames fails alike")


def target_error(rig, pf):
    r = ctl(rig.sock, "capture", "--target-error", "0.03", "-q", "-o", os.path.join(os.path.dirname(rig.sock), "x"))
    print(r.stdout + r.stderr)
    check(r.returncode != 0, f"{pf}: capture --target-error 0.03 fails (exit {r.returncode})")
    check("bad_argument" not in r.stderr and "failed:" in r.stderr,
          f"{pf}: ... with `failed`, not `bad_argument` (the request was fine)")
    check("no stripes at the configured period" in r.stderr, f"{pf}: ... saying there are no stripes")


def main():
    with tempfile.TemporaryDirectory(prefix="ds-nostripes-") as tmp:
        for pf in ("Mono16", "Mono8"):
            rig = Rig(tmp, pf)
            try:
                calibrate(rig, pf, tmp)
                target_error(rig, pf)
                check(rig.daemon.poll() is None, f"{pf}: the daemon keeps serving")
            finally:
                rig.close()
            if failures:
                print(open(rig.log_path).read()[-3000:])
    if failures:
        print(f"{len(failures)} failure(s)")
        sys.exit(1)


main()
