#!/usr/bin/python3
"""status tells the truth about dark frames (and stop about what it stopped), through descatterd
on the simulated lab.
Usage: test_status_dark.py DESCATTERD DESCATTERCTL DESCATTER-SIM SCENE

Before, `descatterctl status` said "dark frame: none yet" while every set took and subtracted
its own dark frame (the default, dark-frame=true): it reported only the dark command's frame.
Now status says which dark frame the next set subtracts (mode: per-set, stored, none), and when
the last one was taken, by whom and at what level. The expectations are independent of the
daemon's arithmetic:
- the level: the mean of the illuminator-off frame that `descatter-sim render` draws for the
  same scene offline (another program, its own noise seed), and the mean of the very dark frame
  the set saved (`--save-phases`: black.png), read with PIL and numpy;
- the time: the test's own clock around the request;
- the mode: the configuration written and the options given."""
import datetime
import json
import os
import socket
import subprocess
import sys
import tempfile
import time

import numpy as np
from PIL import Image

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from live_daemon import LiveDaemon  # noqa: E402

DAEMON, CTL, SIM, SCENE = sys.argv[1:5]
failures = []


def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what, flush=True)
    if not cond:
        failures.append(what)


def png_mean(path):
    return float(np.asarray(Image.open(path)).astype(np.float64).mean())


def taken_at(d):
    return datetime.datetime.fromisoformat(d["taken_utc"].replace("Z", "+00:00")).timestamp()


def within(d, before, after):
    # The daemon's wall clock against the test's; 1 ms of slack for rounding.
    return d is not None and before - 1e-3 <= taken_at(d) <= after + 1e-3


def offline_dark_level(tmp):
    out = os.path.join(tmp, "offline")
    subprocess.run([SIM, "render", "-n", "2", "--seed", "7", "-o", out, SCENE], check=True, capture_output=True)
    return png_mean(os.path.join(out, "black.png"))


def fresh_daemon(tmp, name, conf=""):
    """A descatterd on the scene in its own folder tmp/name, with conf added to its configuration."""
    folder = os.path.join(tmp, name)
    os.mkdir(folder)
    return folder, LiveDaemon(DAEMON, CTL, folder, f"[sim]\nscene={SCENE}\n{conf}")


def check_idle(d, mode, what):
    """Before any set: the dark mode the configuration gives, and no dark frame taken yet."""
    st = d.status()
    check(st["dark"]["mode"] == mode and st["dark"]["last"] is None, f"{what}: {st['dark']}")


def per_set_default(tmp, offline):
    """The default configuration: every set takes its own dark frame."""
    folder, d = fresh_daemon(tmp, "per-set")
    try:
        check_idle(d, "per-set", "idle, default configuration: per-set, none taken yet")
        text = d.ctl("status").stdout
        check("taken by every set" in text and "none taken yet" in text,
              f"the summary says every set takes one: {text!r}")
        out = os.path.join(folder, "cap")
        before = time.time()
        d.ctl("capture", "-n", "4", "-q", "--save-phases", "--out", out)
        after = time.time()
        st = d.status()
        last = st["dark"]["last"]
        phases = [os.path.join(out, n) for n in os.listdir(out) if n.endswith("-phases")]
        saved = png_mean(os.path.join(phases[0], "black.png")) if len(phases) == 1 else float("nan")
        check(last is not None and last["source"] == "set" and last["frames"] == 1 and within(last, before, after),
              f"after a capture: the last dark frame is the set's, taken during the request: {last}")
        check(last is not None and abs(last["mean_dn"] - saved) < 1e-6 * max(1.0, saved),
              f"its level is the mean of the dark frame the set saved ({saved:.4f} DN): {last and last['mean_dn']}")
        check(last is not None and abs(last["mean_dn"] - offline) < 0.5,
              f"... and the scene's illuminator-off level rendered offline ({offline:.3f} DN): {last and last['mean_dn']}")
        check(st["dark"]["stored"] is None and st["has_dark"] is False, "no dark command: nothing stored")
        text = d.ctl("status").stdout
        check("last by a set at" in text and f"mean {last['mean_dn']:.1f} DN" in text,
              f"the summary names the last dark frame and its level: {text!r}")
        # A capture the devices fail is no bad request: the summary counts replies with an error
        # (it said "1 bad" for a device failure, as if the client had sent garbage).
        with socket.socket(socket.AF_UNIX) as c:
            c.connect(d.sock)
            c.sendall(b'{"id": 1, "cmd": "capture", "args": {"phases": 1}}\n')
            reply = json.loads(c.makefile().readline())
        text = d.ctl("status").stdout
        check(reply.get("ok") is False and "1 answered with an error" in text and " bad)" not in text,
              f"the summary counts error replies as such: {reply} {text!r}")
        # A capture without a dark frame leaves the last one as it was (none taken by it).
        d.ctl("capture", "-n", "4", "-q", "--no-dark-frame", "--out", os.path.join(folder, "nodark"))
        again = d.status()["dark"]["last"]
        check({k: v for k, v in again.items() if k != "age_s"} == {k: v for k, v in last.items() if k != "age_s"},
              f"a set without a dark frame does not pass for one: {again}")
    finally:
        d.stop()  # asserts a clean exit


