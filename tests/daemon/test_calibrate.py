#!/usr/bin/python3
"""The daemon's `calibrate` on the simulated rig (issue 12, "Calibration"), through descatterctl
and the Python client. Usage: test_calibrate.py BINDIR PYTHONDIR SCENE

The simulated camera looks at a clear reference (SCENE with its [illuminator] replaced by known
values: period 9.5 px, duty 0.3, black level 0.1, edge blur 1 px). The calibration measures
them from the frames (nothing tells the daemon the blur, and the period is measured unless
period_px is given). Expectations are the scene file's numbers."""
import configparser
import contextlib
import glob
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import time

BIN, PYDIR, SCENE = sys.argv[1:4]
sys.path.insert(0, PYDIR)
import descatter  # noqa: E402

CTL = os.path.join(BIN, "descatterctl")
DAEMON = os.path.join(BIN, "descatterd")
TRUTH = dict(period_px=9.5, duty=0.3, black_level=0.1, edge_blur_px=1.0)
TOLERANCE = dict(period_px=0.01, duty=0.01, black_level=0.01, edge_blur_px=0.1)
failures = []


def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what, flush=True)
    if not cond:
        failures.append(what)


def run(*args):
    return subprocess.run(list(args), capture_output=True, text=True, timeout=120)


def reference_scene(path, medium=None):
    """SCENE with the known illuminator; with medium, its [medium] replaced by that text."""
    out, in_illuminator, in_medium = [], False, False
    for line in open(SCENE).read().splitlines():
        if line.startswith("["):
            in_medium = medium is not None and line == "[medium]"
        if in_medium:
            continue
        if line.startswith("["):
            in_illuminator = line == "[illuminator]"
            out.append(line)
            if in_illuminator:
                out += ["period-px=9.5", "duty=0.3", "black-level=0.1", "edge-blur-px=1.0"]
            continue
        if in_illuminator and line.split("=")[0] in ("period-px", "duty", "black-level", "edge-blur-px"):
            continue
        out.append(line)
    with open(path, "w") as f:
        f.write("\n".join(out) + "\n" + (medium or ""))


def close_to_truth(cal, what):
    for key, want in TRUTH.items():
        got = float(cal[key])
        check(abs(got - want) <= TOLERANCE[key], f"{what}: {key} {got:.4f} (scene {want})")


def start_daemon(tmp, scene, illuminator="", sim=""):
    conf = os.path.join(tmp, "d.conf")
    with open(conf, "w") as f:
        f.write(f"[camera]\nbackend=sim\n[illuminator]\nbackend=sim\n{illuminator}[sim]\nscene={scene}\n{sim}")
    sock = os.path.join(tmp, "d.sock")
    log = open(os.path.join(tmp, "d.log"), "w")
    proc = subprocess.Popen([DAEMON, "--config", conf, "--socket", sock, "--no-socket-activation"],
                            stdout=log, stderr=subprocess.STDOUT)
    deadline = time.time() + 120
    while True:
        r = run(CTL, "-a", sock, "status", "--json")
        if r.returncode == 0 and json.loads(r.stdout)["ready"]:
            break
        if proc.poll() is not None or time.time() > deadline:
            proc.terminate()
            proc.wait(30)
            raise AssertionError("descatterd not ready")
        time.sleep(0.2)
    return proc, sock, log


def stop_daemon(tmp, proc, log):
    proc.terminate()
    rc = proc.wait(30)
    log.close()
    check(rc == 0, "descatterd exits cleanly")
    if failures:
        print(open(os.path.join(tmp, "d.log")).read()[-3000:])


@contextlib.contextmanager
def daemon_running(tmp, scene, illuminator="", sim=""):
    """start_daemon ... stop_daemon around a block; yields the socket."""
    proc, sock, log = start_daemon(tmp, scene, illuminator, sim)
    try:
        yield sock
    finally:
        stop_daemon(tmp, proc, log)


