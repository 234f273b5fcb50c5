#!/usr/bin/python3
"""The live view in a real browser (headless Chromium over its DevTools protocol) against
`descatterd` on the simulated lab: the page connects with the token, draws frames with the
measured stripe period, sees its images change as sets complete (the transmissive canvas's
pixels differ between two results), its Capture button makes the daemon take one set whose
result the page then shows, and Release/Acquire close and reopen the devices (the frame shown
is marked released meanwhile). Optionally saves a screenshot of the page streaming, zoomed 4:1
with the cursor's pixel read out (docs/live-view.png is made so:
tests/daemon/test_live_view.py DESCATTERD DESCATTERCTL docs/live-view.png).
Usage: test_live_view.py DESCATTERD DESCATTERCTL [SCREENSHOT.png]"""
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cdp_browser import Browser  # noqa: E402
from live_daemon import LiveDaemon  # noqa: E402
from live_page import BODY  # noqa: E402

TOKEN = "live-view-token-0123456789"
# A checksum of the pixels drawn on a canvas.
CANVAS_SUM = ("(() => {{ const c = document.getElementById('{0}'); const d = c.getContext('2d')"
              ".getImageData(0, 0, c.width, c.height).data; let s = 0; for (let i = 0; i < d.length; i += 4)"
              " s = (s * 31 + d[i]) >>> 0; return s; }})()")


def main():
    daemon, ctl = sys.argv[1:3]
    shot = sys.argv[3] if len(sys.argv) > 3 else None
    with tempfile.TemporaryDirectory() as tmp:
        token_file = os.path.join(tmp, "token")
        with open(token_file, "w") as f:
            f.write(TOKEN)
        d = LiveDaemon(daemon, ctl, tmp, f"[http]\nlisten=127.0.0.1:0\ntoken-file={token_file}\n"
                                         "[acquisition]\nphases=6\n")
        b = Browser(height=1500 if shot else 1000)
        try:
            b.open(d.url + "?token=" + TOKEN)
            b.wait(f"{BODY}.connected === '1'", "the page's WebSocket")
            b.wait("document.getElementById('version').textContent.includes('descatterd')", "a status update")
            # Continuous acquisition from the page's own controls.
            b.js("document.getElementById('phases').value = 6")
            b.click("#start")
            b.wait(f"Number({BODY}.results || 0) >= 1", "a first result")
            first_set = int(b.js(f"{BODY}.resultSet"))
            first_sum = b.js(CANVAS_SUM.format("transmissive"))
            b.wait(f"Number({BODY}.resultSet) > {first_set}", "the next result")
            second_sum = b.js(CANVAS_SUM.format("transmissive"))
            assert first_sum != second_sum, "the transmissive image did not change between two results"
            b.wait(f"Number({BODY}.frames || 0) >= 2", "raw frames")
            info = b.js("document.getElementById('frame-info').textContent")
            assert "px measured" in info and "– px measured" not in info, info
            b.click("#stop")
            d.wait_for(lambda s: not s["continuous"] and s["state"] == "idle" and s["pending"] == 0, "the stop")
            # Wait until the page shows the daemon's last result, then take one more with the button.
            done = d.status()["sets_done"]
            b.wait(f"Number({BODY}.resultSet) === {done}", "the last continuous result on the page")
            replies = int(b.js(f"Number({BODY}.replies || 0)"))
            b.click("#capture")
            b.wait(f"Number({BODY}.replies || 0) > {replies}", "the capture's reply")
            assert b.js(f"{BODY}.lastReply") == "ok", b.js("document.getElementById('reply').textContent")
            b.wait(f"Number({BODY}.resultSet) === {done + 1}", "the captured result on the page")
            st = d.status()
            assert st["sets_done"] == done + 1, st["sets_done"]
            title = b.js("document.getElementById('result-title').textContent")
            assert f"set {done + 1}," in title, title
            # A bad value from the page gets the daemon's own error back.
            b.js("document.getElementById('phases').value = 1")
            replies = int(b.js(f"Number({BODY}.replies || 0)"))
            b.click("#capture")
            b.wait(f"Number({BODY}.replies || 0) > {replies}", "the refusal")
            msg = b.js("document.getElementById('reply').textContent")
            assert b.js(f"{BODY}.lastReply") == "error" and "bad_argument" in msg and "phases" in msg, msg
            # Release the camera for another program and take it back, from the page.
            for button, state in (("#release", "released"), ("#acquire", "idle")):
                replies = int(b.js(f"Number({BODY}.replies || 0)"))
                b.click(button)
                b.wait(f"Number({BODY}.replies || 0) > {replies}", f"the reply to {button}")
                assert b.js(f"{BODY}.lastReply") == "ok", b.js("document.getElementById('reply').textContent")
                assert d.status()["state"] == state, d.status()["state"]
                if state == "released":
                    b.wait(f"{BODY}.frameState === 'released'", "the frame marked released", timeout=10)
            assert not b.console, b.console
            if shot:
                b.js("document.getElementById('phases').value = 6")
                b.click("#start")
                done = int(b.js(f"Number({BODY}.resultSet)"))
                b.wait(f"Number({BODY}.resultSet) >= {done + 3}", "results for the screenshot")
                b.js("(() => { const z = document.getElementById('zoom'); z.value = '4';"
                     " z.dispatchEvent(new Event('change')); })()")
                r = b.js("(() => { const r = document.getElementById('raw').getBoundingClientRect();"
                         " return [r.left, r.top, r.width, r.height]; })()")
                b.mouse("moved", r[0] + r[2] * 0.45, r[1] + r[3] * 0.4)
                b.wait(f"Number({BODY}.focusPoints || 0) >= 20 && {BODY}.frameState === 'live'", "a focus trace")
                b.screenshot(shot)
                b.click("#stop")
        finally:
            b.close()
            d.stop()
    print("live view in chromium: ok")


if __name__ == "__main__":
    main()
