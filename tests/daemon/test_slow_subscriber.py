#!/usr/bin/python3
"""A subscriber that reads slower than the camera, against descatterd on the simulated lab in
per-frame mode (docs/protocol.md, "Events" and "Per-frame results"). Its wire is read here by
hand (a line, then exactly the payload bytes it announces), so a torn result would show as a
line that does not parse.

Checked, each against an independent count:
  - the slow subscriber's results come with increasing frame ids and set ids;
  - `skipped` on each result is the set ids it jumped over (the acquisition thread numbers every
    result; the connection counts what it did not send); the seq numbers it never got are the
    results skipped; received plus skipped is status `frame_results` once the stream stopped;
  - after a pause of 40 results, the newest result it gets within the few that were already on
    their way (the one being written, what the socket buffer holds) is one the daemon had
    published when the pause ended (status `frame_results`), not a backlog;
  - the daemon's queue to its clients (status `clients.queued_bytes`) stays within what two
    results per subscriber take however long the pause lasts;
  - status `results_dropped` is the results the subscribers were told they skipped;
  - a fast subscriber (the Python client) gets every result: skipped 0, every set id;
  - per-set mode is unchanged: a subscriber pausing over several sets still gets each of them.
Usage: test_slow_subscriber.py DESCATTERD DESCATTERCTL PYTHON_PACKAGE_DIR"""
import math
import os
import sys
import tempfile
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from daemon_checks import RawSubscriber, set_id  # noqa: E402
from live_daemon import LiveDaemon  # noqa: E402

PAUSE_RESULTS = 40


def frame_id(h):
    return h["body"]["window"]["newest_frame_id"]


def rss_kib(pid):
    with open(f"/proc/{pid}/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS:"))


def result_bytes(h):
    return sum(p["bytes"] for p in h["payloads"])


def check_accounting(sub, what):
    """Set-id gaps against `skipped`, result by result, and the seq numbers never received against
    the results skipped (every other event is sent: the queue stays far below max-queued-bytes);
    returns received + skipped."""
    prev_set = 0  # a fresh daemon: the first result ever is set 1
    for h in sub.results():
        assert set_id(h) - prev_set - 1 == h["skipped"], \
            f"{what}: set {prev_set} -> {set_id(h)} with skipped {h['skipped']}"
        prev_set = set_id(h)
    seqs = [h["seq"] for h in sub.events]
    assert all(b > a for a, b in zip(seqs, seqs[1:])), f"{what}: seq out of order"
    res = sub.results()
    last = sub.events.index(res[-1])  # results skipped after the last result count in none
    missing = seqs[last] - (sub.next_seq - 1) - (last + 1)
    skipped = sum(h["skipped"] for h in res)
    assert missing == skipped, f"{what}: {missing} seq numbers never received, {skipped} results skipped"
    return len(res) + skipped


