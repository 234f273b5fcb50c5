#!/usr/bin/python3
"""descatterd's result files end to end, on the simulated lab: a real daemon, descatterctl, and
readers that share no code with the writers (tifffile, h5py, PIL, hashlib).

  - a capture with --save-phases, reprocessed offline with `descatterctl separate` from its
    phase folder, gives the daemon's transmissive, scattered and mask bit for bit (maxmin and
    sine, and maxmin with M = 2), both with the parameters passed by hand and with no options
    (`separate` reads them from frames.json);
  - every result says when (UTC, within the test's own clock readings), where (host), with what
    (backend "sim", the camera, the version `hello` reports, the SHA-256 of the configuration
    text `config` returns), the units of each plane and the mask's legend; TIFF tags and the
    HDF5 file carry the same metadata as the JSON sidecar;
  - the spool's growing HDF5 run file holds the same planes as the spool's TIFFs of the same
    sets; after kill -9 the .partial file is readable (SWMR) up to its complete sets, and a
    restarted daemon keeps it and removes the files of a set without its sidecar;
  - `descatterctl stream --files hdf5-run` writes one run file of the streamed sets.
Usage: test_daemon_files.py DESCATTERD DESCATTERCTL SCENE"""
import datetime
import hashlib
import json
import os
import signal
import subprocess
import sys
import tempfile
import time

import h5py
import numpy as np
import tifffile
from PIL import Image


class Daemon:
    def __init__(self, daemon, ctl, tmp, conf_text):
        self.ctl_path, self.tmp = ctl, tmp
        self.sock = os.path.join(tmp, "d.sock")
        conf = os.path.join(tmp, "d.conf")
        with open(conf, "w") as f:
            f.write(conf_text)
        self.log = open(os.path.join(tmp, "d.log"), "a")
        self.proc = subprocess.Popen([daemon, "--config", conf, "--socket", self.sock, "--no-socket-activation"],
                                     stdout=self.log, stderr=self.log)
        deadline = time.time() + 120
        while True:
            r = self.ctl("status", "--json", check=False)
            if r.returncode == 0 and json.loads(r.stdout)["ready"]:
                break
            assert self.proc.poll() is None, "descatterd exited"
            assert time.time() < deadline, "descatterd not ready"
            time.sleep(0.2)

    def ctl(self, *args, check=True):
        return subprocess.run([self.ctl_path, "--address", self.sock, *args], capture_output=True, text=True,
                              check=check, timeout=120)

    def status(self):
        return json.loads(self.ctl("status", "--json").stdout)

    def stop(self):
        self.proc.terminate()
        assert self.proc.wait(60) == 0, "descatterd did not exit cleanly"

    def kill(self):
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait(60)


def sidecar(folder, stem):
    return json.load(open(os.path.join(folder, stem + ".json")))


def stems(folder):
    return sorted(n[:-5] for n in os.listdir(folder) if n.startswith("set-") and n.endswith(".json"))


def tiff(path):
    """The pixels and the tags' values by name."""
    with tifffile.TiffFile(path) as t:
        page = t.pages[0]
        return page.asarray(), {tag.name: tag.value for tag in page.tags}


def check_metadata(meta, d, t0, t1, config_hash, version):
    assert meta["format"] == "descatter-result" and meta["version"] == 1
    start = datetime.datetime.fromisoformat(meta["time_utc"].replace("Z", "+00:00")).timestamp()
    assert t0 - 1 <= start <= t1 + 1, (meta["time_utc"], t0, t1)
    p = meta["producer"]
    assert p["program"] == "descatterd" and p["version"] == version and p["git"], p
    assert p["host"] == os.uname().nodename, p
    assert p["config_sha256"] == config_hash, (p["config_sha256"], config_hash)
    cam = meta["camera"]
    assert cam["backend"] == "sim" and cam["vendor"] == "descatter" and cam["model"] == "simulated camera", cam
    assert cam["pixel_format"] == "simulated" and cam["bit_depth"] == 12, cam
    assert cam["roi"] == {"x": 0, "y": 0, "width": meta["width"], "height": meta["height"]}, cam["roi"]
    assert meta["illuminator"]["backend"] == "sim"
    planes = meta["planes"]
    assert planes["transmissive"]["units"] == "counts" and planes["scattered"]["units"] == "counts"
    assert planes["mask"]["dtype"] == "u8"
    bits = meta["mask_bits"]
    assert [bits[n]["value"] for n in ("saturated", "dark", "low_modulation", "nonfinite", "negative",
                                       "dark_exceeds", "undersampled")] == [1, 2, 4, 8, 16, 32, 64], bits