def calibrate_json(sock, what):
    """`descatterctl calibrate --json --phases 8` on the rig, checked to exit 0: the reply ({} when not)."""
    r = run(CTL, "-a", sock, "calibrate", "--json", "--phases", "8")
    check(r.returncode == 0, f"{what} --json exits 0 {r.stderr.strip()}")
    return json.loads(r.stdout) if r.returncode == 0 else {}


def illuminator_lines(text):
    """The [illuminator] section of the `# descatterd.conf` block calibrate printed."""
    block = text.split("# descatterd.conf\n", 1)[1].split("\n\n", 1)[0]
    kf = configparser.ConfigParser()
    kf.read_string(block)
    return kf["illuminator"]


# A forward-scattering medium (g 0.9) in front of the reference: part of its scattered light
# keeps the stripes and is read as black level.
MEDIUM = "[medium]\nthickness-mm=5\nmua=0.0043\nmus=0.35\ng=0.9\nn=1.33\nphotons=100000\nseed=7\n"


def scattering_reference():
    """On the rig too, calibrate says when the reference scatters (the reply's "scattering" and
    "warning", printed above the configuration lines)."""
    with tempfile.TemporaryDirectory(prefix="ds-calibrate-") as tmp:
        scene = os.path.join(tmp, "reference.scene")
        reference_scene(scene, MEDIUM)
        with daemon_running(tmp, scene) as sock:
            cal = calibrate_json(sock, "scattering reference: calibrate")
            if cal:
                check(cal["scattering"]["suspected"] and "the reference scatters" in cal.get("warning", ""),
                      f"scattering reference: suspected, with a warning ({cal['scattering']})")
                check(cal["black_level"] > 0.13, f"scattering reference: black level {cal['black_level']:.3f} "
                      "(0.1 in the scene: what the warning is for)")
            r = run(CTL, "-a", sock, "calibrate", "--phases", "8")
            check(r.returncode == 0 and "# WARNING: the reference scatters" in r.stdout
                  and "warning: the reference scatters" in r.stderr and "Calibrate on a clear reference" in r.stdout,
                  "scattering reference: the text output and stderr warn")


def sine_reference():
    """A clear reference lit by sine stripes (the lab-user trial's gen-22-02 was read as a blurred
    square with a false scattering warning): calibrate tells sine from the frames and gives sine's
    lines, no scattering warning. The sim illuminator takes its pattern from the scene, so the
    daemon expects sine here: no pattern notice (the notice on a mismatch is tested offline,
    tests/proc/test_ctl_calibrate.c /ctl-calibrate/clear-sine, through the same JSON members)."""
    with tempfile.TemporaryDirectory(prefix="ds-calibrate-") as tmp:
        scene = os.path.join(tmp, "reference.scene")
        reference_scene(scene)
        text = open(scene).read()
        check("pattern=square" in text, "the reference scene names its pattern")
        with open(scene, "w") as f:
            f.write(text.replace("pattern=square", "pattern=sine"))
        with daemon_running(tmp, scene) as sock:
            cal = calibrate_json(sock, "sine reference: calibrate")
            if cal:
                pc = cal["pattern_check"]
                check(cal["pattern"] == "sine" and pc["detected"] and pc["sine_residual"] < pc["square_residual"],
                      f"sine reference: pattern sine, told from the frames ({pc})")
                check(pc["expected"] == "sine" and "pattern_notice" not in cal,
                      "sine reference: the configured (scene's) pattern agrees: no notice")
                check(not cal["scattering"]["suspected"] and "warning" not in cal,
                      f"sine reference: no scattering warning ({cal['scattering']})")
            r = run(CTL, "-a", sock, "calibrate", "--phases", "8")
            check(r.returncode == 0 and "the reference scatters" not in r.stdout + r.stderr
                  and "\npattern=sine\n" in r.stdout and "duty=" not in r.stdout,
                  "sine reference: the text output gives sine's lines, no warning")


