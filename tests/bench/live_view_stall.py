#!/usr/bin/python3
"""Does a stalled browser slow acquisition? descatterd on the simulated lab, continuous sets,
HTTP on; sets per second measured in rounds of equal length:
  A   baseline: nobody connected
  B   4 WebSocket clients that never read nor acknowledge, a socket subscriber that never
      reads, and an HTTP client that never finishes its request
  A'  baseline again (the machine's drift)
  C   one browser-like client that reads and acknowledges every update as fast as it can
Prints each round's rate and its ratio to the mean of A and A'. Timing is reported, not
asserted; what is checked: each stalled WebSocket client holds exactly one update (the daemon
waits for its ack and sends nothing more), the daemon counted the updates it replaced, its RSS
did not grow by more than 64 MiB, and the active client saw results and frames.
Usage: live_view_stall.py DESCATTERD DESCATTERCTL [--quick]   (docs/benchmarks.md, "Live view")"""
import json
import os
import socket
import struct
import sys
import tempfile
import threading
import time

import websocket

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "daemon"))
from live_daemon import LiveDaemon  # noqa: E402


def rss_kib(pid):
    for line in open(f"/proc/{pid}/status"):
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    return 0


def measure(d, seconds):
    st0 = d.status()
    t0 = time.monotonic()
    time.sleep(seconds)
    st1 = d.status()
    return (st1["sets_done"] - st0["sets_done"]) / (time.monotonic() - t0)


def ws_url(d):
    """The live view's WebSocket with the page's token (descatterctl live-url)."""
    return d.page_url().replace("http://", "ws://").replace("/?token=", "/ws?token=")


def active_client(url, stop, seen):
    ws = websocket.create_connection(url, timeout=10)
    while not stop.is_set():
        try:
            m = ws.recv()
        except websocket.WebSocketTimeoutException:
            continue
        if isinstance(m, bytes):
            n = struct.unpack("<I", m[:4])[0]
            seen[json.loads(m[4:4 + n])["type"]] += 1
        ws.send('{"ack": true}')
    ws.close()


def main():
    daemon, ctl = sys.argv[1:3]
    seconds = 5 if "--quick" in sys.argv else 30
    with tempfile.TemporaryDirectory() as tmp:
        d = LiveDaemon(daemon, ctl, tmp, "[http]\nlisten=127.0.0.1:0\n[acquisition]\nphases=4\n")
        try:
            d.ctl("start")
            d.wait_for(lambda s: s["sets_done"] >= 2, "warm-up")
            rss0 = rss_kib(d.proc.pid)
            rates = {"A": measure(d, seconds)}

            stalled = [websocket.create_connection(ws_url(d), timeout=10) for _ in range(4)]
            sub = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            sub.connect(d.sock)
            sub.sendall(b'{"id": 1, "cmd": "subscribe"}\n')
            host, port = d.url.split("//")[1].rstrip("/").split(":")
            slow = socket.create_connection((host, int(port)))
            slow.sendall(b"GET /metrics HTTP/1.1\r\nHost: x\r\n")
            rates["B"] = measure(d, seconds)
            st = d.status()
            superseded = st["http"]["live_updates_superseded"]
            rss1 = rss_kib(d.proc.pid)
            held = []
            for ws in stalled:
                ws.settimeout(1)
                n = 0
                try:
                    while True:
                        ws.recv()
                        n += 1
                except websocket.WebSocketTimeoutException:
                    pass
                held.append(n)
                ws.close()
            sub.close()
            slow.close()

            rates["A'"] = measure(d, seconds)
            stop, seen = threading.Event(), {"frame": 0, "result": 0}
            t = threading.Thread(target=active_client, args=(ws_url(d), stop, seen))
            t.start()
            rates["C"] = measure(d, seconds)
            stop.set()
            t.join()
            d.ctl("stop")
        finally:
            d.stop()
    base = (rates["A"] + rates["A'"]) / 2
    print(f"live view stall benchmark, {seconds} s per round, sets of 4 phases on the simulated lab")
    for k, what in (("A", "nobody connected"), ("B", "4 stalled WebSockets, a stalled subscriber, a stalled HTTP request"),
                    ("A'", "nobody connected, again"), ("C", "one browser reading every update")):
        print(f"  {k:2} {rates[k]:6.2f} sets/s  ratio {rates[k] / base if base else float('nan'):5.2f}  {what}")
    print(f"  updates held by each stalled WebSocket: {held}; updates replaced while they stalled: {superseded}")
    print(f"  RSS {rss0 // 1024} MiB before the stalled clients, {rss1 // 1024} MiB with them")
    print(f"  the reading client saw {seen['result']} results and {seen['frame']} frames")
    assert held == [1, 1, 1, 1], f"a stalled WebSocket client was sent more than one update: {held}"
    assert superseded > 0, "no update was replaced while the clients stalled"
    assert rss1 - rss0 < 64 * 1024, f"RSS grew by {(rss1 - rss0) // 1024} MiB with stalled clients"
    assert seen["result"] >= 1 and seen["frame"] >= 1, seen


if __name__ == "__main__":
    main()