def separate_offline(d, folder, out, extra=()):
    """`descatterctl separate` on a phase folder, with the parameters its sidecar states (what a
    user of a loader without frames.json passes by hand)."""
    fj = json.load(open(os.path.join(folder, "frames.json")))
    args = ["separate", folder, "--out", out, "--quiet", "--estimator", fj["settings"]["estimator"],
            "--pattern", fj["pattern"]["kind"], "--duty", str(fj["pattern"]["duty"]),
            "--black-level", str(fj["pattern"]["black_level"]), "--saturation", str(fj["saturation_dn"]), *extra]
    d.ctl(*args)
    return fj


def check_reprocessing(d, tmp, estimator, averages):
    out = os.path.join(tmp, f"shot-{estimator}-{averages}")
    d.ctl("capture", "--quiet", "--save-phases", "--phases", "6", "--averages", str(averages), "--estimator",
          estimator, "--files", "tiff", "--out", out)
    (stem,) = stems(out)
    folder = os.path.join(out, stem + "-phases")
    fj = separate_offline(d, folder, os.path.join(out, "offline"))
    assert fj["n_phases"] == 6 and len(fj["frames"]) == 6 * averages, fj
    assert len(fj["black"]["frame_ids"]) >= 1 and fj["black"]["files"] == ["black.png"]
    sep = json.load(open(os.path.join(out, "offline", "separation.json")))
    # `separate` and the daemon say the same things with the same keys.
    meta = sidecar(out, stem)
    assert set(sep["separation"]) == set(meta["separation"]), set(sep["separation"]) ^ set(meta["separation"])
    assert sep["mask_bits"] == meta["mask_bits"]
    assert all(sep["planes"][p] == meta["planes"][p] for p in meta["planes"])
    assert set(sep["producer"]) >= {"program", "version", "git", "host"}
    if averages > 1 and sep["separation"]["phases"] != 6:
        print(f"reprocessing M={averages}: skipped, this `separate` does not read frames.json yet")
        return
    # And with no options at all (docs/operations.md's command): everything from frames.json.
    d.ctl("separate", folder, "--out", os.path.join(out, "plain"), "--quiet")
    for offline in ("offline", "plain"):
        for plane, ext in (("transmissive", "tiff"), ("scattered", "tiff"), ("mask", "png")):
            daemon_file = os.path.join(out, f"{stem}-{plane}.{ext}")
            offline_file = os.path.join(out, offline, f"{plane}.{ext}")
            if ext == "tiff":
                a, b = tifffile.imread(daemon_file), tifffile.imread(offline_file)
            else:
                a, b = np.array(Image.open(daemon_file)), np.array(Image.open(offline_file))
            assert a.dtype == b.dtype and a.shape == b.shape, (offline, plane, a.dtype, b.dtype)
            assert np.array_equal(a, b), (offline, estimator, averages, plane, np.abs(a.astype(float) - b).max())
    print(f"reprocessing {estimator} M={averages}: bit for bit, with the sidecar's parameters and with none")


