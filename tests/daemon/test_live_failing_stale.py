#!/usr/bin/python3
"""The live view's banner for a failure only the status reports, after a capture failure of the
same message that no status matched (daemon/service/live_page.html, failureReports), in headless
Chromium on the simulated lab with every frame incomplete ([sim] faults = incomplete=1: every
set fails with the same message).

1. A Capture from the page during a continuous run fails. The status counts its set with the
   run's (the run's banner), so nothing matches the reply's report; a set another client
   starts afterwards fails the same way, and only the status reports it to this page: it
   raises its own banner ("1 set failed — ..."), not swallowed by the capture's report.
2. That failure was not this page's: the page keeps no report waiting for a reply of its own;
   the page's next Capture fails with one banner, and no report stays waiting.
3. A Capture refused before any set runs (the devices released: device_error, never counted as
   a failed set) raises its banner, and its report goes once two statuses passed. No failure
   the daemon counts carries that refusal's message, so case 1 gives the collision instead.
Usage: test_live_failing_stale.py DESCATTERD DESCATTERCTL"""
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cdp_browser import Browser  # noqa: E402
from live_daemon import LiveDaemon  # noqa: E402
from live_page import BODY, banner  # noqa: E402


def banners(b):
    return int(b.js(f"Number({BODY}.banners || 0)"))


def page_capture(b):
    """Clicks Capture and waits for its reply: (code, message) of its error."""
    n = int(b.js(f"Number({BODY}.replies || 0)"))
    b.click("#capture")
    b.wait(f"Number({BODY}.replies || 0) > {n}", "the capture's reply", timeout=60)
    assert b.js(f"{BODY}.lastReply") == "error", b.js("document.getElementById('reply').textContent")
    reply = b.js("document.getElementById('reply').textContent")  # "#ID: CODE: MESSAGE"
    _, code, message = reply.split(": ", 2)
    return code, message


def no_reports_waiting(b, what):
    b.wait(f"Number({BODY}.pendingByReply) === 0 && Number({BODY}.pendingByStatus) === 0", what, timeout=20)


def main():
    daemon, ctl = sys.argv[1:3]
    with tempfile.TemporaryDirectory() as tmp:
        # max-failed-sets = 0: the run goes on failing until it is stopped, the capture inside it.
        d = LiveDaemon(daemon, ctl, tmp, "[http]\nlisten=127.0.0.1:0\n[acquisition]\nphases=6\nmax-failed-sets=0\n"
                                         "[sim]\nfaults=incomplete=1\n")
        b = Browser(height=760)
        try:
            b.open(d.page_url())
            b.wait(f"{BODY}.connected === '1' && {BODY}.state === 'idle'", "the page connected, the daemon idle")
            b.js("document.getElementById('phases').value = 6")

            # 1. The page's capture inside a failing continuous run.
            b.click("#start")
            b.wait(f"{BODY}.banner === 'continuous-failing'", "the continuous run's banner", timeout=40)
            code, message = page_capture(b)
            assert code in ("device_error", "failed"), (code, message)
            n = int(b.js(f"Number({BODY}.replies || 0)"))
            b.click("#stop")
            b.wait(f"Number({BODY}.replies || 0) > {n}", "the stop's reply")
            d.wait_for(lambda s: s["state"] == "idle" and not s["continuous"], "idle after the stop", timeout=40)
            b.wait(f"{BODY}.state === 'idle'", "the page seeing the daemon idle")
            # The capture's report goes at the status that counts its set, or by the second status
            # after its reply when that status came first (the page's bound); a failure counted
            # before then could not be told from the capture's own.
            b.wait(f"Number({BODY}.pendingByReply || 0) === 0", "the capture's report resolved", timeout=20)
            b.js("document.getElementById('banner-dismiss').click()")
            before, failed = banners(b), d.status()["sets_failed"]
            # Another client's capture fails with the same message; only the status tells the page.
            r = d.ctl("capture", "-o", os.path.join(tmp, "other"), check=False)
            assert r.returncode != 0 and message in r.stderr, (message, r.stderr)
            st = d.wait_for(lambda s: s["sets_failed"] > failed, "the other client's failed set", timeout=60)
            assert st["sets_failed"] == failed + 1 and st["last_error"] == message, (failed, st["sets_failed"],
                                                                                     st["last_error"], message)
            b.wait(f"Number({BODY}.setsFailed) === {failed + 1}", "the page seeing the failed set", timeout=20)
            assert banners(b) == before + 1, ("the status-only failure raised no banner", before, banners(b))
            bn = banner(b)
            assert b.js(f"{BODY}.banner") == "set-failed" and bn["shown"], (b.js(f"{BODY}.banner"), bn)
            assert f"1 set failed — {message}" in bn["text"], (message, bn)

            # 2. Not this page's failure: no report waits for a reply, and the page's own capture
            # failing the same way raises one banner.
            assert int(b.js(f"Number({BODY}.pendingByStatus)")) == 0, b.js(f"{BODY}.pendingByStatus")
            b.js("document.getElementById('banner-dismiss').click()")
            before, failed = banners(b), d.status()["sets_failed"]
            code, again = page_capture(b)
            assert again == message, (again, message)
            d.wait_for(lambda s: s["sets_failed"] == failed + 1, "the page's failed set counted", timeout=60)
            b.wait(f"Number({BODY}.setsFailed) === {failed + 1}", "the page seeing its failed set", timeout=20)
            no_reports_waiting(b, "the capture's reports matched")
            assert banners(b) == before + 1, (before, banners(b))

            # 3. A capture refused before any set runs: never counted; its report does not stay.
            n = int(b.js(f"Number({BODY}.replies || 0)"))
            b.click("#release")
            b.wait(f"Number({BODY}.replies || 0) > {n} && {BODY}.state === 'released'", "the devices released")
            before, failed = banners(b), d.status()["sets_failed"]
            code, refused = page_capture(b)
            assert code == "device_error" and "released" in refused, (code, refused)
            assert banners(b) == before + 1 and b.js(f"{BODY}.banner") == "reply-device_error", \
                (before, banners(b), b.js(f"{BODY}.banner"))
            no_reports_waiting(b, "the refusal's report gone after two statuses")
            assert d.status()["sets_failed"] == failed, "the refusal was counted as a failed set"
            assert banners(b) == before + 1, (before, banners(b))
            n = int(b.js(f"Number({BODY}.replies || 0)"))
            b.click("#acquire")
            b.wait(f"Number({BODY}.replies || 0) > {n} && {BODY}.state === 'idle'", "the devices acquired again",
                   timeout=60)
            assert not b.console, b.console
        finally:
            b.close()
            d.stop()
    print("a failure only the status reports, after an unmatched capture failure: one banner each: ok")


if __name__ == "__main__":
    main()
