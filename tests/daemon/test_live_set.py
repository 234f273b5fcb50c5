#!/usr/bin/python3
"""Camera settings from the live view, in headless Chromium against descatterd on the simulated
lab (needs the daemon's `set` command):
  - exposures of 1250, 2500 and 3750 µs typed into the page and applied, each followed by a
    Capture from the page: the mean of a frame the daemon sent (computed here from its samples,
    the same phase at each exposure) grows linearly with exposure (signal = dark level + rate x
    exposure: the step 1250 -> 3750 is twice the step 1250 -> 2500, within 10 %), and the page
    shows the exposure the frame was taken with;
  - an exposure out of range: the daemon's refusal (`bad_argument` naming it) by the inputs;
  - an ROI (48, 32, 128 x 96): frames of its size, and the pixel under the cursor reads sensor
    coordinates offset by the ROI's origin, with the value of the frame's sample there.
Usage: test_live_set.py DESCATTERD DESCATTERCTL"""
import math
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cdp_browser import Browser  # noqa: E402
from live_daemon import LiveDaemon  # noqa: E402
from live_messages import frames  # noqa: E402
from live_page import BODY  # noqa: E402


def command_reply(b, selector, where, what):
    n = int(b.js(f"Number({BODY}.replies || 0)"))
    b.click(selector)
    b.wait(f"Number({BODY}.replies || 0) > {n}", what, timeout=60)
    return b.js(f"{BODY}.lastReply"), b.js(f"document.getElementById('{where}').textContent")


def set_inputs(b, **values):
    for k, v in values.items():
        b.js(f"(() => {{ const e = document.getElementById('{k}'); e.value = '{v}';"
             " e.dispatchEvent(new Event('input')); })()")  # as typed: status no longer refills it


def capture_frames(b, **expect):
    """Capture from the page; the frame messages of that set (by their header)."""
    n = int(b.js(f"Number({BODY}.results || 0)"))
    ok, text = command_reply(b, "#capture", "reply", "the capture")
    assert ok == "ok", text
    b.wait(f"Number({BODY}.results || 0) > {n}", "the capture's result on the page")
    out = {}
    for f in frames(b.received_messages()):
        if all(f.header[k] == v for k, v in expect.items()):
            out[f.header["phase"]] = f
    assert out, f"no frame with {expect}"
    return out


def mean(f):
    return sum(f.samples) / len(f.samples)


def main():
    daemon, ctl = sys.argv[1:3]
    with tempfile.TemporaryDirectory() as tmp:
        d = LiveDaemon(daemon, ctl, tmp, "[http]\nlisten=127.0.0.1:0\nlive-fps=100\n"
                                         "[acquisition]\nphases=8\ndark-frame=false\n")
        b = Browser()
        try:
            b.capture_websocket(keep=64)
            b.open(d.page_url())
            b.wait(f"{BODY}.connected === '1' && {BODY}.state === 'idle'", "the page connected, the daemon idle")
            b.js("document.getElementById('phases').value = 8")
            by_exposure = {}
            for e in (1250, 2500, 3750):
                set_inputs(b, exposure=e)
                ok, text = command_reply(b, "#apply", "camera-reply", f"the set of {e} µs")
                assert ok == "ok" and f"{e} µs" in text, text
                by_exposure[e] = capture_frames(b, exposure_us=e)
                b.wait(f"Number({BODY}.frameExposure) === {e}", "the page showing the exposure")
            common = set.intersection(*(set(v) for v in by_exposure.values()))
            assert common, {e: sorted(v) for e, v in by_exposure.items()}
            k = min(common)
            m = {e: mean(v[k]) for e, v in by_exposure.items()}
            step1, step2 = m[2500] - m[1250], m[3750] - m[1250]
            assert step1 > 20 and abs(step2 / step1 - 2) < 0.2, m
            print("frame means (phase %d): " % k + ", ".join(f"{e} µs {v:.1f} DN" for e, v in m.items()))
            set_inputs(b, exposure=-5)
            ok, text = command_reply(b, "#apply", "camera-reply", "the refused set")
            assert ok == "error" and text.startswith("bad_argument: ") and "exposure" in text, text
            # A region: the readout counts from the sensor's corner.
            set_inputs(b, **{"roi-x": 48, "roi-y": 32, "roi-w": 128, "roi-h": 96})
            ok, text = command_reply(b, "#apply", "camera-reply", "the ROI")
            assert ok == "ok" and "ROI 48,32 128×96" in text, text
            last = capture_frames(b, width=128, height=96)
            f = last[max(last)]
            b.wait(f"Number({BODY}.frameId) === {f.header['frame_id']}", "the ROI frame on the page")
            r = b.js("(() => { const r = document.getElementById('raw').getBoundingClientRect(); return [r.left, r.top, r.width, r.height]; })()")
            s = min(r[2] / 128, r[3] / 96)
            ox, oy = -(r[2] / s - 128) / 2, -(r[3] / s - 96) / 2
            cx, cy = r[2] * 0.3 + 0.4, r[3] * 0.6 + 0.4
            b.mouse("moved", r[0] + cx, r[1] + cy)
            x, y = math.floor(ox + cx / s), math.floor(oy + cy / s)
            got = b.js(f"[Number({BODY}.readoutX), Number({BODY}.readoutY), Number({BODY}.readoutDn)]")
            assert got == [48 + x, 32 + y, f.sample(x, y)], (got, x, y, f.sample(x, y))
            assert not b.console, b.console
        finally:
            b.close()
            d.stop()
    print("camera settings from the page in chromium: ok")


if __name__ == "__main__":
    main()
