#!/usr/bin/python3
"""descatterd's HTTP side without a browser: /metrics parsed with prometheus_client's own parser
and checked against the status document (the same counters read another way) and against the
results a subscriber received; the token (none, wrong, ?token=, Bearer); a WebSocket from a
foreign origin refused; a non-loopback address without a token refused at start; the live
view's WebSocket protocol (an update, the ack that allows the next, a command through the
bridge and its reply, a command the view does not offer).
Usage: test_http.py DESCATTERD DESCATTERCTL"""
import json
import os
import struct
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request

import websocket
from prometheus_client.parser import text_string_to_metric_families

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from live_daemon import LiveDaemon  # noqa: E402

TOKEN = "s3cret-token-0123456789"


def get(url, headers=None):
    req = urllib.request.Request(url, headers=headers or {})
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            return r.status, r.read().decode(), r.headers
    except urllib.error.HTTPError as e:
        return e.code, e.read().decode(), e.headers


def metrics(url):
    code, text, headers = get(url + "metrics?token=" + TOKEN)
    assert code == 200 and headers["Content-Type"].startswith("text/plain; version=0.0.4"), (code, headers)
    fams = {f.name: f for f in text_string_to_metric_families(text)}
    return fams


def value(fams, name, **labels):
    for s in fams[name].samples:
        if s.name.endswith(("_total", "_bucket", "_sum", "_count")) and not name.endswith("seconds") and s.name != name + "_total":
            continue
        if all(s.labels.get(k) == v for k, v in labels.items()):
            return s.value
    raise KeyError((name, labels))


def check_metrics(d):
    # Three results to a subscriber, then the counters.
    sub = subprocess.Popen([d.ctl_path, "--address", d.sock, "stream", "--count", "3"], stdout=subprocess.PIPE, text=True)
    d.ctl("start", "--phases", "4")
    out, _ = sub.communicate(timeout=120)
    d.ctl("stop")
    st = d.wait_for(lambda s: not s["continuous"] and s["state"] == "idle", "idle")
    fams = metrics(d.url)
    st = d.status()
    assert value(fams, "descatter_sets", outcome="done") == st["sets_done"] >= 3
    assert value(fams, "descatter_sets", outcome="failed") == st["sets_failed"]
    assert value(fams, "descatter_frames_acquired") == st["frames"]["acquired"]
    assert value(fams, "descatter_frames_folded") == st["frames"]["folded"]
    for reason, n in st["frames"]["dropped_by_reason"].items():
        assert value(fams, "descatter_frames_dropped", reason=reason) == n, reason
    assert value(fams, "descatter_results_published") == st["clients"]["results_published"]
    assert value(fams, "descatter_camera_missing_packets") == st["devices"]["camera"]["missing_packets"]
    assert value(fams, "descatter_camera_resend_requests") == st["devices"]["camera"]["resend_requests"]
    # The latency histogram saw every published result; its buckets never decrease.
    h = fams["descatter_result_latency_seconds"]
    assert h.type == "histogram"
    buckets = [(float(s.labels["le"]), s.value) for s in h.samples if s.name.endswith("_bucket")]
    count = [s.value for s in h.samples if s.name.endswith("_count")][0]
    assert count == st["clients"]["results_published"] and buckets[-1] == (float("inf"), count)
    assert all(a[1] <= b[1] for a, b in zip(buckets, buckets[1:])), buckets
    assert fams["descatter_illuminator_temperature_celsius"].type == "gauge"
    assert value(fams, "descatter_clients", kind="live") == 0
    assert [s for s in fams["descatter_build_info"].samples][0].labels["version"] == st["version"]
    current = [s.labels["state"] for s in fams["descatter_acquisition_state"].samples if s.value == 1]
    assert current == [st["state"]], current


def check_token(d):
    url = d.url
    assert get(url + "metrics")[0] == 401
    assert get(url + "metrics?token=wrong-token-0123456789")[0] == 401
    assert get(url + "metrics", {"Authorization": "Bearer " + TOKEN})[0] == 200
    code, body, _ = get(url + "?token=" + TOKEN)
    assert code == 200 and "<canvas id=\"raw\"" in body
    assert get(url + "nothing?token=" + TOKEN)[0] == 404
    ws_url = url.replace("http://", "ws://") + "ws?token=" + TOKEN
    try:
        websocket.create_connection(ws_url.replace(TOKEN, "wrong"), timeout=10)
        raise AssertionError("a WebSocket without the token was accepted")
    except websocket.WebSocketBadStatusException as e:
        assert e.status_code == 401
    try:
        websocket.create_connection(ws_url, timeout=10, origin="http://evil.example")
        raise AssertionError("a WebSocket from another origin was accepted")
    except websocket.WebSocketBadStatusException as e:
        assert e.status_code == 403
    host = url.split("//")[1].rstrip("/")
    ws = websocket.create_connection(ws_url, timeout=10, origin="http://" + host)
    ws.close()


