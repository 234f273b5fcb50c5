#!/usr/bin/python3
"""descatterd's /metrics read by a real Prometheus server (Debian's `prometheus`) on loopback,
and checked by `promtool check metrics`; the series compared with the status document and with
rules written here independently of the daemon:
- bucket labels are the shortest text that reads back as the bound (Python's repr is exactly
  that), so a query for le="0.0025" finds its series;
- the state is a state set: every state of the status document's vocabulary is a series, the
  current one 1 and the others 0;
- `descatter_ready` follows status.ready; `process_start_time_seconds` lies between the
  test's clock before the start and after readiness; `descatter_last_result_timestamp_seconds`
  appears with the first result, between the request and its reply;
- a device error is counted as an error reply with its code, not as a bad request; a malformed
  request as both.
Usage: test_prometheus.py DESCATTERD DESCATTERCTL"""
import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import urllib.parse
import urllib.request

from prometheus_client.parser import text_string_to_metric_families

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from live_daemon import LiveDaemon  # noqa: E402

TOKEN = "prometheus-token-0123456789"
STATES = ["opening", "idle", "acquiring", "continuous", "reconnecting", "released", "failed", "cancelling",
          "preview"]


def scrape(url):
    req = urllib.request.Request(url + "metrics", headers={"Authorization": "Bearer " + TOKEN})
    with urllib.request.urlopen(req, timeout=30) as r:
        return r.read().decode()


def families(text):
    return {f.name: f for f in text_string_to_metric_families(text)}


def value(fams, name, **labels):
    for fam in fams.values():
        for s in fam.samples:
            if s.name in (name, name + "_total") and all(s.labels.get(k) == v for k, v in labels.items()):
                return s.value
    raise KeyError((name, labels))


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def request_raw(sock_path, line):
    """One raw line on the UNIX socket, its reply line."""
    with socket.socket(socket.AF_UNIX) as s:
        s.settimeout(30)
        s.connect(sock_path)
        s.sendall(line.encode() + b"\n")
        buf = b""
        while not buf.endswith(b"\n"):
            chunk = s.recv(65536)
            if not chunk:
                break
            buf += chunk
        return json.loads(buf.splitlines()[0])


def check_exposition(d, text, t_before_start, t_ready):
    fams = families(text)
    st = d.status()
    # Shortest round-trip labels: float(label) reads back the bound and no shorter text does.
    for s in fams["descatter_result_latency_seconds"].samples:
        if s.name.endswith("_bucket") and s.labels["le"] != "+Inf":
            le = s.labels["le"]
            v = float(le)
            shortest = repr(v)[:-2] if repr(v).endswith(".0") else repr(v)
            assert le == shortest, (le, shortest)
    assert 'le="0.0025"' in text
    # The state set: the status vocabulary, exactly one 1.
    states = {s.labels["state"]: s.value for s in fams["descatter_acquisition_state"].samples}
    assert sorted(states) == sorted(STATES), states
    assert [k for k, v in states.items() if v == 1] == [st["state"]], (states, st["state"])
    assert value(fams, "descatter_ready") == (1 if st["ready"] else 0)
    start = value(fams, "process_start_time_seconds")
    assert t_before_start - 1 <= start <= t_ready + 1, (t_before_start, start, t_ready)
    assert "descatter_uptime_seconds" not in fams


def check_error_accounting(d):
    fams0 = families(scrape(d.url))
    bad0 = value(fams0, "descatter_socket_bad_requests")
    # A malformed request: the client's fault.
    r = request_raw(d.sock, '{"id": 1, "cmd": "capture", "args": {"phases": "many"}}')
    assert not r["ok"] and r["error"]["code"] == "bad_argument", r
    # Released devices: a capture is refused, but not for what the client sent.
    assert json.loads(d.ctl("release", "--json").stdout)["state"] == "released"
    r = request_raw(d.sock, '{"id": 2, "cmd": "capture", "args": {}}')
    assert not r["ok"], r
    code = r["error"]["code"]
    assert code == "device_error" and "released" in r["error"]["message"], r
    fams1 = families(scrape(d.url))
    assert value(fams1, "descatter_socket_bad_requests") == bad0 + 1
    assert value(fams1, "descatter_socket_error_replies", code="bad_argument") == \
        value(fams0, "descatter_socket_error_replies", code="bad_argument") + 1
    assert value(fams1, "descatter_socket_error_replies", code=code) == \
        value(fams0, "descatter_socket_error_replies", code=code) + 1
    assert value(fams1, "descatter_acquisition_state", state="released") == 1
    assert value(fams1, "descatter_acquisition_state", state="idle") == 0
    st = d.status()
    assert st["clients"]["error_replies"][code] >= 1 and st["clients"]["bad_requests"] == bad0 + 1, st["clients"]
    assert json.loads(d.ctl("acquire", "--json").stdout)["state"] == "idle"
    d.wait_for(lambda s: s["ready"], "ready")


