#!/usr/bin/python3
"""Hostile clients on descatterd's HTTP side (loopback only, bounded in count and time), each
held to what docs/reliability.md ("HTTP") promises, while a socket client is served
throughout:

  - token:      on loopback without token-file, a request without the token is refused and the
                token file beside the socket is readable by the socket's group only;
  - paths:      a foreign-origin WebSocket at /ws/, /ws/x, /ws;x is not upgraded (nor at /ws);
  - rebinding:  a Host that is not the listen address (with its matching Origin) is refused;
  - bodies:     an unauthenticated 300 MiB POST is refused from its Content-Length, and an
                8 MiB header is cut off, the daemon's RSS barely moving;
  - slowloris:  connections trickling header bytes, or sending nothing, are closed;
  - ack:        a page acknowledging every 20 ms without reading gets (almost) nothing more;
  - bridges:    40 pages polling status never keep a socket client out;
  - exhaustion: 400 idle connections stay below the descriptor limit (socket clients still
                served); with descriptors gone, accepting pauses without a flood of log lines and
                resumes afterwards;
  - malformed:  every malformed WebSocket message is answered with an error (the daemon runs
                with G_DEBUG=fatal-criticals), ids come back as sent.

The daemon runs with RLIMIT_NOFILE 256 so that exhaustion is reached quickly. RSS and
descriptor counts (/proc/PID/status, /proc/PID/fd) are printed before and after, and must come
back (RSS within 48 MiB; under AddressSanitizer, whose quarantine keeps freed memory, its leak
check at exit stands for it). Every check runs even when an earlier one failed; the summary names the failures.
HOSTILE_BASELINE=1 leaves out the configuration keys an older descatterd does not know (to show
what failed before).
Usage: test_http_hostile.py DESCATTERD DESCATTERCTL"""
import json
import os
import resource
import socket
import stat
import sys
import tempfile
import threading
import time

import websocket

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from live_daemon import LiveDaemon  # noqa: E402

NOFILE = 256
MIB = 1 << 20
BASELINE = os.environ.get("HOSTILE_BASELINE") == "1"
LIMITS = ("max-live-clients=8\nheader-timeout-ms=1500\nidle-timeout-ms=2000\n"
          "live-send-budget-bytes=65536\n")