def without_per_set(tmp, offline):
    """dark-frame=false: nothing subtracted until the dark command stores one at the sets' exposure."""
    folder, d = fresh_daemon(tmp, "stored", "[acquisition]\ndark-frame=false\n")
    try:
        check_idle(d, "none", "dark-frame=false: none subtracted")
        check("NONE subtracted" in d.ctl("status").stdout, "the summary says nothing is subtracted")
        before = time.time()
        reply = json.loads(d.ctl("dark", "--json").stdout)
        after = time.time()
        st = d.status()
        stored = st["dark"]["stored"]
        check(st["dark"]["mode"] == "stored" and st["has_dark"] is True and within(stored, before, after)
              and stored["source"] == "dark-command",
              f"after the dark command at the default exposure: stored, taken during the request: {st['dark']}")
        check(stored is not None and abs(stored["mean_dn"] - offline) < 0.5 and
              abs(stored["mean_dn"] - reply["dark_mean_dn"]) < 1e-9,
              f"its level is the scene's illuminator-off level ({offline:.3f} DN) and the reply's: {stored}")
        text = d.ctl("status").stdout
        check("the dark command's, subtracted from every set" in text and "last by the dark command" in text,
              f"the summary: {text!r}")
        # A dark frame at another exposure is stored, but no longer applies to the sets.
        exposure = stored["exposure_us"] / 2
        d.ctl("dark", "--exposure-us", f"{exposure:g}")
        st = d.status()
        check(st["dark"]["mode"] == "none" and st["dark"]["stored"]["exposure_us"] == exposure,
              f"a stored dark frame at another exposure is not subtracted: {st['dark']}")
        check("other exposure or gain" in d.ctl("status").stdout, "... and the summary says why")
        # Continuous mode with its own dark frames: per-set while it runs, and the last is a set's.
        d.ctl("start", "-n", "4", "--dark-frame")
        st = d.wait_for(lambda s: s["dark"]["last"] and s["dark"]["last"]["source"] == "set", "a set's dark frame")
        check(st["dark"]["mode"] == "per-set" and st["continuous"] is True,
              f"start --dark-frame: per-set while running: {st['dark']}")
        check(abs(st["dark"]["last"]["mean_dn"] - offline) < 0.5, "the set's dark frame has the scene's level")
        stopped = json.loads(d.ctl("stop", "--json").stdout)
        check(stopped.get("was_running") is True and "stops after the set in progress" in stopped.get("message", ""),
              f"stop says that continuous acquisition was on and stops (it printed {{}}): {stopped}")
        st = d.wait_for(lambda s: not s["continuous"], "continuous mode to stop")
        again = json.loads(d.ctl("stop", "--json").stdout)
        check(again.get("was_running") is False and "was not running" in again.get("message", ""),
              f"a second stop says nothing was running: {again}")
        check(st["dark"]["mode"] == "none", f"stopped: back to the configuration's: {st['dark']}")
    finally:
        d.stop()  # asserts a clean exit


def main():
    with tempfile.TemporaryDirectory() as tmp:
        offline = offline_dark_level(tmp)
        per_set_default(tmp, offline)
        without_per_set(tmp, offline)
    print(f"{len(failures)} failed" if failures else "status dark: ok")
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
