#!/usr/bin/python3
"""The physical scale and self-describing files of a running descatterd, read by third-party
readers that share no code with the writers (silx, h5py, tifffile, Pillow, and a PNG chunk
parser written here with struct and zlib):

  - every NXdata group of a per-set HDF5 file and of the spool's growing run file passes silx's
    validation (silx.io.nxdata.is_valid_nxdata), and silx.io.nxdata.get_default follows
    @default from the file to a plottable image in both; signals and axes carry units and long
    names; bit_depth_readout and the *_indices attributes are integers;
  - the object-plane pixel size is the same in the NeXus x/y axes (µm), the TIFF resolution tags
    (pixels per centimetre) and the JSON (pixel_size_um), and equals the pixel pitch over the
    magnification: both configured; the pitch from the camera (the simulated camera reports the
    scene's sensor pitch, read here from the scene file) and the magnification configured; or,
    with no magnification, unknown everywhere: pixel_size_um null with the reason, index axes
    in pixels, no TIFF resolution;
  - the 16-bit direct/global PNGs carry their scale and units in tEXt chunks and sBIT = 16 -
    log2(scale), and file value / scale gives the TIFF's counts.
Usage: test_daemon_nexus.py DESCATTERD DESCATTERCTL SCENE"""
import configparser
import math
import os
import struct
import sys
import tempfile
import zlib

import h5py
import numpy as np
import tifffile
from PIL import Image
from silx.io import nxdata

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from test_daemon_files import Daemon, sidecar, stems, wait_for  # noqa: E402


def scene_pitch_um(scene):
    """The scene's sensor pixel pitch, from its [sensor] section (docs/scene-format.md)."""
    cp = configparser.ConfigParser(inline_comment_prefixes=("#", ";"))
    cp.read(scene)
    return float(cp["sensor"]["pixel-pitch-um"])


def nxdata_groups(f):
    found = []

    def visit(name, obj):
        if isinstance(obj, h5py.Group) and obj.attrs.get("NX_class") in ("NXdata", b"NXdata"):
            found.append(name)
    f.visititems(visit)
    return found


def text(v):
    return v.decode() if isinstance(v, bytes) else str(v)


def check_nexus(path, pixel_um, stack):
    """silx's validity of every NXdata, the default plot, axes in µm (or indices), units."""
    with h5py.File(path, "r") as f:
        groups = nxdata_groups(f)
        assert {"entry/transmissive", "entry/scattered", "entry/mask", "entry/phases"} <= set(groups), groups
        for name in groups:
            g = f[name]
            assert nxdata.is_valid_nxdata(g), (path, name, nxdata.NXdata(g).issues)
            nxd = nxdata.NXdata(g)
            sig = nxd.signal
            assert "units" in sig.attrs and text(sig.attrs["long_name"]), (name, dict(sig.attrs))
            ndim = sig.ndim
            assert ndim == 3 if stack or name.endswith("phases") else ndim == 2, (name, sig.shape)
            axes = [text(a) for a in g.attrs["axes"]]
            assert len(axes) == ndim and axes[-2:] == ["y", "x"], (name, axes)
            for ax_name, dim in (("y", ndim - 2), ("x", ndim - 1)):
                idx = g.attrs[f"{ax_name}_indices"]
                assert np.issubdtype(np.asarray(idx).dtype, np.integer) and int(idx) == dim, (name, ax_name, idx)
                ax = g[ax_name]
                n = sig.shape[dim]
                assert ax.shape == (n,), (name, ax_name, ax.shape, n)
                if pixel_um is None:
                    assert text(ax.attrs["units"]) == "pixel" and "unknown" in text(ax.attrs["long_name"])
                    np.testing.assert_array_equal(ax[()], np.arange(n))
                else:
                    assert text(ax.attrs["units"]) == "um", (name, dict(ax.attrs))
                    np.testing.assert_allclose(ax[()], np.arange(n) * pixel_um, rtol=1e-12)
            if name.endswith("phases"):
                assert axes[0] == "frame_id" and int(g.attrs["frame_id_indices"]) == 0
                assert g["frame_id"].shape == (sig.shape[0],)
            elif stack:
                assert axes[0] == ".", axes
        # @default: root -> entry -> transmissive, and silx follows it to an image.
        assert text(f.attrs["default"]) == "entry" and text(f["entry"].attrs["default"]) == "transmissive"
        d = nxdata.get_default(f)
        assert d is not None and d.group.name == "/entry/transmissive", d
        assert d.is_image and d.interpretation == "image", (d.interpretation, d.signal.shape)
        cam = f["entry/instrument/camera"]
        assert cam["bit_depth_readout"].dtype.kind in "iu" and cam["bit_depth_readout"][()] == 12
        # NXdetector's saturation_value is NX_INT: the 12-bit sensor clips at 2^12 - 1.
        assert cam["saturation_value"].dtype.kind in "iu" and cam["saturation_value"][()] == 4095
        return d


