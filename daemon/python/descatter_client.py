"""Client for descatterd's socket protocol (docs/protocol.md), standard library + numpy only.

    from descatter_client import Client
    with Client("/run/descatterd/descatterd.sock") as c:
        meta, images = c.capture(phases=8, exposure_us=4000)
        transmissive = images["transmissive"]      # numpy float32 array, height x width

Each message is one JSON line followed by the binary payloads its "payloads" array announces.
"""
import json
import socket

import numpy as np

_DTYPES = {"u8": np.dtype("u1"), "u16": np.dtype("<u2"), "f32": np.dtype("<f4")}


class DescatterError(Exception):
    """A reply with ok=false: .code is the stable error name, the message says why."""

    def __init__(self, code, message):
        super().__init__(f"{code}: {message}")
        self.code = code
        self.message = message


class Client:
    def __init__(self, address, timeout=None):
        """address: a UNIX socket path, 'unix:PATH' or 'tcp:HOST:PORT'."""
        if address.startswith("tcp:"):
            host, port = address[4:].rsplit(":", 1)
            self._sock = socket.create_connection((host, int(port)), timeout=timeout)
        else:
            path = address[5:] if address.startswith("unix:") else address
            self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            self._sock.settimeout(timeout)
            self._sock.connect(path)
        self._file = self._sock.makefile("rb")
        self._next_id = 0

    def close(self):
        self._file.close()
        self._sock.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def read_message(self):
        """Next reply or event as (header dict, {payload name: numpy array})."""
        line = self._file.readline()
        if not line:
            raise ConnectionError("descatterd closed the connection")
        header = json.loads(line)
        images = {}
        for p in header.get("payloads", []):
            dtype = _DTYPES[p["dtype"]]
            expected = p["width"] * p["height"] * dtype.itemsize
            if p["bytes"] != expected:
                raise ValueError(f"payload {p['name']}: {p['bytes']} bytes, shape needs {expected}")
            data = self._file.read(p["bytes"])
            if len(data) != p["bytes"]:
                raise ConnectionError(f"payload {p['name']}: connection closed mid-payload")
            images[p["name"]] = np.frombuffer(data, dtype=dtype).reshape(p["height"], p["width"])
        return header, images

    def call(self, cmd, on_event=None, **args):
        """Sends a command, returns (result dict, images). Events arriving meanwhile (progress,
        subscribed results) go to on_event(header, images)."""
        self._next_id += 1
        request = {"id": self._next_id, "cmd": cmd}
        if args:
            request["args"] = args
        self._sock.sendall(json.dumps(request).encode() + b"\n")
        while True:
            header, images = self.read_message()
            if "event" in header:
                if on_event:
                    on_event(header, images)
                continue
            if header.get("id") != self._next_id:
                continue
            if not header.get("ok"):
                err = header.get("error", {})
                raise DescatterError(err.get("code", "failed"), err.get("message", ""))
            return header.get("result", {}), images

    def hello(self):
        return self.call("hello")[0]

    def status(self):
        return self.call("status")[0]

    def capture(self, **args):
        """One phase set. Arguments as in docs/protocol.md (phases, averages, exposure_us, ...)."""
        return self.call("capture", **args)

    def results(self):
        """Subscribes and yields (metadata, images) for every published result."""
        self.call("subscribe")
        while True:
            header, images = self.read_message()
            if header.get("event") == "result":
                yield header.get("body", {}), images
