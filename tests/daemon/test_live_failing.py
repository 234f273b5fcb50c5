#!/usr/bin/python3
"""A failing rig on the live view, in headless Chromium: the simulated camera delivers every
frame incomplete ([sim] faults = incomplete=1), so every set fails once its retries are exhausted.
Start from the page: the daemon answers the start itself, but the page raises a loud banner
that says every set of the run failed (and, loud still, once the run ended), with the time it saw it, the daemon's reason (status'
last_error, read here over the socket) and a remedy naming the camera's network. A Capture from the
page then fails and the banner shows the reply's error code and message. Optionally saves a
screenshot of the loud banner (docs/live-view-failing.png is made so:
tests/daemon/test_live_failing.py DESCATTERD DESCATTERCTL docs/live-view-failing.png).
Usage: test_live_failing.py DESCATTERD DESCATTERCTL [SCREENSHOT.png]"""
import os
import re
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cdp_browser import Browser  # noqa: E402
from live_daemon import LiveDaemon  # noqa: E402
from live_page import BODY, banner  # noqa: E402


def main():
    daemon, ctl = sys.argv[1:3]
    shot = sys.argv[3] if len(sys.argv) > 3 else None
    with tempfile.TemporaryDirectory() as tmp:
        d = LiveDaemon(daemon, ctl, tmp, "[http]\nlisten=127.0.0.1:0\n[acquisition]\nphases=6\n"
                                         "[sim]\nfaults=incomplete=1\n")
        b = Browser(height=760)
        try:
            b.open(d.page_url())
            b.wait(f"{BODY}.connected === '1' && {BODY}.state === 'idle'", "the page connected, the daemon idle")
            assert not banner(b)["shown"], banner(b)
            b.js("document.getElementById('phases').value = 6")
            b.click("#start")
            st = d.wait_for(lambda s: s["sets_failed"] >= 2, "two failed sets", timeout=40)
            assert st["sets_done"] == 0, st["sets_done"]
            b.wait(f"{BODY}.banner === 'continuous-failing'", "the continuous run's banner", timeout=20)
            bn = banner(b)
            reason = d.status()["last_error"]
            assert reason and reason.split(":")[0] in bn["text"], (reason, bn)
            assert bn["shown"] and bn["cls"] == "loud" and bn["top"] < 200, bn
            assert re.search(r"all \d+ sets since \d\d:\d\d:\d\d failed, none done", bn["text"]), bn["text"]
            assert re.match(r"\d\d:\d\d:\d\d \(\d\d:\d\d:\d\d UTC\)", bn["when"]), bn["when"]
            assert "network" in bn["remedy"], bn["remedy"]
            if shot:
                b.screenshot(shot)
            n = int(b.js(f"Number({BODY}.replies || 0)"))
            b.click("#stop")
            b.wait(f"Number({BODY}.replies || 0) > {n}", "the stop's reply")
            d.wait_for(lambda s: s["state"] == "idle" and not s["continuous"], "idle after the stop", timeout=40)
            # The run ended with every set failed: still loud.
            b.wait(f"{BODY}.state === 'idle'", "the page seeing the daemon idle")
            bn = banner(b)
            assert b.js(f"{BODY}.banner") == "continuous-ended" and bn["cls"] == "loud", bn
            assert re.search(r"Continuous run ended: all \d+ sets since \d\d:\d\d:\d\d failed", bn["text"]), bn["text"]
            # A single capture fails too: its reply's error is the banner's cause.
            b.js("document.getElementById('banner-dismiss').click()")
            assert not banner(b)["shown"]
            n = int(b.js(f"Number({BODY}.replies || 0)"))
            banners = int(b.js(f"Number({BODY}.banners || 0)"))
            failed = d.status()["sets_failed"]
            b.click("#capture")
            b.wait(f"Number({BODY}.replies || 0) > {n}", "the capture's reply", timeout=60)
            assert b.js(f"{BODY}.lastReply") == "error"
            # The reply and the status that counts the failed set both report the failure (which
            # comes first depends on the machine's load): one banner, raised by the first.
            failed_now = d.wait_for(lambda s: s["sets_failed"] > failed, "the failed set counted",
                                    timeout=60)["sets_failed"]
            assert failed_now == failed + 1, (failed, failed_now)
            b.wait(f"Number({BODY}.setsFailed) === {failed_now}", "the page seeing the failed set", timeout=60)
            assert int(b.js(f"Number({BODY}.banners || 0)")) == banners + 1, (banners, b.js(f"{BODY}.banners"))
            b.wait(f"({BODY}.banner || '').startsWith('reply-') || {BODY}.banner === 'set-failed'",
                   "the capture's banner", timeout=60)
            bn = banner(b)
            reply = b.js("document.getElementById('reply').textContent")
            code = reply.split(": ")[1]
            assert bn["shown"] and code in ("failed", "device_error"), (bn, reply)
            if b.js(f"{BODY}.banner") == "set-failed":
                reason = d.status()["last_error"]
                assert reason and reason.split(":")[0] in bn["text"], (reason, bn)
            else:
                assert code in bn["text"], (bn, reply)
            assert "network" in bn["remedy"], bn["remedy"]
            assert not b.console, b.console
        finally:
            b.close()
            d.stop()
    print("failing rig banner in chromium: ok")


if __name__ == "__main__":
    main()
