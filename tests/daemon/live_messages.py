"""The live view's binary messages read the way the wire format says (daemon/service/live_encode.h),
without the page's code: a little-endian u32 header length, the JSON header, 8-bit pictures, and for
frames the sensor's samples at full resolution."""
import array
import json
import struct
import sys


class LiveMessage:
    def __init__(self, data):
        n = struct.unpack("<I", data[:4])[0]
        self.header = json.loads(data[4:4 + n].decode())
        self.type = self.header["type"]
        self.pixels = data[4 + n:]
        self.samples = None
        s = self.header.get("sensor")
        if s:
            code = {"u8": "B", "u16": "H", "f32": "f"}[s["sample"]]
            a = array.array(code)
            size = a.itemsize * s["width"] * s["height"]
            a.frombytes(self.pixels[s["offset"]:s["offset"] + size])
            if sys.byteorder == "big":
                a.byteswap()  # the wire is little-endian
            self.samples = a

    def sample(self, x, y):
        return self.samples[y * self.header["sensor"]["width"] + x]


def frames(messages):
    """The frame messages among raw WebSocket messages, oldest first."""
    out = []
    for m in messages:
        msg = LiveMessage(m)
        if msg.type == "frame":
            out.append(msg)
    return out