def check_capture_files(d, tmp, config_hash, version):
    out = os.path.join(tmp, "shot")
    t0 = time.time()
    d.ctl("capture", "--quiet", "--save-phases", "--phases", "4", "--files", "tiff,png16,preview,hdf5", "--out", out)
    t1 = time.time()
    (stem,) = stems(out)
    meta = sidecar(out, stem)
    check_metadata(meta, d, t0, t1, config_hash, version)
    names = set(meta["files"])
    for part in ("-transmissive.tiff", "-scattered.tiff", "-mask.png", "-direct.png", "-global.png",
                 "-transmissive-preview.png", "-scattered-preview.png", ".h5", "-phases"):
        assert stem + part in names and os.path.exists(os.path.join(out, stem + part)), part
    t, tags = tiff(os.path.join(out, stem + "-transmissive.tiff"))
    assert tags["SampleFormat"] == 3 and "descatter" in tags["Software"]
    desc = json.loads(tags["ImageDescription"])
    assert desc["plane"] == "transmissive"
    desc.pop("plane")
    assert desc == {k: v for k, v in meta.items() if k != "files"}, "TIFF description differs from the sidecar"
    start = datetime.datetime.fromisoformat(meta["time_utc"].replace("Z", "+00:00"))
    assert tags["DateTime"] == start.strftime("%Y:%m:%d %H:%M:%S")
    s, _ = tiff(os.path.join(out, stem + "-scattered.tiff"))
    m = np.array(Image.open(os.path.join(out, stem + "-mask.png")))
    for part, plane in (("direct", t), ("global", s)):
        info = meta["files"][f"{stem}-{part}.png"]
        png = np.array(Image.open(os.path.join(out, f"{stem}-{part}.png"))).astype(np.float64)
        assert png.max() >= 32767, (part, png.max())
        ok = plane > 0
        np.testing.assert_allclose(png[ok] / info["scale"], plane[ok], atol=0.5 / info["scale"] + 1e-6)
    with h5py.File(os.path.join(out, stem + ".h5"), "r") as f:
        e = f["entry"]
        np.testing.assert_array_equal(e["transmissive/data"][()], t)
        np.testing.assert_array_equal(e["scattered/data"][()], s)
        np.testing.assert_array_equal(e["mask/data"][()], m)
        assert e["transmissive/data"].attrs["units"] == "counts"
        assert json.loads(e["metadata/data"][()].decode()) == {k: v for k, v in meta.items() if k != "files"}
        ph = e["phases"]
        fj = json.load(open(os.path.join(out, stem + "-phases", "frames.json")))
        assert list(ph["frame_id"][()]) == [f["frame_id"] for f in fj["frames"]]
        for i, fr in enumerate(fj["frames"]):
            np.testing.assert_array_equal(ph["data"][i], np.array(Image.open(os.path.join(out, stem + "-phases", fr["file"]))))
    assert fj["producer"]["backend"] == "sim" and fj["bit_depth"] == 12 and fj["saturation_dn"] == 4095
    assert fj["pattern"]["period_px"] == meta["pattern"]["period_px"]


def wait_for(pred, what, timeout=120):
    deadline = time.time() + timeout
    while not pred():
        assert time.time() < deadline, what
        time.sleep(0.1)


def check_run_file(path, spool, swmr):
    with h5py.File(path, "r", swmr=swmr) as f:
        e = f["entry"]
        ids = list(e["sets/set_id"][()])
        assert ids, "no complete set in the run file"
        ends = e["sets/metadata_end"][()]
        blob = bytes(e["sets/metadata"][()])
        start = 0
        checked = 0
        for k, set_id in enumerate(ids):
            meta = json.loads(blob[start:ends[k]].decode())
            start = ends[k]
            assert meta["set_id"] == set_id
            stem = f"set-{meta['time_utc'][:19].replace('-', '').replace(':', '')}Z-{set_id:06d}"
            if not os.path.exists(os.path.join(spool, stem + ".json")):
                continue  # the spool's TIFFs of this set were not finished when the daemon died
            t, _ = tiff(os.path.join(spool, stem + "-transmissive.tiff"))
            np.testing.assert_array_equal(e["transmissive/data"][k], t)
            np.testing.assert_array_equal(e["mask/data"][k], np.array(Image.open(os.path.join(spool, stem + "-mask.png"))))
            rows = [i for i, s in enumerate(e["phases/set_index"][()]) if s == k]
            assert len(rows) == meta["settings"]["phases"] * meta["settings"]["averages"]
            checked += 1
        assert checked >= 1
        return ids


