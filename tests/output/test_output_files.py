#!/usr/bin/python3
"""Result files read back with readers that share no code with descatter's writers: tifffile
(TIFF tags), h5py (NeXus HDF5, the growing SWMR run file, also after kill -9) and PIL (16-bit
PNG). The expected values come from the closed forms of tests/output/sample_result.h, computed
here again. Usage: test_output_files.py WRITE_SAMPLE"""
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

W, H, PHASES = 24, 10, 4


def expected(set_):
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    t = (1000 + 10 * x + y + set_ / 4).astype(np.float32)
    s = (200 + 3 * x + 2 * y + set_).astype(np.float32)
    m = ((x + 2 * y + set_) % 64).astype(np.uint8)
    phases = [(100 + x + 10 * k + set_ + y % 2).astype(np.uint16) for k in range(PHASES)]
    black = (50 + (x + y) % 3).astype(np.uint16)
    return t, s, m, phases, black


def stem(set_):
    return f"set-20260102T0304{set_ % 60:02d}Z-{set_ + 1:06d}"


def check_tiff(path, plane, want, set_):
    with tifffile.TiffFile(path) as tif:
        page = tif.pages[0]
        assert page.dtype == np.float32, page.dtype
        tags = page.tags
        assert tags["SampleFormat"].value == 3, tags["SampleFormat"].value  # IEEE float
        assert tags["BitsPerSample"].value == 32
        assert "descatter" in tags["Software"].value, tags["Software"].value
        assert tags["DateTime"].value == f"2026:01:02 03:04:{set_ % 60:02d}", tags["DateTime"].value
        meta = json.loads(tags["ImageDescription"].value)
        assert meta["set_id"] == set_ + 1 and meta["plane"] == plane, meta
        assert meta["camera"]["serial"] == f"S{set_}"
        np.testing.assert_array_equal(page.asarray(), want)


def check_files(tool, tmp):
    out = os.path.join(tmp, "files")
    subprocess.run([tool, "files", out, "tiff,png16,preview,hdf5", "2"], check=True)
    for set_ in range(2):
        t, s, m, phases, black = expected(set_)
        st = stem(set_)
        side = json.load(open(os.path.join(out, st + ".json")))
        assert side["set_id"] == set_ + 1
        check_tiff(os.path.join(out, st + "-transmissive.tiff"), "transmissive", t, set_)
        check_tiff(os.path.join(out, st + "-scattered.tiff"), "scattered", s, set_)
        check_tiff(os.path.join(out, st + "-mean.tiff"), "mean", (t + s) / 2, set_)
        np.testing.assert_array_equal(np.array(Image.open(os.path.join(out, st + "-mask.png"))), m)
        # 16-bit PNG: file value = round(value * scale), scale recorded in the sidecar.
        for part, plane in (("direct", t), ("global", s)):
            name = f"{st}-{part}.png"
            scale = side["files"][name]["scale"]
            png = np.array(Image.open(os.path.join(out, name))).astype(np.float64)
            assert png.max() >= 32767, (name, png.max())  # visible: the top half of the range
            np.testing.assert_allclose(png / scale, plane, atol=0.5 / scale + 1e-9)
        # NeXus HDF5.
        with h5py.File(os.path.join(out, st + ".h5"), "r") as f:
            assert f.attrs["NX_class"] == "NXroot" and f.attrs["default"] == "entry"
            e = f["entry"]
            assert e.attrs["NX_class"] == "NXentry" and e.attrs["default"] == "transmissive"
            assert e["start_time"][()].decode() == side["time_utc"]
            for name, want in (("transmissive", t), ("scattered", s), ("mask", m), ("mean", (t + s) / 2)):
                g = e[name]
                assert g.attrs["NX_class"] == "NXdata" and g.attrs["signal"] == "data", name
                d = g["data"]
                np.testing.assert_array_equal(d[()], want)
                assert d.attrs["long_name"], name
                assert d.attrs["units"] == ("" if name == "mask" else "counts"), name
            assert list(e["mask/data"].attrs["flag_masks"]) == [1, 2, 4, 8, 16, 32, 64, 128]
            assert e["mask/data"].attrs["flag_meanings"].split()[0] == "saturated"
            assert e["mask/data"].attrs["flag_meanings"].split()[-1] == "motion"
            ph = e["phases"]
            np.testing.assert_array_equal(ph["data"][()], np.stack(phases))
            assert list(ph["phase"][()]) == list(range(PHASES))
            assert list(ph["frame_id"][()]) == [1000 * set_ + k for k in range(PHASES)]
            np.testing.assert_array_equal(ph["black"][()], black)
            cam = e["instrument/camera"]
            assert cam.attrs["NX_class"] == "NXdetector"
            assert cam["serial_number"][()].decode() == f"S{set_}"
            assert cam["count_time"].attrs["units"] == "us" and cam["count_time"][()] == 1500
            note = json.loads(e["metadata/data"][()].decode())
            assert note["set_id"] == set_ + 1 and note["camera"]["model"] == "M"
        # Phase folder.
        pf = os.path.join(out, st + "-phases")
        fj = json.load(open(os.path.join(pf, "frames.json")))
        assert fj["n_phases"] == PHASES and fj["bit_depth"] == 12 and fj["saturation_dn"] == 4095
        for k, fr in enumerate(fj["frames"]):
            np.testing.assert_array_equal(np.array(Image.open(os.path.join(pf, fr["file"]))), phases[k])
        np.testing.assert_array_equal(np.array(Image.open(os.path.join(pf, "black.png"))), black)
    assert not [n for n in os.listdir(out) if n.startswith(".")], os.listdir(out)