def rss_bytes(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    raise AssertionError("no VmRSS")


def fd_count(pid):
    return len(os.listdir(f"/proc/{pid}/fd"))


def http_status(resp):
    try:
        return int(resp.split(b" ", 2)[1])
    except (IndexError, ValueError):
        return None


def raw_request(port, data, timeout=5):
    """Sends `data`, returns the status of the answer (None: closed without one)."""
    s = socket.create_connection(("127.0.0.1", port), timeout=timeout)
    try:
        s.sendall(data)
        resp = b""
        while b"\r\n\r\n" not in resp:
            chunk = s.recv(4096)
            if not chunk:
                break
            resp += chunk
        return http_status(resp)
    except (socket.timeout, ConnectionError):
        return None
    finally:
        s.close()


def upgrade(path, host, origin, token):
    q = f"?token={token}" if token else ""
    return (f"GET {path}{q} HTTP/1.1\r\nHost: {host}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
            f"Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
            f"Origin: {origin}\r\n\r\n").encode()


def socket_status(path, timeout=5):
    """One `status` on a new connection to the socket: True if answered ok."""
    try:
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        s.settimeout(timeout)
        s.connect(path)
        s.sendall(b'{"id": 1, "cmd": "status"}\n')
        line = b""
        while not line.endswith(b"\n"):
            chunk = s.recv(65536)
            if not chunk:
                break
            line += chunk
        s.close()
        return json.loads(line).get("ok") is True
    except (OSError, ValueError):
        return False


class SocketProbe(threading.Thread):
    """A socket client asking `status` on one connection every 0.3 s, all along."""

    def __init__(self, path):
        super().__init__(daemon=True)
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.sock.settimeout(5)
        self.sock.connect(path)
        self.served = self.failed = 0
        self.stop = threading.Event()

    def run(self):
        f = self.sock.makefile("rb")
        n = 0
        while not self.stop.wait(0.3):
            n += 1
            try:
                self.sock.sendall(json.dumps({"id": n, "cmd": "status"}).encode() + b"\n")
                reply = json.loads(f.readline())
                if reply.get("id") == n and reply.get("ok"):
                    self.served += 1
                else:
                    self.failed += 1
            except (OSError, ValueError):
                self.failed += 1


class Suite:
    def __init__(self, d, tmp):
        self.d, self.tmp = d, tmp
        self.pid = d.proc.pid
        self.port = int(d.url.rstrip("/").rsplit(":", 1)[1])
        self.host = f"127.0.0.1:{self.port}"
        tf = d.sock + ".http-token"
        self.token = open(tf).read().strip() if os.path.exists(tf) else None
        self.failures = []

    def run(self, name, fn):
        t0 = time.time()
        try:
            fn()
            print(f"ok   {name} ({time.time() - t0:.1f} s)", flush=True)
        except Exception as e:  # noqa: BLE001 (every check runs; the summary fails the test)
            print(f"FAIL {name}: {type(e).__name__}: {e}", flush=True)
            self.failures.append(name)

    def url(self, path="/"):
        return f"http://{self.host}{path}" + (f"?token={self.token}" if self.token else "")

    def ws(self, **kw):
        return websocket.create_connection(self.url("/ws").replace("http://", "ws://"), timeout=10, **kw)

    def get_status(self, path="/", headers=b""):
        q = f"?token={self.token}" if self.token else ""
        return raw_request(self.port, f"GET {path}{q} HTTP/1.1\r\nHost: {self.host}\r\n".encode() + headers +
                           b"Connection: close\r\n\r\n")

    # ---- the checks ----

    def check_token(self):
        code = raw_request(self.port, f"GET / HTTP/1.1\r\nHost: {self.host}\r\nConnection: close\r\n\r\n".encode())
        assert code == 401, f"GET / without the token on loopback: {code}, expected 401"
        tf = self.d.sock + ".http-token"
        st, sock = os.stat(tf), os.stat(self.d.sock)
        assert stat.S_IMODE(st.st_mode) == 0o640 and st.st_gid == sock.st_gid, (oct(st.st_mode), st.st_gid,
                                                                                 sock.st_gid)
        assert self.get_status() == 200
        url = self.d.ctl("live-url").stdout.strip()
        assert url == self.url("/"), (url, self.url("/"))

    def check_paths(self):
        for path in ("/ws/", "/ws/x", "/ws;x", "/ws"):
            code = raw_request(self.port, upgrade(path, self.host, "http://evil.example", self.token))
            assert code != 101, f"a foreign-origin WebSocket at {path} was upgraded"
            assert code in (403, 404), (path, code)
        assert raw_request(self.port, upgrade("/ws", self.host, f"http://{self.host}", self.token)) == 101

    def check_rebinding(self):
        host = f"rebind.example:{self.port}"
        code = raw_request(self.port, upgrade("/ws", host, f"http://{host}", self.token))
        assert code != 101, "a WebSocket for Host rebind.example was upgraded"
        code = raw_request(self.port, f"GET /metrics HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n".encode())
        assert code == 421 or (code != 200 and self.token), f"GET /metrics with Host rebind.example: {code}"

    def check_bodies(self):
        before = rss_bytes(self.pid)
        peak = before
        # A send blocked for 1 s counts as refused: the daemon reads no more.
        s = socket.create_connection(("127.0.0.1", self.port), timeout=1)
        s.sendall(f"POST /metrics HTTP/1.1\r\nHost: {self.host}\r\nContent-Length: {300 * MIB}\r\n\r\n".encode())
        chunk, sent = b"x" * MIB, 0
        try:
            while sent < 64 * MIB:
                s.sendall(chunk)
                sent += len(chunk)
                if sent % (8 * MIB) == 0:
                    peak = max(peak, rss_bytes(self.pid))
        except (ConnectionError, socket.timeout):
            pass
        time.sleep(0.3)
        peak = max(peak, rss_bytes(self.pid))
        s.close()
        print(f"     300 MiB POST: {sent / MIB:.0f} MiB sent before the daemon closed, RSS "
              f"{before / MIB:.1f} -> peak {peak / MIB:.1f} MiB")
        assert sent < 64 * MIB, "the daemon read 64 MiB of a body it will refuse"
        assert peak - before < 16 * MIB, f"RSS grew {(peak - before) / MIB:.1f} MiB for a refused body"
        before = rss_bytes(self.pid)
        s = socket.create_connection(("127.0.0.1", self.port), timeout=1)
        s.sendall(f"GET / HTTP/1.1\r\nHost: {self.host}\r\nX-Big: ".encode())
        sent = 0
        try:
            while sent < 8 * MIB:
                s.sendall(chunk[:64 * 1024])
                sent += 64 * 1024
        except (ConnectionError, socket.timeout):
            pass
        time.sleep(0.3)
        grown = rss_bytes(self.pid) - before
        s.close()
        print(f"     8 MiB header: {sent / MIB:.1f} MiB sent, RSS grew {grown / MIB:.1f} MiB")
        assert sent < 8 * MIB, "the daemon read an 8 MiB header"

    def check_slowloris(self):
        socks = []
        for i in range(15):
            s = socket.create_connection(("127.0.0.1", self.port), timeout=5)
            s.setblocking(False)
            if i < 10:
                s.send(f"GET / HTTP/1.1\r\nHost: {self.host}\r\nX-Slow: ".encode())
            socks.append(s)
        closed = set()
        # header-timeout-ms 1500 and idle-timeout-ms 2000 close them all; the daemon's sweep can
        # run late on a loaded machine, so the bound is for connections never closed (the slow
        # ones keep sending and would stay open without the timeouts), not a timing.
        deadline = time.time() + 60
        while time.time() < deadline and len(closed) < len(socks):
            time.sleep(0.3)
            for i, s in enumerate(socks):
                if i in closed:
                    continue
                try:
                    data = s.recv(4096)
                    if not data or b" 408 " in data:
                        closed.add(i)
                        continue
                except BlockingIOError:
                    pass
                except ConnectionError:
                    closed.add(i)
                    continue
                if i < 10:
                    try:
                        s.send(b"a")
                    except (BlockingIOError, ConnectionError):
                        pass
        for s in socks:
            s.close()
        assert len(closed) == len(socks), f"{len(socks) - len(closed)} of {len(socks)} slow connections still open after 60 s"

    def check_ack_without_reading(self):
        self.d.ctl("start")
        try:
            base = rss_bytes(self.pid)
            ws = self.ws(sockopt=((socket.SOL_SOCKET, socket.SO_RCVBUF, 4096),))
            t0 = time.time()
            sent = []
            while time.time() - t0 < 5:
                ws.send('{"ack": true}')
                time.sleep(0.02)
                if not sent and time.time() - t0 > 1.5:
                    sent.append(self.d.status()["http"]["live_updates_sent"])
            sent.append(self.d.status()["http"]["live_updates_sent"])
            grown = rss_bytes(self.pid) - base
            ws.close()
        finally:
            self.d.ctl("stop")
        time.sleep(1)
        after = rss_bytes(self.pid) - base
        print(f"     {sent[1] - sent[0]} updates sent in 3.5 s to a page that reads nothing; RSS +{grown / MIB:.1f} "
              f"MiB, +{after / MIB:.1f} MiB after it left")
        assert sent[1] - sent[0] < 8, f"{sent[1] - sent[0]} updates sent to a page that reads nothing"

    def check_bridges(self):
        pages, refused = [], 0
        for _ in range(40):
            try:
                pages.append(self.ws())
            except websocket.WebSocketBadStatusException as e:
                assert e.status_code == 503, e.status_code
                refused += 1
        served = tries = 0
        try:
            t0 = time.time()
            while tries < 3 or (time.time() - t0 < 3 and tries < 10):
                tries += 1
                for p in pages:
                    p.send(json.dumps({"id": tries, "cmd": "status"}))
                    p.settimeout(0.05)
                    try:
                        while True:
                            p.recv()
                            p.send('{"ack": true}')
                    except (websocket.WebSocketTimeoutException, BlockingIOError):
                        pass
                    p.settimeout(10)
                served += socket_status(self.d.sock, timeout=3)
            live = self.d.status()["http"]["live_clients"]
        finally:
            for p in pages:
                p.close()
        print(f"     40 pages: {len(pages)} connected, {refused} refused; socket clients served {served} of {tries}")
        assert served == tries, f"socket clients served {served} of {tries} while pages polled"
        assert live <= 8 and len(pages) <= 8, (live, len(pages))

    def check_exhaustion(self):
        fds0 = fd_count(self.pid)
        conns = []
        for _ in range(400):
            try:
                conns.append(socket.create_connection(("127.0.0.1", self.port), timeout=2))
            except OSError:
                break
        time.sleep(1)
        peak = fd_count(self.pid)
        fresh = socket_status(self.d.sock)
        refused = 0
        for c in conns:
            c.setblocking(False)
            try:
                refused += b" 503 " in c.recv(64)
            except OSError:
                pass
            c.close()
        time.sleep(1)
        print(f"     {len(conns)} idle connections, {refused} refused: daemon descriptors {fds0} -> {peak} "
              f"(limit {NOFILE}); a new socket client served: {fresh}")
        assert fresh, "a new socket client was not served while HTTP connections were open"
        assert self.get_status() == 200, "HTTP does not answer after the idle connections closed"
        # Descriptors gone altogether: lower the daemon's limit under what it holds plus a few.
        log_before = open(self.d.log_path, errors="replace").read().count("\n")
        resource.prlimit(self.pid, resource.RLIMIT_NOFILE, (fd_count(self.pid) + 4, NOFILE))
        conns = [socket.create_connection(("127.0.0.1", self.port), timeout=2) for _ in range(40)]
        # Socket clients arriving meanwhile wait in the backlog, and are served once descriptors
        # are back.
        waiting = []
        for _ in range(3):
            u = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            u.settimeout(10)
            u.connect(self.d.sock)
            u.sendall(b'{"id": 1, "cmd": "status"}\n')
            waiting.append(u)
        time.sleep(2)
        resource.prlimit(self.pid, resource.RLIMIT_NOFILE, (NOFILE, NOFILE))
        for c in conns:
            c.close()
        late = 0
        for u in waiting:
            try:
                late += json.loads(u.makefile("rb").readline()).get("ok") is True
            except (OSError, ValueError):
                pass
            u.close()
        time.sleep(1)
        lines = open(self.d.log_path, errors="replace").read().count("\n") - log_before
        code = self.get_status()
        print(f"     out of descriptors for 2 s: {lines} log lines; HTTP afterwards: {code}; socket clients "
              f"that waited served: {late} of 3")
        assert lines < 20, f"{lines} log lines in 2 s out of descriptors (a busy loop)"
        assert code == 200, f"HTTP does not accept after descriptors came back ({code})"
        assert late == 3, f"{late} of 3 socket clients that waited were served"

    def check_malformed(self):
        ws = self.ws()

        def reply():
            deadline = time.time() + 10
            while time.time() < deadline:
                m = ws.recv()
                if isinstance(m, str):
                    o = json.loads(m)
                    if "ok" in o:
                        return o
                ws.send('{"ack": true}')
            raise AssertionError("no reply")

        for bad in ('{"cmd":{}}', '{"cmd":5}', '[1,2]', 'not json', '{"id":[1],"cmd":"status"}',
                    '{"cmd":"status","args":5}', '{"cmd":"status","extra":1}', '{"id":3}'):
            ws.send(bad)
            r = reply()
            assert r["ok"] is False and r["error"]["message"], (bad, r)
        for ident in ("abc", 7, -2, 1.5):
            ws.send(json.dumps({"id": ident, "cmd": "status"}))
            r = reply()
            assert r["id"] == ident and r["ok"], (ident, r)
        ws.close()
        assert self.d.proc.poll() is None, "descatterd died"


def main():
    daemon, ctl = sys.argv[1], sys.argv[2]
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (max(soft, min(hard, 4096)), hard))
    env = dict(os.environ, G_DEBUG="fatal-criticals")

    def low_nofile():
        resource.setrlimit(resource.RLIMIT_NOFILE, (NOFILE, NOFILE))

    with tempfile.TemporaryDirectory(prefix="ds-hostile-") as tmp:
        conf = "[daemon]\nidle-timeout-ms=60000\n[http]\nlisten=127.0.0.1:0\n" + ("" if BASELINE else LIMITS)
        d = LiveDaemon(daemon, ctl, tmp, conf, env=env, preexec_fn=low_nofile)
        try:
            suite = Suite(d, tmp)
            probe = SocketProbe(d.sock)
            probe.start()
            time.sleep(1)
            rss0, fds0 = rss_bytes(suite.pid), fd_count(suite.pid)
            names = ("token", "paths", "rebinding", "bodies", "slowloris", "ack_without_reading", "bridges",
                     "exhaustion", "malformed")
            for name in os.environ.get("HOSTILE_ONLY", ",".join(names)).split(","):
                if d.proc.poll() is not None:
                    print(f"FAIL {name}: descatterd is gone")
                    suite.failures.append(name)
                    continue
                suite.run(name, getattr(suite, "check_" + name))
            probe.stop.set()
            probe.join(10)
            if d.proc.poll() is None:
                time.sleep(2.5)  # idle HTTP connections of the checks time out
                rss1, fds1 = rss_bytes(suite.pid), fd_count(suite.pid)
                print(f"RSS {rss0 / MIB:.1f} -> {rss1 / MIB:.1f} MiB, descriptors {fds0} -> {fds1}; socket client "
                      f"served {probe.served}, failed {probe.failed}")
                # AddressSanitizer keeps freed memory in quarantine (256 MiB) and checks leaks itself at
                # exit: there the RSS bound says nothing.
                sanitized = "libasan" in open(f"/proc/{suite.pid}/maps").read()
                if fds1 > fds0 + 4 or (rss1 > rss0 + 48 * MIB and not sanitized):
                    suite.failures.append("resources returned")
            if probe.failed or not probe.served:
                suite.failures.append("socket client served throughout")
        finally:
            if d.proc.poll() is None:
                d.stop()
        if suite.failures:
            print("FAILED: " + ", ".join(suite.failures))
            print(open(d.log_path, errors="replace").read()[-1500:])
            return 1
        return 0


if __name__ == "__main__":
    sys.exit(main())