def recv_update(ws):
    """The next live update: ("status", dict) or (type, header) of a binary one."""
    m = ws.recv()
    if isinstance(m, str):
        o = json.loads(m)
        return (o.get("type") or "reply"), o
    n = struct.unpack("<I", m[:4])[0]
    h = json.loads(m[4:4 + n].decode())
    pixels = m[4 + n:]
    for img in h["images"]:
        assert img["offset"] + img["width"] * img["height"] <= len(pixels), img
    return h["type"], h


def check_websocket(d):
    ws_url = d.url.replace("http://", "ws://") + "ws?token=" + TOKEN
    ws = websocket.create_connection(ws_url, timeout=30)
    # The first update; nothing more comes until it is acknowledged.
    kind, first = recv_update(ws)
    assert kind == "status" and "frames" in first["status"], first
    d.ctl("capture", "--quiet", "--phases", "4", "--out", os.path.join(d.tmp, "cap"))
    ws.settimeout(2)
    try:
        ws.recv()
        raise AssertionError("an update came before the ack")
    except websocket.WebSocketTimeoutException:
        pass
    ws.settimeout(30)
    seen = set()
    for _ in range(10):
        ws.send('{"ack": true}')
        kind, h = recv_update(ws)
        seen.add(kind)
        if kind == "result":
            names = {i["name"] for i in h["images"]}
            assert names == {"transmissive", "scattered", "average", "mask"}, names
            assert h["meta"]["set_id"] >= 1 and h["meta"]["camera"]["backend"] == "sim"
            break
    assert "result" in seen, seen
    # A command through the live view: a reply with the socket protocol's error for a bad argument.
    ws.send(json.dumps({"id": 7, "cmd": "capture", "args": {"phases": 1}}))
    for _ in range(20):
        kind, h = recv_update(ws)
        if kind == "reply":
            break
        ws.send('{"ack": true}')
    assert h["id"] == 7 and not h["ok"] and h["error"]["code"] == "bad_argument" and "phases" in h["error"]["message"], h
    ws.send(json.dumps({"id": 8, "cmd": "subscribe"}))
    for _ in range(20):
        kind, h = recv_update(ws)
        if kind == "reply":
            break
        ws.send('{"ack": true}')
    assert h["id"] == 8 and not h["ok"] and "not a command of the live view" in h["error"]["message"], h
    ws.send(json.dumps({"id": 9, "cmd": "status"}))
    for _ in range(20):
        kind, h = recv_update(ws)
        if kind == "reply":
            break
        ws.send('{"ack": true}')
    assert h["id"] == 9 and h["ok"] and "frames" in h["result"], h
    # The daemon closes an idle connection (idle-timeout-ms); the view makes a new one.
    time.sleep(1.5)
    ws.send(json.dumps({"id": 10, "cmd": "status"}))
    for _ in range(40):
        kind, h = recv_update(ws)
        if kind == "reply":
            break
        ws.send('{"ack": true}')
    assert h["id"] == 10 and h["ok"], h
    ws.close()


def check_refusals(daemon, ctl, tmp):
    # Not loopback and no token: refused at start, naming the key.
    d = LiveDaemon(daemon, ctl, os.path.join(tmp, "open"), "[http]\nlisten=0.0.0.0:0\n", wait=False)
    code = d.proc.wait(60)
    d.log.close()
    log = open(d.log_path).read()
    assert code != 0 and "[http] listen" in log and "[http] token-file" in log, (code, log[-500:])


def main():
    daemon, ctl = sys.argv[1:3]
    with tempfile.TemporaryDirectory() as tmp:
        os.mkdir(os.path.join(tmp, "open"))
        token_file = os.path.join(tmp, "token")
        with open(token_file, "w") as f:
            f.write(TOKEN + "\n")
        d = LiveDaemon(daemon, ctl, tmp, f"[daemon]\nidle-timeout-ms=1000\n"
                                         f"[http]\nlisten=127.0.0.1:0\ntoken-file={token_file}\n")
        try:
            assert d.url and d.url.startswith("http://127.0.0.1:"), d.url
            check_token(d)
            check_metrics(d)
            check_websocket(d)
            # descatterctl release / acquire (the labsim test shows another program taking the camera).
            assert json.loads(d.ctl("release", "--json").stdout)["state"] == "released"
            r = d.ctl("capture", "--quiet", "--out", os.path.join(tmp, "refused"), check=False)
            assert r.returncode != 0 and "acquire" in r.stderr, r.stderr
            assert value(metrics(d.url), "descatter_acquisition_state", state="released") == 1
            assert json.loads(d.ctl("acquire", "--json").stdout)["state"] == "idle"
        finally:
            d.stop()
        check_refusals(daemon, ctl, tmp)
    print("http: ok")


if __name__ == "__main__":
    main()
