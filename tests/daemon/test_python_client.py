#!/usr/bin/python3
"""The Python client (daemon/python/descatter_client.py) against a running descatterd on the
simulated lab. Usage: test_python_client.py DESCATTERD SCENE

Independent checks: in one result, the max/min estimator's closed form must hold between the
payloads as decoded (transmissive = max - min, scattered = 2 min for a = 1/2, b = 0), which a
byte-order, dtype or framing error in the client would break; errors arrive as exceptions
with the protocol's stable codes; subscribed results arrive with increasing seq."""
import os
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "daemon", "python"))
import numpy as np  # noqa: E402
from descatter_client import Client, DescatterError  # noqa: E402


def main():
    daemon, scene = sys.argv[1], sys.argv[2]
    with tempfile.TemporaryDirectory() as tmp:
        sock = os.path.join(tmp, "d.sock")
        conf = os.path.join(tmp, "d.conf")
        with open(conf, "w") as f:
            f.write(f"[camera]\nbackend=sim\n[illuminator]\nbackend=sim\n[sim]\nscene={scene}\n")
        proc = subprocess.Popen([daemon, "--config", conf, "--socket", sock, "--no-socket-activation"])
        try:
            deadline = time.time() + 120
            while True:
                try:
                    with Client(sock) as c:
                        if c.status()["ready"]:
                            break
                except (OSError, ConnectionError):
                    pass
                assert proc.poll() is None, "descatterd exited"
                assert time.time() < deadline, "descatterd not ready"
                time.sleep(0.1)
            with Client(sock) as c:
                hello = c.hello()
                assert hello["protocol"] == 1, hello
                meta, im = c.capture(phases=4, outputs=["transmissive", "scattered", "mask", "max", "min", "mean"])
                t, s, mx, mn = im["transmissive"], im["scattered"], im["max"], im["min"]
                assert t.dtype == np.float32 and im["mask"].dtype == np.uint8
                assert t.shape == (meta["height"], meta["width"])
                np.testing.assert_allclose(t, mx - mn, rtol=1e-5, atol=1e-3)
                np.testing.assert_allclose(s, 2 * mn, rtol=1e-5, atol=1e-3)
                assert meta["frames"]["acquired"] == meta["frames"]["folded"] + meta["frames"]["dropped"]
                try:
                    c.capture(phases=1)
                    raise AssertionError("phases=1 accepted")
                except DescatterError as e:
                    assert e.code == "bad_argument" and "phases" in e.message, e
                meta16, im16 = c.capture(phases=4, format="u16")
                assert im16["transmissive"].dtype == np.dtype("<u2")
            with Client(sock) as sub, Client(sock) as ctl:
                ctl.call("start", phases=4)
                seqs = []
                stream = sub.results()
                for _ in range(3):
                    body, images = next(stream)
                    seqs.append(body["set_id"])
                    assert set(images) == {"transmissive", "scattered", "mask"}
                ctl.call("stop")
                assert seqs == sorted(seqs) and len(set(seqs)) == 3, seqs
        finally:
            proc.terminate()
            assert proc.wait(30) == 0, "descatterd did not exit cleanly"
    print("python client: ok")


if __name__ == "__main__":
    main()
