#!/usr/bin/python3
"""The live view as an alignment tool, in headless Chromium against descatterd on the simulated
lab (12-bit sensor, 256 x 192) with an ROI at (32, 16):
  - zoom 4:1 and a drag: the pixel under the cursor reads the value and sensor coordinates that
    this test computes from the frame message the daemon sent (parsed here from the bytes) and
    the view mapping of docs/operations.md, and its screen block is one flat grey (nearest
    neighbour);
  - the histogram spans the 12 significant bits (0..4095), its bins and the clipped count match
    the samples; "at full scale" fires for a capture exposed into clipping;
  - the stripe phase prints wrapped to [0, 1) (0.99996 cycles reads 0.000);
  - after a resize the stripe overlay covers the frame canvas exactly and stays in its section;
  - idle after a capture, the frame is marked stale;
  - Cancel on the page answers a long capture, sent over the socket, `cancelled`;
  - a refused camera setting shows the daemon's message beside the inputs.
Usage: test_live_align.py DESCATTERD DESCATTERCTL"""
import json
import math
import os
import socket
import sys
import tempfile
import threading

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cdp_browser import Browser  # noqa: E402
from live_daemon import LiveDaemon  # noqa: E402
from live_messages import frames  # noqa: E402
from live_page import BODY  # noqa: E402

ROI = (32, 16, 192, 160)
RECT = "(() => {{ const r = document.getElementById('{0}').getBoundingClientRect(); return [r.left, r.top, r.width, r.height]; }})()"


def replies(b):
    return int(b.js(f"Number({BODY}.replies || 0)"))


def click_and_wait(b, selector, what):
    n = replies(b)
    b.click(selector)
    b.wait(f"Number({BODY}.replies || 0) > {n}", what, timeout=40)
    return b.js("document.getElementById('reply').textContent")


def shown_frame(b):
    """The frame message the page shows now, as the daemon sent it."""
    fid = int(b.js(f"{BODY}.frameId"))
    for f in reversed(frames(b.received_messages())):
        if f.header["frame_id"] == fid:
            return f
    raise AssertionError(f"frame {fid} shown but not among the messages received")


def clamp_origin(o, span, size):
    """docs/operations.md: a frame wider than the view pans within it; a narrower one is centred."""
    return -(span - size) / 2 if span >= size else min(max(o, 0), size - span)


def check_zoom_readout(b):
    f = shown_frame(b)
    h = f.header
    w, hh = h["width"], h["height"]
    assert (w, hh) == ROI[2:], (w, hh)
    left, top, vw, vh = b.js(RECT.format("raw"))
    fit = min(vw / w, vh / hh)
    zoom = 4
    # Fit shows the frame centred; zooming keeps the view's centre; a drag moves the frame with it.
    cu, cv = (clamp_origin(0, vw / fit, w) + vw / 2 / fit), (clamp_origin(0, vh / fit, hh) + vh / 2 / fit)
    ox, oy = clamp_origin(cu - vw / 2 / zoom, vw / zoom, w), clamp_origin(cv - vh / 2 / zoom, vh / zoom, hh)
    b.js(f"(() => {{ const z = document.getElementById('zoom'); z.value = '{zoom}'; z.dispatchEvent(new Event('change')); }})()")
    dx, dy = -60, -30
    b.drag(left + vw / 2, top + vh / 2, left + vw / 2 + dx, top + vh / 2 + dy)
    ox, oy = clamp_origin(ox - dx / zoom, vw / zoom, w), clamp_origin(oy - dy / zoom, vh / zoom, hh)
    for cx, cy in ((101.3, 57.8), (vw - 3.5, vh - 2.5), (2.2, 3.9)):
        b.mouse("moved", left + cx, top + cy)
        px, py = math.floor(ox + cx / zoom), math.floor(oy + cy / zoom)
        expect = (px + ROI[0], py + ROI[1], f.sample(px, py))
        got = b.js(f"[Number({BODY}.readoutX), Number({BODY}.readoutY), Number({BODY}.readoutDn), Number({BODY}.readoutFrame)]")
        assert tuple(got[:3]) == expect and got[3] == h["frame_id"], (got, expect)
        text = b.js("document.getElementById('readout').textContent")
        assert f"x {expect[0]}, y {expect[1]}: {expect[2]} DN" in text, text
        # The sensor pixel covers a zoom x zoom block of one grey: nearest neighbour, no smoothing.
        bx, by = math.ceil((px - ox) * zoom), math.ceil((py - oy) * zoom)
        greys = b.js(f"Array.from(document.getElementById('raw').getContext('2d').getImageData({bx}, {by}, 3, 3).data)"
                     ".filter((v, i) => i % 4 === 0)")
        raw = [p for p in h["images"] if p["name"] == "raw"][0]
        g = round(min(255, max(0, (expect[2] - raw["lo"]) / (raw["hi"] - raw["lo"]) * 255)))
        assert len(set(greys)) == 1 and abs(greys[0] - g) <= 1, (greys, g)
    print(f"zoom {zoom}:1 readout ok (frame {h['frame_id']}, origin {ox:.2f},{oy:.2f})")


