#!/usr/bin/python3
"""Motion in the live view, in headless Chromium against descatterd on the simulated lab:
  - the page's drawing of a result: pixels whose mask carries bit 7 (motion) are tinted half
    way to magenta (217, 70, 239) on the transmissive view, every other pixel keeps its grey,
    and a mask of another size tints nothing (a synthetic picture drawn with the page's own
    function, read back from the canvas);
  - the mask legend lists `motion`, and after a capture (detect-motion=true, N = 6)
    the transmissive caption reads the result's own count, `motion: N pixels` (at most 3e-3 of
    the pixels: the simulated scene is still and the design's false-alarm rate is 1e-3), and
    the canvas was tinted at as many pictured pixels as the result's mask picture marks.
Usage: test_live_motion.py DESCATTERD DESCATTERCTL"""
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cdp_browser import Browser  # noqa: E402
from live_daemon import LiveDaemon  # noqa: E402
from live_page import BODY  # noqa: E402

TOKEN = "live-motion-token-0123456789"
MAGENTA = (217, 70, 239)

# A 3 x 2 grey picture at offset 0 and its mask at offset 6, drawn with the page's draw().
GREYS = [0, 100, 200, 255, 50, 10]
MASK = [0, 128, 129, 0, 128 | 1, 64]
DRAW = """(() => {{
  const buf = new ArrayBuffer(12), v = new Uint8Array(buf);
  v.set({greys}, 0); v.set({mask}, 6);
  const c = document.createElement('canvas');
  const tinted = draw(c, {{width: 3, height: 2, offset: 0}}, buf, false, {{width: {mw}, height: {mh}, offset: 6}});
  return [tinted, Array.from(c.getContext('2d').getImageData(0, 0, 3, 2).data)];
}})()"""


def check_synthetic(b):
    tinted, rgba = b.js(DRAW.format(greys=GREYS, mask=MASK, mw=3, mh=2))
    moved = [m & 128 != 0 for m in MASK]
    assert tinted == sum(moved), (tinted, moved)
    for i, g in enumerate(GREYS):
        want = tuple((g + t) // 2 for t in MAGENTA) if moved[i] else (g, g, g)
        assert tuple(rgba[4 * i:4 * i + 3]) == want, (i, rgba[4 * i:4 * i + 4], want)
    # a mask picture of another size belongs to another picture: nothing tinted
    tinted, rgba = b.js(DRAW.format(greys=GREYS, mask=MASK, mw=2, mh=3))
    assert tinted == 0 and all(rgba[4 * i:4 * i + 3] == [g, g, g] for i, g in enumerate(GREYS)), rgba


def main():
    daemon, ctl = sys.argv[1:3]
    with tempfile.TemporaryDirectory() as tmp:
        token_file = os.path.join(tmp, "token")
        with open(token_file, "w") as f:
            f.write(TOKEN)
        d = LiveDaemon(daemon, ctl, tmp, f"[http]\nlisten=127.0.0.1:0\ntoken-file={token_file}\n"
                                         "[acquisition]\nphases=6\ndetect-motion=true\n")
        b = Browser(height=1000)
        try:
            b.open(d.url + "?token=" + TOKEN)
            b.wait(f"{BODY}.connected === '1'", "the page's WebSocket")
            b.wait("document.getElementById('version').textContent.includes('descatterd')", "a status update")
            check_synthetic(b)
            legend = b.js("document.getElementById('legend').textContent")
            assert "motion" in legend, legend
            b.js("document.getElementById('phases').value = 6")
            replies = int(b.js(f"Number({BODY}.replies || 0)"))
            b.click("#capture")
            b.wait(f"Number({BODY}.replies || 0) > {replies}", "the capture's reply", timeout=60)
            assert b.js(f"{BODY}.lastReply") == "ok", b.js("document.getElementById('reply').textContent")
            b.wait(f"Number({BODY}.results || 0) >= 1", "the captured result on the page")
            sep = b.js("lastResultMeta.separation")
            assert sep["motion_checked"] is True, sep
            n = sep["flagged"]["motion"]
            # the simulated scene is still: at most the design's 1e-3 false alarms (3e-3 with room)
            meta = b.js("lastResultMeta")
            assert n <= 3e-3 * meta["width"] * meta["height"], (n, meta["width"], meta["height"])
            note = b.js("document.getElementById('motion-note').textContent")
            assert note == f"motion: {n} pixel{'' if n == 1 else 's'}", (note, n)
            assert int(b.js(f"{BODY}.motionPixels")) == n
            # the tint follows the mask picture the page received (each of its pixels ORs a box)
            pictured = b.js("(() => { const c = document.getElementById('mask'); const d = c.getContext('2d')"
                            ".getImageData(0, 0, c.width, c.height).data; let k = 0; for (let i = 0; i < d.length;"
                            f" i += 4) k += d[i] === {MAGENTA[0]} && d[i + 1] === {MAGENTA[1]} && d[i + 2] === {MAGENTA[2]};"
                            " return k; })()")
            tinted = int(b.js(f"{BODY}.motionTinted"))
            # the mask canvas shows the first bit set, so motion pixels with a lower bit show that
            assert tinted >= pictured and (n > 0 or tinted == 0), (tinted, pictured, n)
            print(f"motion: {n} pixels flagged on a still simulated scene, {tinted} pictured pixels tinted")
        finally:
            b.close()
            d.stop()


if __name__ == "__main__":
    main()
