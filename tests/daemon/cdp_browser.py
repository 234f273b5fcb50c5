"""Headless Chromium driven through its DevTools protocol (python3-websocket; no npm, no
download): start, open a page, evaluate JavaScript, click, move and drag the mouse, resize the
viewport, keep the binary WebSocket messages the page receives, take a screenshot."""
import base64
import collections
import json
import os
import shutil
import subprocess
import tempfile
import time
import urllib.request

import websocket

CHROMIUM_FLAGS = ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--remote-debugging-port=0"]


class Browser:
    def __init__(self, width=1400, height=1000):
        exe = shutil.which("chromium") or shutil.which("chromium-browser")
        if not exe:
            raise RuntimeError("chromium is not installed (Debian package chromium; tools/lab.sh deps)")
        self.profile = tempfile.mkdtemp(prefix="ds-chromium-")
        # Chromium's own temporary files (its singleton socket folder, org.chromium.Chromium.*)
        # go in TMPDIR and outlive a terminated browser: kept inside the profile, they go with it.
        own_tmp = os.path.join(self.profile, "tmp")
        os.mkdir(own_tmp)
        self.proc = subprocess.Popen([exe, *CHROMIUM_FLAGS, f"--user-data-dir={self.profile}",
                                      f"--window-size={width},{height}", "about:blank"],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                     env={**os.environ, "TMPDIR": own_tmp})
        port_file = os.path.join(self.profile, "DevToolsActivePort")
        deadline = time.time() + 60
        while not (os.path.exists(port_file) and "\n" in open(port_file).read()):
            if self.proc.poll() is not None or time.time() > deadline:
                raise RuntimeError("chromium did not start")
            time.sleep(0.1)
        port = open(port_file).read().split("\n")[0]
        targets = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=30))
        page = [t for t in targets if t["type"] == "page"][0]
        self.ws = websocket.create_connection(page["webSocketDebuggerUrl"], timeout=60, suppress_origin=True)
        self.next_id = 0
        self.call("Page.enable")
        self.call("Runtime.enable")
        self.console = []
        self.ws_messages = None  # the newest binary WebSocket messages, once capture_websocket()

    def call(self, method, **params):
        self.next_id += 1
        self.ws.send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        while True:
            m = json.loads(self.ws.recv())
            if m.get("method") == "Runtime.exceptionThrown":
                d = m["params"]["exceptionDetails"]
                self.console.append(d.get("text", "exception") + ": " + str(d.get("exception", {}).get("description")))
            if m.get("method") == "Network.webSocketFrameReceived" and self.ws_messages is not None:
                r = m["params"]["response"]
                if r.get("opcode") == 2:
                    self.ws_messages.append(r["payloadData"])
            if m.get("id") == self.next_id:
                if "error" in m:
                    raise RuntimeError(f"{method}: {m['error']}")
                return m.get("result", {})

    def open(self, url):
        self.call("Page.navigate", url=url)

    def js(self, expression):
        r = self.call("Runtime.evaluate", expression=expression, returnByValue=True, awaitPromise=True)
        if "exceptionDetails" in r:
            raise RuntimeError(f"{expression}: {r['exceptionDetails']}")
        return r["result"].get("value")

    def wait(self, expression, what, timeout=120):
        """Until expression is truthy; one that throws (the page still loading) counts as false."""
        deadline = time.time() + timeout
        while True:
            try:
                v = self.js(expression)
            except RuntimeError:
                v = None
            if v:
                return v
            if time.time() > deadline:
                raise AssertionError(f"timed out waiting for {what} ({expression})")
            time.sleep(0.1)

    def click(self, selector):
        self.js(f"document.querySelector({json.dumps(selector)}).click()")

    def capture_websocket(self, keep=16):
        """From now on keep the newest `keep` binary messages the page's WebSockets receive (bytes,
        as the server sent them), read by received_messages()."""
        self.ws_messages = collections.deque(maxlen=keep)
        self.call("Network.enable", maxTotalBufferSize=256 << 20)

    def received_messages(self):
        self.js("0")  # reads the events that came meanwhile
        return [base64.b64decode(p) for p in self.ws_messages]

    def mouse(self, kind, x, y, buttons=0):
        """A real mouse event at page coordinates (CSS pixels): kind moved, pressed or released."""
        self.call("Input.dispatchMouseEvent", type={"moved": "mouseMoved", "pressed": "mousePressed",
                                                    "released": "mouseReleased"}[kind], x=x, y=y,
                  button="left" if buttons or kind != "moved" else "none", buttons=buttons, clickCount=1)

    def drag(self, x0, y0, x1, y1, steps=5):
        self.mouse("moved", x0, y0)
        self.mouse("pressed", x0, y0, 1)
        for i in range(1, steps + 1):
            self.mouse("moved", x0 + (x1 - x0) * i / steps, y0 + (y1 - y0) * i / steps, 1)
        self.mouse("released", x1, y1, 1)

    def set_viewport(self, width, height):
        self.call("Emulation.setDeviceMetricsOverride", width=width, height=height, deviceScaleFactor=1, mobile=False)

    def screenshot(self, path):
        data = self.call("Page.captureScreenshot", format="png")["data"]
        with open(path, "wb") as f:
            f.write(base64.b64decode(data))

    def close(self):
        try:
            self.ws.close()
        finally:
            self.proc.terminate()
            try:
                self.proc.wait(30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
            # The browser's helper processes may still write in the profile for a moment after
            # the main one exited: removed until nothing is left (30 s at most).
            deadline = time.time() + 30
            while True:
                shutil.rmtree(self.profile, ignore_errors=True)
                if not os.path.exists(self.profile) or time.time() > deadline:
                    break
                time.sleep(0.2)