def check_run_file(path, n):
    with h5py.File(path, "r", swmr=True) as f:
        e = f["entry"]
        ids = e["sets/set_id"][()]
        assert len(ids) == n, (len(ids), n)
        assert list(ids) == [k + 1 for k in range(n)], ids
        ends = e["sets/metadata_end"][()]
        blob = bytes(e["sets/metadata"][()])
        start = 0
        for k in range(n):
            t, s, m, phases, black = expected(k)
            np.testing.assert_array_equal(e["transmissive/data"][k], t)
            np.testing.assert_array_equal(e["scattered/data"][k], s)
            np.testing.assert_array_equal(e["mask/data"][k], m)
            meta = json.loads(blob[start:ends[k]].decode())
            start = ends[k]
            assert meta["set_id"] == k + 1
            assert e["sets/time_utc"][k].decode() == meta["time_utc"]
            # Sets 0, 2, ... carried raw frames; the others did not.
            idx = e["phases/set_index"][()]
            rows = [i for i in range(len(idx)) if idx[i] == k]
            if k % 2 == 0:
                assert len(rows) == PHASES
                for j, r in enumerate(rows):
                    np.testing.assert_array_equal(e["phases/data"][r], phases[j])
                assert e["phases/has_black"][k] == 1
                np.testing.assert_array_equal(e["phases/black"][k], black)
            else:
                assert rows == [] and e["phases/has_black"][k] == 0


def check_run(tool, tmp):
    path = os.path.join(tmp, "run.h5")
    subprocess.run([tool, "run", path, "5"], check=True)
    assert not os.path.exists(path + ".partial")
    check_run_file(path, 5)
    with h5py.File(path, "r") as f:
        assert f["entry/end_time"][()].decode() == "2026-01-02T03:04:04.006Z"

    # kill -9 after 3 sets: the .partial stays, readable in SWMR mode, with 3 whole sets.
    path = os.path.join(tmp, "crash.h5")
    p = subprocess.Popen([tool, "run", path, "3", "hang"], stdout=subprocess.PIPE, text=True)
    for line in p.stdout:
        if line.strip() == "appended 3":
            break
    os.kill(p.pid, signal.SIGKILL)
    p.wait()
    assert not os.path.exists(path)
    check_run_file(path + ".partial", 3)


def check_killed_writer(tool, tmp):
    """kill -9 while sets are being written, three times at different moments: every file under
    its final name is whole (HDF5 opens with all its planes, TIFFs read back in full), every set
    with a sidecar has all its files; what the kill interrupted is only under hidden temporary
    names."""
    for round_, delay in enumerate((0.0, 0.013, 0.031)):
        out = os.path.join(tmp, f"killed-{round_}")
        p = subprocess.Popen([tool, "files", out, "tiff,hdf5", "100000"])
        deadline = time.time() + 60
        while len([n for n in os.listdir(out) if n.endswith(".json")] if os.path.isdir(out) else []) < 3:
            assert p.poll() is None and time.time() < deadline, "the writer did not get going"
            time.sleep(0.005)
        time.sleep(delay)
        os.kill(p.pid, signal.SIGKILL)
        p.wait()
        names = os.listdir(out)
        complete = {n[:-5] for n in names if n.endswith(".json")}
        checked = 0
        for n in names:
            if n.startswith("."):
                continue  # an interrupted temporary: a reader skips it, the spool removes it
            st = n[:len("set-20260102T030400Z-000001")]
            set_ = int(st[-6:]) - 1
            t, s, m, phases, black = expected(set_)
            path = os.path.join(out, n)
            if n.endswith(".h5"):
                with h5py.File(path, "r") as f:
                    np.testing.assert_array_equal(f["entry/transmissive/data"][()], t)
                    np.testing.assert_array_equal(f["entry/mask/data"][()], m)
                    np.testing.assert_array_equal(f["entry/phases/data"][()], np.stack(phases))
                    assert json.loads(f["entry/metadata/data"][()].decode())["set_id"] == set_ + 1
                checked += 1
            elif n.endswith("-transmissive.tiff"):
                np.testing.assert_array_equal(tifffile.imread(path), t)
            elif n.endswith(".json"):
                side = json.load(open(path))
                assert all(os.path.exists(os.path.join(out, f)) for f in side["files"]), (n, side["files"])
        assert checked >= 3 and len(complete) >= 3, (checked, len(complete))
        print(f"killed writer, round {round_}: {checked} whole HDF5 files, {len(complete)} complete sets, "
              f"{sum(n.startswith('.') for n in names)} interrupted temporaries")


def main():
    tool = sys.argv[1]
    with tempfile.TemporaryDirectory() as tmp:
        check_files(tool, tmp)
        check_run(tool, tmp)
        check_killed_writer(tool, tmp)
    print("ok")


if __name__ == "__main__":
    main()