def check_histogram(b, expect_clipped):
    f = shown_frame(b)
    h, s = f.header, f.samples
    assert h["significant_bits"] == 12 and h["full_scale_dn"] == 4095, (h["significant_bits"], h["full_scale_dn"])
    bins = [0] * 64
    for v in s:
        bins[63 if v >= 4095 else int(v / 4095 * 64)] += 1
    assert bins == h["histogram"], (bins, h["histogram"])
    clipped = sum(1 for v in s if v >= 4095)
    assert (clipped > 0) == expect_clipped, clipped
    ordered = sorted(s)
    p50 = ordered[(len(ordered) - 1) // 2]
    assert abs(h["percentiles"]["p50"] - p50) <= 1, (h["percentiles"], p50)
    assert b.js(f"Number({BODY}.clipped)") == clipped and b.js(f"Number({BODY}.histogramTop)") == 4095
    cap = b.js("document.getElementById('histogram-caption').textContent")
    assert "0 … 4095 DN (12 significant bits)" in cap and f"{clipped} at full scale" in cap, cap
    # Samples span the significant range: the brightest one lies in the bin the 12-bit scale gives.
    top_bin = max(i for i, n in enumerate(h["histogram"]) if n)
    assert top_bin == (63 if max(s) >= 4095 else int(max(s) / 4095 * 64)), top_bin
    print(f"histogram ok: max {max(s)} DN, {clipped} clipped")


def check_phase_wrap(b):
    shown = b.js(f"{BODY}.stripePhase")
    assert shown == "–" or 0 <= float(shown) < 1, shown
    for phase, text in ((0.99996, "0.000"), (1.0, "0.000"), (-0.00002, "0.000"), (0.4996, "0.500"), (2.25, "0.250")):
        b.js(f"showFrameStats({{ ...lastFrameHeader, stripe_phase: {phase} }})")
        info = b.js("document.getElementById('frame-info').textContent")
        assert b.js(f"{BODY}.stripePhase") == text and f"{text} cycles measured" in info, (phase, info)
        assert "1.000 cycles" not in info and "-0.000" not in info, info


def check_resize(b):
    for width in (760, 1400):
        b.set_viewport(width, 1000)
        b.wait("document.getElementById('raw').width === Math.round(document.getElementById('view').clientWidth)",
               "the frame canvas following the resize", timeout=20)
        raw, ov, view = (b.js(RECT.format(i)) for i in ("raw", "overlay", "view"))
        sec = b.js("(() => { const r = document.getElementById('view').closest('section').getBoundingClientRect();"
                   " return [r.left, r.top, r.width, r.height]; })()")
        assert all(abs(a - c) < 0.5 for a, c in zip(raw, ov)), (raw, ov)
        assert ov[0] >= sec[0] and ov[0] + ov[2] <= sec[0] + sec[2] + 0.5 and ov[0] + ov[2] <= width, (ov, sec, width)
        assert abs(view[2] - ov[2]) < 0.5, (view, ov)
        dims = b.js("[document.getElementById('overlay').width, document.getElementById('raw').width]")
        assert dims[0] == dims[1] == round(ov[2]), dims


def long_capture(sock_path, out):
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    s.connect(sock_path)
    s.settimeout(120)
    s.sendall(b'{"id": 1, "cmd": "capture", "args": {"phases": 64, "averages": 8}}\n')
    buf = b""
    while b"\n" not in buf:
        chunk = s.recv(65536)
        if not chunk:
            break
        buf += chunk
    out.append(json.loads(buf.split(b"\n")[0]))
    s.close()


def check_cancel(b, d):
    cancelled0 = d.status()["sets_cancelled"]
    out = []
    t = threading.Thread(target=long_capture, args=(d.sock, out))
    t.start()
    d.wait_for(lambda s: s["state"] == "acquiring", "the long capture running", timeout=30)
    text = click_and_wait(b, "#cancel", "the cancel's reply")
    t.join(60)
    assert out and not out[0]["ok"] and out[0]["error"]["code"] == "cancelled", out
    assert "cancelled 1 request" in text, text
    st = d.wait_for(lambda s: s["state"] == "idle", "idle after the cancel", timeout=30)
    assert st["sets_cancelled"] == cancelled0 + 1, st["sets_cancelled"]


def check_refusal_shown(b):
    """A refused camera setting shows the daemon's own message by the inputs: an exposure out of
    range (with the daemon's `set`), or the unknown command (without it)."""
    b.js("(() => { const e = document.getElementById('exposure'); e.value = '-5'; e.dispatchEvent(new Event('input')); })()")
    n = replies(b)
    b.click("#apply")
    b.wait(f"Number({BODY}.replies || 0) > {n}", "the set's reply", timeout=30)
    text, cls = b.js("[document.getElementById('camera-reply').textContent, document.getElementById('camera-reply').className]")
    assert cls == "err" and b.js(f"{BODY}.cameraReply") == "error", (text, cls)
    assert text.startswith(("bad_argument: ", "unknown_command: ")) and ("exposure" in text or '"set"' in text), text


def main():
    daemon, ctl = sys.argv[1:3]
    with tempfile.TemporaryDirectory() as tmp:
        d = LiveDaemon(daemon, ctl, tmp, "[http]\nlisten=127.0.0.1:0\nlive-fps=20\n[acquisition]\nphases=6\n"
                                         f"[camera]\nroi={','.join(map(str, ROI))}\n")
        b = Browser()
        try:
            b.capture_websocket()
            b.open(d.page_url())
            b.wait(f"{BODY}.connected === '1' && {BODY}.state === 'idle'", "the page connected, the daemon idle")
            b.js("document.getElementById('phases').value = 6")
            text = click_and_wait(b, "#capture", "the capture's reply")
            assert "done" in text, text
            b.wait(f"Number({BODY}.results || 0) >= 1 && Number({BODY}.frames || 0) >= 1", "a result and frames")
            b.wait(f"{BODY}.frameState === 'stale'", "the idle frame marked stale", timeout=20)
            assert "daemon idle" in b.js("document.getElementById('freshness').textContent")
            check_histogram(b, expect_clipped=False)
            check_zoom_readout(b)
            check_phase_wrap(b)
            check_resize(b)
            check_refusal_shown(b)
            # Four times the exposure clips the bright part: the histogram's top bin fires.
            d.ctl("capture", "--quiet", "--phases", "4", "--exposure-us", "20000", "--out", os.path.join(tmp, "clip"))
            b.wait(f"Number({BODY}.clipped || 0) > 0", "a clipped frame")
            b.wait(f"{BODY}.frameState === 'stale'", "the last frame of the capture", timeout=20)
            check_histogram(b, expect_clipped=True)
            check_cancel(b, d)
            assert not b.console, b.console
        finally:
            b.close()
            d.stop()
    print("live view alignment tools in chromium: ok")


if __name__ == "__main__":
    main()