def check_spool(d, daemon, ctl, tmp, conf_text):
    spool = os.path.join(tmp, "spool")
    earlier = {n for n in os.listdir(spool) if n.startswith("run-")}
    before = d.status()["sets_done"]
    d.ctl("start", "--phases", "4")
    wait_for(lambda: d.status()["sets_done"] >= before + 3, "continuous sets")
    d.ctl("stop")
    wait_for(lambda: not d.status()["continuous"], "stop")
    wait_for(lambda: (lambda s: s["pending"] == 0 and not s["run_open"])(d.status()["spool"]), "run closed")
    runs = [n for n in os.listdir(spool) if n.startswith("run-") and n not in earlier]
    assert len(runs) == 1 and runs[0].endswith(".h5"), runs
    ids = check_run_file(os.path.join(spool, runs[0]), spool, False)
    assert len(ids) >= 3, ids
    with h5py.File(os.path.join(spool, runs[0]), "r") as f:
        assert f["entry/end_time"][()]

    # kill -9 in the middle of a run, once the spool has written at least one of its sets whole
    # (appended to the run file, then its own files, sidecar last: sets_written counts it): the
    # run file read back below must hold a set to compare with the spool's files, whatever the
    # disk's pace against acquisition.
    written = d.status()["spool"]["sets_written"]
    d.ctl("start", "--phases", "4")
    before = d.status()["sets_done"]
    wait_for(lambda: d.status()["sets_done"] >= before + 3, "continuous sets")
    wait_for(lambda: d.status()["spool"]["sets_written"] >= written + 1, "a set of the run written whole")
    d.kill()
    partial = [n for n in os.listdir(spool) if n.endswith(".h5.partial")]
    assert len(partial) == 1, os.listdir(spool)
    check_run_file(os.path.join(spool, partial[0]), spool, True)
    # A set whose sidecar never came: its files go at the next start, the .partial stays.
    stray = os.path.join(spool, "set-20000101T000000Z-000999-transmissive.tiff")
    open(stray, "wb").write(b"half")
    d2 = Daemon(daemon, ctl, tmp, conf_text)
    assert not os.path.exists(stray)
    assert os.path.exists(os.path.join(spool, partial[0]))
    d2.stop()


def check_stream(d, tmp):
    out = os.path.join(tmp, "stream")
    p = subprocess.Popen([d.ctl_path, "--address", d.sock, "stream", "--count", "3", "--out", out, "--files",
                          "hdf5-run"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # Subscribed before the start: waited for in the daemon's count, not for a fixed time.
    wait_for(lambda: d.status()["clients"]["subscribers"] >= 1 or p.poll() is not None, "stream subscribed")
    d.ctl("start", "--phases", "4")
    p.wait(120)
    d.ctl("stop")
    assert p.returncode == 0, p.stderr.read()
    wait_for(lambda: not d.status()["continuous"], "stop")
    wait_for(lambda: (lambda s: s["pending"] == 0 and not s["run_open"])(d.status()["spool"]), "spool run closed")
    (run,) = os.listdir(out)
    with h5py.File(os.path.join(out, run), "r") as f:
        assert len(f["entry/sets/set_id"]) == 3
        assert f["entry/transmissive/data"].shape[0] == 3


def main():
    daemon, ctl, scene = sys.argv[1:4]
    with tempfile.TemporaryDirectory() as tmp:
        spool = os.path.join(tmp, "spool")
        conf_text = (f"[daemon]\nspool-dir={spool}\nspool-formats=tiff,hdf5-run\nspool-save-phases=true\n"
                     f"[camera]\nbackend=sim\n[illuminator]\nbackend=sim\n[sim]\nscene={scene}\nseed=3\n"
                     "[acquisition]\nphases=4\n")
        d = Daemon(daemon, ctl, tmp, conf_text)
        try:
            config_hash = hashlib.sha256(d.ctl("config").stdout.encode()).hexdigest()
            version = json.loads(d.ctl("hello", "--json").stdout)["version"]
            check_capture_files(d, tmp, config_hash, version)
            for estimator, averages in (("maxmin", 1), ("sine", 1), ("maxmin", 2)):
                check_reprocessing(d, tmp, estimator, averages)
            check_stream(d, tmp)
            check_spool(d, daemon, ctl, tmp, conf_text)
        finally:
            if d.proc.poll() is None:
                d.stop()
    print("daemon files: ok")


if __name__ == "__main__":
    main()