# A sine illuminator whose black level and blur calibrate must tell apart (issue 12: calibrate
# folded the blur into the black level, and the pattern check refused every automatic capture).
SINE = dict(period=12.0, black=0.05, blur=1.2)


def sine_scene(path, objects):
    """SCENE (clear water and a wire grid) lit by the sine illuminator; without objects, the clear
    reference calibrate wants."""
    out, section = [], None
    for line in open(SCENE).read().splitlines():
        if line.startswith("["):
            section = line
            if section.startswith("[object") and not objects:
                continue
            out.append(line)
            if section == "[illuminator]":
                out += ["pattern=sine", f"period-px={SINE['period']}", f"black-level={SINE['black']}",
                        f"edge-blur-px={SINE['blur']}", "irradiance=0.5"]
            continue
        if section == "[illuminator]" or (section or "").startswith("[object") and not objects:
            continue
        out.append(line)
    with open(path, "w") as f:
        f.write("\n".join(out) + "\n")


def read_tiff(path):
    import numpy
    import tifffile
    return numpy.asarray(tifffile.imread(path), dtype=numpy.float64)


def read_png_gray8(path):
    """An 8-bit grayscale PNG (descatterd's mask) as a numpy array: the format's own chunks,
    zlib and row filters (Debian's python3 has no PNG reader without PIL)."""
    import numpy
    import struct
    import zlib
    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", path
    pos, idat, width = 8, b"", 0
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            width, height, depth, color, _, _, interlace = struct.unpack(">IIBBBBB", body)
            assert depth == 8 and color == 0 and interlace == 0, f"{path}: not 8-bit grayscale"
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    raw = zlib.decompress(idat)
    out = numpy.zeros((height, width), dtype=numpy.uint8)
    prev = bytearray(width)
    for y in range(height):
        f, row = raw[y * (width + 1)], bytearray(raw[y * (width + 1) + 1:(y + 1) * (width + 1)])
        for x in range(width):
            a = row[x - 1] if x else 0
            b, c = prev[x], (prev[x - 1] if x else 0)
            if f == 1:
                row[x] = (row[x] + a) & 255
            elif f == 2:
                row[x] = (row[x] + b) & 255
            elif f == 3:
                row[x] = (row[x] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                row[x] = (row[x] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        out[y] = numpy.frombuffer(bytes(row), dtype=numpy.uint8)
        prev = row
    return out


def calibrate_then_capture():
    """The documented workflow end to end, on a rig whose illuminator is not what descatterd is
    configured with ([sim] geometry = config: the daemon assumes the configured pattern, the
    simulated illuminator draws the scene's sine stripes, as a real one draws its own):
    - calibrate on a clear reference with descatterd at its defaults (square stripes) says "the
      stripes are sine, not square" and measures the black level and the harmonic gain apart
      (a second set at twice the period): the scene's black level within 0.01, the harmonic gain
      within 2 % of (1 - b)/2 exp(-2 pi^2 sigma^2 / P^2) (the simulator samples a sine at the pixel
      centre);
    - its printed lines pasted into the configuration, an automatic capture with a target error
      of 0.03 on the wire grid succeeds, and its error against the simulator's noise-free truth
      is within a factor 1.5 of the error it predicted."""
    import numpy
    with tempfile.TemporaryDirectory(prefix="ds-calibrate-") as tmp:
        reference = os.path.join(tmp, "reference.scene")
        measured = os.path.join(tmp, "grid.scene")
        sine_scene(reference, objects=False)
        sine_scene(measured, objects=True)
        with daemon_running(tmp, reference, "period-px=12\n", "geometry=config\n") as sock:
            r = run(CTL, "-a", sock, "calibrate", "--phases", "8")
            check(r.returncode == 0, f"workflow: calibrate exits 0 {r.stderr.strip()}")
            text = r.stdout
            check("# NOTE: the stripes are sine, not square" in text and "Configure pattern=sine" in text
                  and "warning: the stripes are sine, not square" in r.stderr,
                  "workflow: configured square, stripes are sine: the notice, in the output and on stderr")
            check("assumed" not in text and "from the contrast at two periods" in text,
                  "workflow: the black level is measured at two periods, not assumed")
        if r.returncode != 0:
            return
        ill = illuminator_lines(text)
        b, h = float(ill["black-level"]), float(ill["harmonic-gain"])
        want_h = (1 - SINE["black"]) / 2 * math.exp(-2 * math.pi ** 2 * SINE["blur"] ** 2 / SINE["period"] ** 2)
        check(ill["pattern"] == "sine" and abs(b - SINE["black"]) <= 0.01,
              f"workflow: pattern={ill['pattern']} black-level={b:.4f} (illuminator {SINE['black']})")
        check(abs(h / want_h - 1) <= 0.02, f"workflow: harmonic-gain={h:.4f} (closed form {want_h:.4f})")

        truth = os.path.join(tmp, "truth")
        r = run(os.path.join(BIN, "descatter-sim"), "render", measured, "-n", "4", "-o", truth)
        check(r.returncode == 0, f"workflow: the truth renders {r.stderr.strip()}")
        lines = "".join(f"{k}={v}\n" for k, v in ill.items())
        with daemon_running(tmp, measured, lines, "geometry=config\n") as sock:
            out = os.path.join(tmp, "capture")
            r = run(CTL, "-a", sock, "capture", "--target-error", "0.03", "-o", out, "-q")
            check(r.returncode == 0, f"workflow: the automatic capture with calibrate's lines succeeds {r.stderr.strip()}")
        if r.returncode != 0:
            return
        meta = json.load(open(glob.glob(os.path.join(out, "*.json"))[0]))
        settings = meta["settings"]
        predicted = settings["operating_point"]["predicted_error"]
        exposure = float(re.search(r"exposure-us=([0-9.e+-]+)", open(measured).read()).group(1))
        t = read_tiff(os.path.join(truth, "truth_transmissive.tiff")) * settings["exposure_us"] / exposure
        e = read_tiff(glob.glob(os.path.join(out, "*transmissive.tiff"))[0])
        mask = read_png_gray8(glob.glob(os.path.join(out, "*mask.png"))[0])
        ok = (mask & (1 | 8)) == 0
        achieved = float(numpy.sqrt(((e - t)[ok] ** 2).sum() / (t[ok] ** 2).sum()))
        check(predicted / 1.5 <= achieved <= 1.5 * predicted,
              f"workflow: {settings['estimator']} N={settings['phases']} M={settings['averages']}: achieved "
              f"{achieved:.4f} against the truth, predicted {predicted:.4f} (within x1.5)")


def scene_value(text, group, key):
    kf = configparser.ConfigParser()
    kf.read_string(text)
    return float(kf[group][key])


def open_field_dark_frame():
    """calibrate measures the open field ([illuminator] open-field-dn-per-ms) above a dark frame
    it takes even where [acquisition] dark-frame = false, and says when it could not. The
    expectation is the scene's radiometry: irradiance (photons per um^2 per ms, object side) x the
    pixel's footprint on the object (pitch / magnification)^2 x quantum efficiency x system gain.
    Ambient light (a tenth of the stripes' level) is in every frame: only a dark frame removes it.
    An opaque grid on the reference does not pull the open field down."""
    with tempfile.TemporaryDirectory(prefix="ds-calibrate-") as tmp:
        scene = os.path.join(tmp, "reference.scene")
        # the reference keeps SCENE's opaque wire grid (18 % of the pixels, and its shaded
        # edges): the open field is a bright quantile of the pixels, which they do not reach
        reference_scene(scene, "[ambient]\nlevel=0.05\n")
        text = open(scene).read()
        check("[object.grid]" in text, "the reference has the grid")
        footprint = scene_value(text, "sensor", "pixel-pitch-um") / scene_value(text, "camera", "magnification")
        want = (scene_value(text, "illuminator", "irradiance") * footprint ** 2
                * scene_value(text, "sensor", "quantum-efficiency") * scene_value(text, "sensor", "system-gain"))
        with daemon_running(tmp, scene, sim="[acquisition]\ndark-frame=false\n") as sock:
            cal = calibrate_json(sock, "dark-frame=false: calibrate")
            got = cal.get("open_field_dn_per_ms")
            check(got is not None and abs(got - want) <= 0.02 * want,
                  f"dark-frame=false: the open field {got} DN/ms measured above a dark frame (scene: {want:.1f})")
            r = run(CTL, "-a", sock, "calibrate", "--phases", "8", "--no-dark-frame")
            check(r.returncode == 0 and "open field      not measured: no dark frame (--no-dark-frame)" in r.stdout
                  and "open-field-dn-per-ms" not in r.stdout,
                  "--no-dark-frame: the open field is said not measured, and no line for it is given")
            with descatter.Client(sock) as c:
                meta = c.capture(phases=8, estimator="sine").meta
            check(meta["settings"]["dark_frame"] is False, "a capture still follows [acquisition] dark-frame = false")


def main():
    with tempfile.TemporaryDirectory(prefix="ds-calibrate-") as tmp:
        scene = os.path.join(tmp, "reference.scene")
        reference_scene(scene)
        with daemon_running(tmp, scene) as sock:
            cal = calibrate_json(sock, "descatterctl calibrate")
            if cal:
                check(cal["n_phases"] == 8 and cal["period_measured"], "8 phases, period measured")
                close_to_truth(cal, "descatterctl calibrate")
                check(not cal["scattering"]["suspected"] and "warning" not in cal,
                      f"a clear reference: no scattering warning ({cal['scattering']})")

            r = run(CTL, "-a", sock, "calibrate", "-n", "6")
            text = r.stdout
            check(r.returncode == 0 and "# descatterd.conf" in text, "the text output has the configuration block")
            check("WARNING" not in text and "warning" not in r.stderr, "a clear reference: no warning printed")
            if r.returncode == 0:
                ill = illuminator_lines(text)
                check(ill["pattern"] == "square", "config: pattern=square")
                close_to_truth({"period_px": ill["period-px"], "duty": ill["duty"], "black_level": ill["black-level"],
                                "edge_blur_px": 1.0}, "config lines")

            r = run(CTL, "-a", sock, "calibrate", "--bit-depth", "12")
            check(r.returncode == 2 and "folder" in r.stderr, "--bit-depth without a folder: usage error")
            r = run(CTL, "-a", sock, "calibrate", "-n", "2")
            check(r.returncode == 1 and "phases" in r.stderr, "calibrate -n 2 refused naming phases")

            with descatter.Client(sock) as c:
                before = c.status()["sets_done"]
                cal = c.calibrate(phases=6, averages=2)
                check(cal["n_phases"] == 6 and cal["frames_per_phase"] == 2, "Python: 6 phases x 2 frames")
                close_to_truth(cal, "Python client calibrate")
                check(cal["config"].startswith("[illuminator]\npattern=square\n"), "Python: config lines")
                fixed = c.calibrate(phases=8, period_px=9.5)
                check(fixed["period_px"] == 9.5 and not fixed["period_measured"], "a given period is used, not measured")
                check(c.status()["sets_done"] == before + 2, "each calibration is one published set")
                try:
                    c.calibrate(phases=8, estimator="maxmin")
                    check(False, "an argument calibrate does not take is refused")
                except TypeError:
                    check(True, "an argument calibrate does not take is refused (TypeError)")
            import asyncio
            from descatter import aio

            async def calibrate_async():
                async with await aio.connect(sock) as c:
                    return await c.calibrate(phases=4)
            cal = asyncio.run(calibrate_async())
            check(cal["n_phases"] == 4 and abs(cal["period_px"] - 9.5) <= 0.01, "asyncio client calibrate")
    open_field_dark_frame()
    scattering_reference()
    sine_reference()
    calibrate_then_capture()
    if failures:
        print(f"{len(failures)} failure(s)")
        sys.exit(1)


main()
