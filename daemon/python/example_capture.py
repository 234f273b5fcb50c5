#!/usr/bin/python3
"""Example: one capture from a running descatterd, printed as numbers.

    /usr/bin/python3 daemon/python/example_capture.py /tmp/descatterd.sock
"""
import sys

from descatter_client import Client

address = sys.argv[1] if len(sys.argv) > 1 else "/run/descatterd/descatterd.sock"
with Client(address) as c:
    print("daemon:", c.hello())
    meta, images = c.capture(phases=8)
    t, s, mask = images["transmissive"], images["scattered"], images["mask"]
    valid = mask == 0
    print(f"set {meta['set_id']}: {t.shape[1]}x{t.shape[0]}, "
          f"transmissive mean {t[valid].mean():.1f} DN, scattered mean {s[valid].mean():.1f} DN, "
          f"{valid.mean() * 100:.1f}% valid pixels")
