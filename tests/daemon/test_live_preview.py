#!/usr/bin/python3
"""Preview and live camera settings from the live view, in headless Chromium against descatterd
on the simulated lab (needs the daemon's `preview` and `set` commands):
  - Preview on (light all) from the page: frames keep arriving while no set is taken
    (status.state `preview`, sets_done unchanged, status.preview.frames growing);
  - exposures of 1250, 2500 and 3750 µs applied with the page's camera inputs: the mean of the
    frames the daemon sent, computed here from their samples, grows linearly with exposure (a
    sensor's signal is dark level + rate x exposure: the step 1250 -> 3750 is twice the step
    1250 -> 2500, within 10 %); the page shows each frame's mean;
  - a refused exposure shows the daemon's own message next to the inputs;
  - light off (preview off, then on again with the light off): the frames' mean falls below
    half the lit mean (only the ambient light is left);
  - an ROI applied from the page while idle: frames of its size, and the pixel under the cursor reads
    sensor coordinates offset by the ROI's origin;
  - Preview off: the daemon is idle again.
Usage: test_live_preview.py DESCATTERD DESCATTERCTL"""
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
    b.wait(f"Number({BODY}.replies || 0) > {n}", what, timeout=30)
    return b.js(f"{BODY}.lastReply"), b.js(f"document.getElementById('{where}').textContent")


def fresh_frame(b, after=3, **expect):
    """A frame sent after `after` more frames have come (the settings in force for all of them)."""
    n = int(b.js(f"Number({BODY}.frames || 0)"))
    b.wait(f"Number({BODY}.frames || 0) >= {n + after}", "preview frames", timeout=30)
    f = frames(b.received_messages())[-1]
    for k, v in expect.items():
        assert f.header[k] == v, (k, f.header[k], v)
    return f


def mean(f):
    return sum(f.samples) / len(f.samples)


def set_inputs(b, **values):
    for k, v in values.items():
        b.js(f"(() => {{ const e = document.getElementById('{k}'); e.value = '{v}';"
             " e.dispatchEvent(new Event('input')); })()")  # as typed: status no longer refills it


def main():
    daemon, ctl = sys.argv[1:3]
    with tempfile.TemporaryDirectory() as tmp:
        d = LiveDaemon(daemon, ctl, tmp, "[http]\nlisten=127.0.0.1:0\nlive-fps=20\n")
        b = Browser()
        try:
            b.capture_websocket(keep=8)
            b.open(d.page_url())
            b.wait(f"{BODY}.connected === '1' && {BODY}.state === 'idle'", "the page connected, the daemon idle")
            done = d.status()["sets_done"]
            b.js("document.getElementById('light').value = 'all'")
            ok, text = command_reply(b, "#preview-on", "preview-reply", "the preview's reply")
            assert ok == "ok", text
            st = d.wait_for(lambda s: s["state"] == "preview", "the preview state")
            fresh_frame(b, after=5)
            st = d.status()
            assert st["state"] == "preview" and st["sets_done"] == done and st["preview"]["frames"] >= 5, st
            assert b.js(f"{BODY}.frameState") == "live" and b.js(f"{BODY}.state") == "preview"
            means = {}
            for e in (1250, 2500, 3750):
                set_inputs(b, exposure=e)
                ok, text = command_reply(b, "#apply", "camera-reply", f"the set of {e} µs")
                assert ok == "ok" and b.js(f"{BODY}.cameraReply") == "ok", text
                f = fresh_frame(b, exposure_us=e)
                means[e] = mean(f)
                b.wait(f"Number({BODY}.frameId) >= {f.header['frame_id']}", "the frame on the page")
                # One read of both: a newer frame may be drawn between two reads.
                shown_id, shown_mean = b.js(f"[{BODY}.frameId, {BODY}.frameMean]")
                if int(shown_id) == f.header["frame_id"]:
                    assert abs(float(shown_mean) - means[e]) < 0.01, (shown_id, shown_mean, means[e])
            step1, step2 = means[2500] - means[1250], means[3750] - means[1250]
            assert step1 > 20 and abs(step2 / step1 - 2) < 0.2, means
            # Out of the camera's range: the daemon's refusal, shown by the inputs.
            set_inputs(b, exposure=-5)
            ok, text = command_reply(b, "#apply", "camera-reply", "the refused set")
            assert ok == "error" and "exposure" in text and b.js(f"{BODY}.cameraReply") == "error", text
            set_inputs(b, exposure=2500)
            assert command_reply(b, "#apply", "camera-reply", "the set back")[0] == "ok"
            lit = mean(fresh_frame(b, exposure_us=2500))
            assert command_reply(b, "#preview-off", "preview-reply", "preview off")[0] == "ok"
            d.wait_for(lambda s: s["state"] == "idle", "idle after the preview")
            b.js("document.getElementById('light').value = 'off'")
            assert command_reply(b, "#preview-on", "preview-reply", "light off")[0] == "ok"
            dark = mean(fresh_frame(b, after=4))
            assert dark < 0.5 * lit, (dark, lit)
            assert command_reply(b, "#preview-off", "preview-reply", "preview off")[0] == "ok"
            d.wait_for(lambda s: s["state"] == "idle", "idle after the preview")
            # An ROI (set while idle): the frame shrinks, and the readout counts from the sensor's corner.
            set_inputs(b, **{"roi-x": 48, "roi-y": 32, "roi-w": 128, "roi-h": 96})
            ok, text = command_reply(b, "#apply", "camera-reply", "the ROI")
            assert ok == "ok", text
            b.js("document.getElementById('light').value = 'all'")
            assert command_reply(b, "#preview-on", "preview-reply", "light all")[0] == "ok"
            f = fresh_frame(b, width=128, height=96)
            b.wait(f"Number({BODY}.frameId) >= {f.header['frame_id']}", "the ROI frame on the page")
            r = b.js("(() => { const r = document.getElementById('raw').getBoundingClientRect(); return [r.left, r.top, r.width, r.height]; })()")
            s = min(r[2] / 128, r[3] / 96)
            ox, oy = -(r[2] / s - 128) / 2, -(r[3] / s - 96) / 2
            # The cursor on the middle of frame pixel (64, 48): a mouse event's offset may be whole
            # CSS pixels, so a point near a pixel's edge could read the neighbour.
            x, y = 64, 48
            b.mouse("moved", r[0] + (x + 0.5 - ox) * s, r[1] + (y + 0.5 - oy) * s)
            assert (int(b.js(f"{BODY}.readoutX")), int(b.js(f"{BODY}.readoutY"))) == (48 + x, 32 + y), \
                (b.js(f"{BODY}.readoutX"), b.js(f"{BODY}.readoutY"), x, y)
            ok, text = command_reply(b, "#preview-off", "preview-reply", "preview off")
            assert ok == "ok", text
            d.wait_for(lambda s: s["state"] == "idle", "idle after the preview")
            assert d.status()["sets_done"] == done
            assert not b.console, b.console
        finally:
            b.close()
            d.stop()
    print("preview and camera settings in chromium: ok")


if __name__ == "__main__":
    main()