def main():
    daemon, ctl, package = sys.argv[1:4]
    sys.path.insert(0, package)
    import descatter
    with open("/proc/sys/net/core/wmem_default") as f:
        socket_buffer = int(f.read())
    with tempfile.TemporaryDirectory() as tmp:
        # 40 ms frames: the Python client keeps up with them on a loaded machine.
        d = LiveDaemon(daemon, ctl, tmp, "[camera]\nexposure-us=40000\n[acquisition]\nphases=4\ndark-frame=false\n")
        try:
            slow = RawSubscriber(d.sock)
            fast_events = []
            fast_error = []
            with descatter.Client("unix:" + d.sock) as fc, fc.subscribe() as fsub:
                stop = threading.Event()

                def listen():
                    try:
                        while not stop.is_set():
                            try:
                                ev = fsub.next(timeout=1)
                            except descatter.Timeout:
                                continue
                            if isinstance(ev, descatter.ResultEvent):
                                fast_events.append(ev)
                    except Exception as e:  # reported by the main thread
                        fast_error.append(e)

                t = threading.Thread(target=listen)
                t.start()
                try:
                    d.ctl("start", "--results", "per-frame")
                    # Slow: a pause after every result, longer than a frame.
                    for _ in range(5):
                        slow.read_result()
                        time.sleep(0.15)
                    size = result_bytes(slow.results()[-1])

                    # The pause: no read while 40 more results are published.
                    f0 = d.status()["frame_results"]
                    rss0 = rss_kib(d.proc.pid)
                    queued_max = 0
                    while True:
                        st = d.status()
                        queued_max = max(queued_max, st["clients"]["queued_bytes"])
                        if st["frame_results"] >= f0 + PAUSE_RESULTS:
                            break
                        time.sleep(0.05)
                    published = st["frame_results"]
                    # Printed only: the heap's size also follows the allocator (and a sanitizer's).
                    print(f"daemon RSS {rss0} KiB before the pause, {rss_kib(d.proc.pid)} KiB after it")

                    # Two subscribers, each at most one result being written and the newest.
                    bound = 2 * 2 * size + 65536
                    print(f"queue to clients during the pause: at most {queued_max} bytes; results of "
                          f"{size} bytes; bound {bound}")
                    assert queued_max <= bound, f"the queue grew with the pause: {queued_max} > {bound}"

                    # What was on its way when the pause ended: the result being written, the socket
                    # buffer's worth of more; the next is the newest the daemon had then, or newer.
                    on_the_way = 2 + math.ceil(socket_buffer / size)
                    after = [slow.read_result() for _ in range(on_the_way + 1)]
                    ids = [set_id(h) for h in after]
                    print(f"after the pause ({published} published): sets {ids}, skipped "
                          f"{[h['skipped'] for h in after]}")
                    assert max(ids) >= published, f"no result as new as set {published} in {ids}: a backlog"
                    assert sum(h["skipped"] for h in after) >= PAUSE_RESULTS - len(after), after

                    for _ in range(5):
                        slow.read_result()
                        time.sleep(0.15)
                    d.ctl("stop")
                    end = d.wait_for(lambda s: s["state"] == "idle", "idle after stop")
                    total = end["frame_results"]
                    # The newest result always arrives, however far behind the reader was.
                    while set_id(slow.results()[-1]) < total:
                        slow.read_result()
                    deadline = time.monotonic() + 60
                    while len(fast_events) < total and time.monotonic() < deadline and not fast_error:
                        time.sleep(0.1)
                finally:
                    stop.set()
                    t.join()
            assert not fast_error, fast_error

            res = slow.results()
            frames = [frame_id(h) for h in res]
            assert all(b > a for a, b in zip(frames, frames[1:])), f"frame ids do not increase: {frames}"
            sets = [set_id(h) for h in res]
            assert all(b > a for a, b in zip(sets, sets[1:])), f"set ids do not increase: {sets}"
            accounted = check_accounting(slow, "slow subscriber")
            skipped = sum(h["skipped"] for h in res)
            print(f"slow subscriber: {len(res)} results received, {skipped} skipped, {total} published")
            assert accounted == total, f"received + skipped = {accounted}, published {total}"
            assert skipped >= PAUSE_RESULTS - len(after), "the slow subscriber skipped too little"

            fast_sets = [ev.meta["set_id"] for ev in fast_events]
            print(f"fast subscriber: {len(fast_events)} results, skipped {sum(ev.skipped for ev in fast_events)}")
            assert fast_sets == list(range(1, total + 1)), f"the fast subscriber missed results: {fast_sets}"
            assert all(ev.skipped == 0 and ev.lost == 0 for ev in fast_events), "a fast subscriber skipped results"
            dropped = d.status()["clients"]["results_dropped"]
            assert dropped == skipped, f"status results_dropped {dropped}, the subscribers were told {skipped}"

            # Per-set mode keeps every result for a reader that pauses (within max-queued-bytes).
            before = len(slow.results())
            sets_before = d.status()["sets_done"]
            d.ctl("start")
            s0 = d.wait_for(lambda s: s["state"] == "continuous", "continuous per-set")["sets_done"]
            d.wait_for(lambda s: s["sets_done"] >= s0 + 4, "four sets while not reading")
            d.ctl("stop")
            end = d.wait_for(lambda s: s["state"] == "idle", "idle after stop")
            last = total + end["sets_done"] - sets_before
            while set_id(slow.results()[-1]) < last:
                slow.read_result()
            per_set = slow.results()[before:]
            assert all(h["skipped"] == 0 for h in per_set), "per-set results were skipped"
            assert [set_id(h) for h in per_set] == list(range(total + 1, last + 1)), "a per-set result is missing"
            assert check_accounting(slow, "slow subscriber, per-set") == last
            print(f"per-set: {len(per_set)} results after a pause over 4 sets, none skipped")
            slow.close()
        finally:
            d.stop()
    print("ok")


if __name__ == "__main__":
    main()