def png_chunks(path):
    """(type, data) of every chunk, checking each CRC: an independent PNG reader."""
    raw = open(path, "rb").read()
    assert raw[:8] == b"\x89PNG\r\n\x1a\n"
    pos, out = 8, []
    while pos < len(raw):
        (n,) = struct.unpack(">I", raw[pos:pos + 4])
        kind, data = raw[pos + 4:pos + 8], raw[pos + 8:pos + 8 + n]
        (crc,) = struct.unpack(">I", raw[pos + 8 + n:pos + 12 + n])
        assert zlib.crc32(kind + data) == crc, (path, kind)
        out.append((kind.decode(), data))
        pos += 12 + n
    return out


def check_png16(out, stem, meta, planes):
    for part, plane in (("direct", "transmissive"), ("global", "scattered")):
        name = f"{stem}-{part}.png"
        scale = meta["files"][name]["scale"]
        chunks = png_chunks(os.path.join(out, name))
        kinds = [k for k, _ in chunks]
        ihdr = dict(chunks)["IHDR"]
        assert ihdr[8] == 16 and ihdr[9] == 0, "not 16-bit grey"
        (sbit,) = [d for k, d in chunks if k == "sBIT"]
        k = math.log2(scale)
        assert k == int(k), scale
        assert len(sbit) == 1 and sbit[0] == 16 - max(int(k), 0), (name, sbit[0], scale)
        assert kinds.index("sBIT") < kinds.index("IDAT")
        texts = dict(d.split(b"\0", 1) for kk, d in chunks if kk == "tEXt")
        assert float(texts[b"descatter:scale"]) == scale, texts
        assert texts[b"descatter:units"] == b"counts" and texts[b"Title"] == plane.encode(), texts
        im = Image.open(os.path.join(out, name))
        assert float(im.text["descatter:scale"]) == scale  # Pillow reads the same text
        png = np.array(im).astype(np.float64)
        ok = planes[plane] > 0
        np.testing.assert_allclose(png[ok] / scale, planes[plane][ok], atol=0.5 / scale + 1e-6)
        # sBIT's promise: shifting right by 16 - sBIT gives whole counts.
        shifted = np.array(im).astype(np.uint32) >> (16 - sbit[0])
        if k >= 0:
            assert np.all(np.abs(shifted[ok] - planes[plane][ok]) <= 1.0), name


def tiff_resolution(path):
    with tifffile.TiffFile(path) as t:
        tags = {tag.name: tag.value for tag in t.pages[0].tags}
        return t.pages[0].asarray(), tags


