#!/usr/bin/python3
"""Per-frame results in the live view, in headless Chromium against descatterd on the simulated
lab (continuous mode `results = per-frame`, docs/protocol.md "Per-frame results"):
  - continuous mode started from the page with results "per frame" (its results selector);
  - the page shows per-frame results ("frame N (newest of 4)") and their window;
  - the results it is sent come newest first, never an older one after a newer (no backlog
    replayed: the live view keeps only the newest update per client, sent once the page has
    drawn the one before);
  - once continuous mode stops, the page shows the last result the daemon published (its
    newest_frame_id, read by a socket subscriber: an independent route);
  - a page slowed down (its acknowledgements a second late) is told of results it skipped, and
    the results it drew plus those are status `frame_results`;
  - how many camera frames the page showed a result of, against the frames the camera took
    meanwhile, is printed (the page's refresh rate decides it: no assertion on speed).
Optionally saves a screenshot of the page showing per-frame results (docs/live-view-per-frame.png).
Usage: test_live_per_frame.py DESCATTERD DESCATTERCTL PYTHON_PACKAGE_DIR [SCREENSHOT.png]"""
import os
import sys
import tempfile
import threading

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cdp_browser import Browser  # noqa: E402
from live_daemon import LiveDaemon  # noqa: E402
from live_messages import LiveMessage  # noqa: E402
from live_page import BODY  # noqa: E402


def main():
    daemon, ctl, package = sys.argv[1:4]
    shot = sys.argv[4] if len(sys.argv) > 4 else None
    sys.path.insert(0, package)
    import descatter
    with tempfile.TemporaryDirectory() as tmp:
        d = LiveDaemon(daemon, ctl, tmp, "[http]\nlisten=127.0.0.1:0\n[acquisition]\nphases=4\ndark-frame=false\n")
        b = Browser()
        newest = []
        try:
            b.capture_websocket(keep=4096)
            b.open(d.page_url())
            b.wait(f"{BODY}.connected === '1' && {BODY}.state === 'idle'", "the page connected, the daemon idle")
            with descatter.Client("unix:" + d.sock) as c, c.subscribe() as sub:
                stop = threading.Event()

                def listen():
                    while not stop.is_set():
                        try:
                            ev = sub.next(timeout=2)
                        except descatter.Timeout:
                            continue  # between messages: the connection stays usable
                        if isinstance(ev, descatter.ResultEvent):
                            newest.append(ev.meta["window"]["newest_frame_id"])

                t = threading.Thread(target=listen)
                t.start()
                try:
                    # Started from the page's own controls: N = 4, results per frame.
                    b.js("(() => { const p = document.getElementById('phases'); p.value = '4';"
                         " document.getElementById('results').value = 'per-frame'; })()")
                    b.click("#start")
                    d.wait_for(lambda s: s["state"] == "continuous", "continuous mode")
                    b.wait(f"Number({BODY}.results || 0) >= 3", "three per-frame results on the page", timeout=60)
                    a0 = d.status()["frames"]["acquired"]
                    shown0 = int(b.js(f"{BODY}.results"))
                    d.wait_for(lambda s: s["frames"]["acquired"] >= a0 + 24, "24 more camera frames")
                    a1 = d.status()["frames"]["acquired"]
                    shown1 = int(b.js(f"{BODY}.results"))
                    if shot:
                        b.screenshot(shot)
                    # A page slower than the camera: each update acknowledged a second late, so results
                    # come faster than it takes them and newer ones replace the unsent.
                    b.js("window.ack = ((drawn) => () => setTimeout(drawn, 1000))(ack)")
                    a2 = d.status()["frames"]["acquired"]
                    d.wait_for(lambda s: s["frames"]["acquired"] >= a2 + 24, "24 frames with a slow page")
                    assert d.ctl("stop", check=False).returncode == 0
                    d.wait_for(lambda s: s["state"] == "idle", "idle after stop")
                finally:
                    stop.set()
                    t.join()
            assert newest, "the subscriber got no result"
            last = newest[-1]
            b.wait(f"String({BODY}.resultFrame) === '{last}'", f"the page showing frame {last}, the last result",
                   timeout=30)
            title = b.js("document.getElementById('result-title').textContent")
            assert title.startswith(f"frame {last} (newest of 4)"), title
            # Every result published reached the page or was counted as skipped before a newer one
            # (the page's own counts against the acquisition thread's).
            published = d.status()["frame_results"]
            drawn, skipped = int(b.js(f"{BODY}.results")), int(b.js(f"{BODY}.resultsSkipped || 0"))
            print(f"the page drew {drawn} results and was told of {skipped} skipped; {published} published")
            assert drawn + skipped == published, (drawn, skipped, published)
            assert skipped > 0, "a page acknowledging a second late was told of no skipped result"
            ids = [LiveMessage(m).header.get("meta", {}).get("window", {}).get("newest_frame_id")
                   for m in b.received_messages() if LiveMessage(m).type == "result"]
            ids = [i for i in ids if i is not None]
            assert len(ids) >= 3, ids
            # Ids wrap from 65535 to 1: compared as steps forward.
            steps = [(y - x) % 65535 for x, y in zip(ids, ids[1:])]
            assert all(0 < s < 32768 for s in steps), ("an older result after a newer one", ids)
            print(f"the page drew {shown1 - shown0} results while the camera took {a1 - a0} frames; "
                  f"it was sent {len(ids)} results, each newer than the one before")
            assert not b.console, b.console
        finally:
            b.close()
            d.stop()
    print("per-frame results in chromium: ok")


if __name__ == "__main__":
    main()