def query(prom, expr):
    url = prom + "api/v1/query?" + urllib.parse.urlencode({"query": expr})
    with urllib.request.urlopen(url, timeout=30) as r:
        doc = json.load(r)
    assert doc["status"] == "success", doc
    return doc["data"]["result"]


def wait_query(prom, expr, pred, what, proc, timeout=90):
    deadline = time.time() + timeout
    last = None
    while time.time() < deadline:
        if proc.poll() is not None:
            raise AssertionError("prometheus exited with %d" % proc.returncode)
        try:
            last = query(prom, expr)
            if pred(last):
                return last
        except OSError as e:  # the server is still starting
            last = e
        time.sleep(0.5)
    raise AssertionError(f"prometheus: {what}: {expr} gave {last}")


def check_prometheus(d, tmp, token_file):
    port = free_port()
    target = d.url.split("//")[1].rstrip("/")
    conf = os.path.join(tmp, "prometheus.yml")
    with open(conf, "w") as f:
        f.write(f"""global:
  scrape_interval: 1s
  evaluation_interval: 1s
scrape_configs:
  - job_name: descatterd
    authorization:
      type: Bearer
      credentials_file: {token_file}
    static_configs:
      - targets: ["{target}"]
""")
    log = open(os.path.join(tmp, "prometheus.log"), "w")
    proc = subprocess.Popen(["prometheus", "--config.file", conf, "--storage.tsdb.path", os.path.join(tmp, "tsdb"),
                             "--web.listen-address", f"127.0.0.1:{port}"], stdout=log, stderr=log)
    prom = f"http://127.0.0.1:{port}/"
    try:
        # The scrape worked: Prometheus parsed the exposition with its own parser.
        wait_query(prom, 'up{job="descatterd"}', lambda r: r and r[0]["value"][1] == "1", "scrape up", proc)
        r = wait_query(prom, "descatter_ready", lambda r: r and r[0]["value"][1] == "1", "ready", proc)
        assert r[0]["metric"]["job"] == "descatterd"
        # The label a person types finds the bucket.
        wait_query(prom, 'descatter_result_latency_seconds_bucket{le="0.0025"}', lambda r: len(r) == 1,
                   "bucket le=0.0025", proc)
        r = wait_query(prom, 'descatter_acquisition_state == 1', lambda r: len(r) == 1, "one state", proc)
        assert r[0]["metric"]["state"] == d.status()["state"], r
        # A result seen by Prometheus: its timestamp after the test asked for it.
        wait_query(prom, "descatter_last_result_timestamp_seconds", lambda r: len(r) == 1, "last result", proc)
        r = wait_query(prom, "time() - process_start_time_seconds", lambda r: len(r) == 1, "uptime", proc)
        assert 0 < float(r[0]["value"][1]) < 3600, r
    finally:
        proc.terminate()
        proc.wait(30)
        log.close()


def main():
    daemon, ctl = sys.argv[1:3]
    if shutil.which("prometheus") is None or shutil.which("promtool") is None:
        raise SystemExit("prometheus and promtool are missing: tools/lab.sh deps installs Debian's prometheus")
    with tempfile.TemporaryDirectory() as tmp:
        token_file = os.path.join(tmp, "token")
        with open(token_file, "w") as f:
            f.write(TOKEN + "\n")
        t_before = time.time()
        d = LiveDaemon(daemon, ctl, tmp, f"[http]\nlisten=127.0.0.1:0\ntoken-file={token_file}\n")
        t_ready = time.time()
        try:
            text = scrape(d.url)
            assert "descatter_last_result_timestamp_seconds" not in text  # no result yet
            check_exposition(d, text, t_before, t_ready)
            t_ask = time.time()
            d.ctl("capture", "--quiet", "--phases", "4", "--out", os.path.join(tmp, "set"))
            t_got = time.time()
            fams = families(scrape(d.url))
            last = value(fams, "descatter_last_result_timestamp_seconds")
            assert t_ask - 1 <= last <= t_got + 1, (t_ask, last, t_got)
            text = scrape(d.url)
            check_exposition(d, text, t_before, t_ready)
            r = subprocess.run(["promtool", "check", "metrics"], input=text, capture_output=True, text=True)
            assert r.returncode == 0, r.stdout + r.stderr
            check_error_accounting(d)
            check_prometheus(d, tmp, token_file)
        finally:
            d.stop()
    print("prometheus: ok")


if __name__ == "__main__":
    main()