def check_set(d, tmp, label, pixel_um):
    out = os.path.join(tmp, f"shot-{label}")
    d.ctl("capture", "--quiet", "--save-phases", "--phases", "4", "--files", "tiff,png16,hdf5", "--out", out)
    (stem,) = stems(out)
    meta = sidecar(out, stem)
    if pixel_um is None:
        assert meta["pixel_size_um"] is None and meta["pixel_size_note"].startswith("unknown"), meta
        assert "magnification" in meta["pixel_size_note"], meta["pixel_size_note"]
    else:
        assert math.isclose(meta["pixel_size_um"], pixel_um, rel_tol=1e-12), (meta["pixel_size_um"], pixel_um)
    planes = {}
    for plane in ("transmissive", "scattered"):
        img, tags = tiff_resolution(os.path.join(out, f"{stem}-{plane}.tiff"))
        planes[plane] = img
        if pixel_um is None:
            assert "XResolution" not in tags and "YResolution" not in tags, tags.keys()
        else:
            assert tags["ResolutionUnit"] == 3, tags["ResolutionUnit"]  # centimetre
            for key in ("XResolution", "YResolution"):
                num, den = tags[key]
                np.testing.assert_allclose(1e4 / (num / den), pixel_um, rtol=1e-6)
    check_png16(out, stem, meta, planes)
    check_nexus(os.path.join(out, stem + ".h5"), pixel_um, stack=False)
    with h5py.File(os.path.join(out, stem + ".h5"), "r") as f:
        cam = f["entry/instrument/camera"]
        pitch = meta["optics"]["sensor_pixel_pitch_um"]
        if pitch is not None:
            assert math.isclose(cam["x_pixel_size"][()], pitch) and text(cam["x_pixel_size"].attrs["units"]) == "um"
    print(f"{label}: set files ok (pixel size {pixel_um} um)")
    return meta


def check_run(d, tmp, pixel_um):
    spool = os.path.join(tmp, "spool")
    d.ctl("start", "--phases", "4")
    before = d.status()["sets_done"]
    wait_for(lambda: d.status()["sets_done"] >= before + 2, "continuous sets")
    d.ctl("stop")
    wait_for(lambda: not d.status()["continuous"], "stop")
    wait_for(lambda: (lambda s: s["pending"] == 0 and not s["run_open"])(d.status()["spool"]), "run closed")
    (run,) = [n for n in os.listdir(spool) if n.startswith("run-") and n.endswith(".h5")]
    check_nexus(os.path.join(spool, run), pixel_um, stack=True)
    print(f"run file ok (pixel size {pixel_um} um)")


def conf(tmp, scene, extra_camera="", optics=""):
    spool = os.path.join(tmp, "spool")
    return (f"[daemon]\nspool-dir={spool}\nspool-formats=hdf5-run\nspool-save-phases=true\n"
            f"[camera]\nbackend=sim\n{extra_camera}[optics]\n{optics}[illuminator]\nbackend=sim\n"
            f"[sim]\nscene={scene}\nseed=3\n[acquisition]\nphases=4\n")


def run_case(daemon, ctl, scene, label, extra_camera, optics, pixel_um, with_run):
    with tempfile.TemporaryDirectory() as tmp:
        d = Daemon(daemon, ctl, tmp, conf(tmp, scene, extra_camera, optics))
        try:
            meta = check_set(d, tmp, label, pixel_um)
            if with_run:
                check_run(d, tmp, pixel_um)
        finally:
            if d.proc.poll() is None:
                d.stop()
        return meta


def main():
    daemon, ctl, scene = sys.argv[1:4]
    # Pitch and magnification configured: 6.5 µm / 0.13 = 50 µm on the object.
    meta = run_case(daemon, ctl, scene, "configured", "pixel-pitch-um=6.5\n", "magnification=0.13\n",
                    6.5 / 0.13, True)
    assert meta["optics"] == {"sensor_pixel_pitch_um": 6.5, "pitch_source": "config", "magnification": 0.13}
    # The pitch from the camera (the simulated sensor's), the magnification configured.
    pitch = scene_pitch_um(scene)
    meta = run_case(daemon, ctl, scene, "camera-pitch", "", "magnification=0.04\n", pitch / 0.04, False)
    assert meta["optics"]["pitch_source"] == "camera" and meta["optics"]["sensor_pixel_pitch_um"] == pitch
    # No magnification: no physical scale anywhere, and the files say so.
    meta = run_case(daemon, ctl, scene, "unknown", "", "", None, True)
    assert meta["optics"]["magnification"] is None
    print("daemon nexus: ok")


if __name__ == "__main__":
    main()
