#!/usr/bin/python3
"""The automatic operating point's thin-film handling end to end over the loopback lab: descatterd
driving descatter-labsim's GigE Vision camera (Aravis) and Modbus TCP illuminator, run through
netns_run.sh (UDP 3956 on 127.0.0.1 is labsim's alone). The same stage on the in-process
simulator: daemon/probe-film. Usage: test_labsim_film.py BINDIR PYDIR

The open field comes as a rig's user gets it: `descatterctl calibrate` against the daemon while
labsim shows the scene's clear reference (the same illuminator, camera and sensor; no medium or
objects), its `[illuminator]` lines pasted into the daemon's configuration for the scenes after.

The film: 0.78 mm thick, g 0.93, scattering about a fifth of the light, an opaque object in front
of part of the field, an 8-bit sensor in Mono8. Independent expectations:
- the simulator's own transmittance into the lens (`descatter-sim describe`: its direct light
  plus the scattered light in the acceptance cone, shares of the incident light) is what the
  probe measures against the calibrated open field, within 0.03 (the calibration's 3 %);
- such a film keeps the stripes at every period, so its loss beyond two Fresnel faces is the only
  trace: the prediction is a lower bound (`lower_bound`, the loss named among
  `lower_bound_reasons`, `light_scattered_into_cone` assumed), and the achieved error (relative RMSE
  of the transmissive image against `descatter-sim render`'s truth at the exposure and gain the
  daemon chose, over the pixels its mask keeps) is at least the prediction;
- with `[camera] acceptance-half-angle-deg` (the scene's lens), the upper end is finite and holds
  the achieved error, within six times it (single scattering at g 0.95 puts at most 1.3 times
  the film's share in the cone), and the film's bias bound holds the simulator's own bias (its
  scattered light in the cone over its direct light);
- without the angle: a lower bound still, no upper end, the note saying the angle is not known;
- the same scene without the film (the object kept) passes the open field's light (within 0.03
  of 1) and is not flagged; its achieved error is its prediction within 1.5 times either way
  (tools/validate_paths.py's criterion), where the film's is many times its lower bound;
- calibrate names the pixel format its open field's DN are in (Mono8), and a daemon whose camera
  delivers Mono16 does not use it and says why (Mono8 holds a 12-bit sensor's top 8 bits)."""
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile

BIN, PYDIR = sys.argv[1:3]
sys.path.insert(0, PYDIR)
import descatter  # noqa: E402
import numpy  # noqa: E402
import tifffile  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from daemon_checks import Labsim, check, failures, spawn, stop_process, wait_ready_on_labsim  # noqa: E402

DAEMON = os.path.join(BIN, "descatterd")
CTL = os.path.join(BIN, "descatterctl")
LABSIM = os.path.join(BIN, "descatter-labsim")
SIM = os.path.join(BIN, "descatter-sim")

MEDIUM = ("[medium]\nthickness-mm=0.778364\nmua=0.00500796\nmus=0.348032\ng=0.927405\nn=1.41235\n"
          "photons=100000\nseed=286599\n\n")
SENSOR = dict(pitch_um=5.92572, qe=0.441411, gain=0.0235907, full_well=11124.2, bits=8, exposure_us=2160)
MAGNIFICATION, IRRADIANCE, CONE_DEG = 0.0566021, 1.0, 7.65407
PERIOD, DUTY = 15.75, 0.537079
OBJECT = "[object.o0]\nshape=rect\nposition=101;10\nsize=77;90\ntransmittance=0\n"
IGNORE_BITS = 1 | 8 | 32  # saturated, nonfinite, dark_exceeds: the mask legend (docs/operations.md)
BUDGET_MS = 3000


def scene_text(name, medium, objects):
    return (f"[scene]\nname={name}\n\n"
            f"[sensor]\nwidth=256\nheight=192\nbit-depth={SENSOR['bits']}\npixel-pitch-um={SENSOR['pitch_um']}\n"
            f"quantum-efficiency={SENSOR['qe']}\nsystem-gain={SENSOR['gain']}\nread-noise-e=12.0979\n"
            f"dark-current-e-per-s=6.051\nfull-well-e={SENSOR['full_well']}\nexposure-us={SENSOR['exposure_us']}\n\n"
            f"[illuminator]\npattern=square\nperiod-px={PERIOD}\nduty={DUTY}\nedge-blur-px=1.28036\n"
            f"irradiance={IRRADIANCE}\n\n" + medium +
            f"[camera]\nmagnification={MAGNIFICATION}\nacceptance-half-angle-deg={CONE_DEG}\n\n" + objects)



class Daemon:
    """descatterd on labsim's camera (Mono8: the sensor's 8 bits as they are) and illuminator;
    `camera` and `illuminator` are extra lines of those groups."""

    def __init__(self, tmp, name, labsim, env, camera="", illuminator="", pixel_format="Mono8"):
        self.sock = os.path.join(tmp, name + ".sock")
        conf = os.path.join(tmp, name + ".conf")
        with open(conf, "w") as f:
            f.write(f"[camera]\nbackend=aravis\naddress=127.0.0.1\npixel-format={pixel_format}\n"
                    f"exposure-us={SENSOR['exposure_us']}\ngrab-timeout-ms=2000\n" + camera +
                    f"[illuminator]\nbackend=modbus\nmodbus-uri=tcp://127.0.0.1:{labsim.port}\n"
                    "modbus-timeout-ms=300\n" + illuminator)
        self.log = os.path.join(tmp, name + ".log")
        self.proc = spawn([DAEMON, "--config", conf, "--socket", self.sock, "--no-socket-activation"],
                          stdout=open(self.log, "w"), stderr=subprocess.STDOUT, env=env)
        wait_ready_on_labsim(descatter, self.proc, self.sock, self.log, name, labsim)

    def stop(self):
        stop_process(self.proc, "descatterd")


def describe(scene, env):
    """The simulator's transmittance into the lens and its film's bias (scattered light in the
    cone over direct light), from `descatter-sim describe`."""
    out = subprocess.run([SIM, "describe", scene], capture_output=True, text=True, env=env, timeout=300,
                         check=True).stdout
    m = re.search(r"scattered light in the acceptance cone: ([0-9.e+-]+) \+- .* holds ([0-9.]+) % of it", out)
    d = re.search(r"direct light: ([0-9.e+-]+) of the incident light", out)
    assert m and d, "descatter-sim describe: " + out[-1500:]
    in_cone = float(m.group(1)) * float(m.group(2)) / 100
    direct = float(d.group(1))
    return direct + in_cone, in_cone / direct


def truth(scene, exposure_us, gain_db, tmp, env):
    """The simulator's transmissive truth at this exposure and gain: `descatter-sim render`."""
    d = os.path.join(tmp, "truth")
    shutil.rmtree(d, ignore_errors=True)
    subprocess.run([SIM, "render", scene, "--phases", "2", "--exposure-us", str(exposure_us), "--out", d],
                   check=True, stdout=subprocess.DEVNULL, env=env, timeout=300)
    return tifffile.imread(os.path.join(d, "truth_transmissive.tiff")).astype("float64") * 10 ** (gain_db / 20)


def achieved_error(result, scene, tmp, env):
    """Relative RMSE of the transmissive image against the truth over the pixels its mask keeps."""
    s = result.meta["settings"]
    t = truth(scene, s["exposure_us"], s.get("gain_db", 0.0), tmp, env)
    est = result.transmissive.astype("float64")
    keep = ((result.mask & IGNORE_BITS) == 0) & numpy.isfinite(est)
    d = est[keep] - t[keep]
    return float(numpy.sqrt(numpy.sum(d * d) / numpy.sum(t[keep] ** 2)))


def calibrate(tmp, env):
    """`descatterctl calibrate` on the clear reference; the [illuminator] lines it prints. The
    exposure keeps the open field at half the 8-bit clip level (from the scene's radiometry: the
    irradiance times the pixel's footprint on the object, QE and system gain); the open field it
    measures is checked against that radiometry."""
    ref = os.path.join(tmp, "reference.scene")
    with open(ref, "w") as f:
        f.write(scene_text("reference", "", ""))
    footprint = SENSOR["pitch_um"] / MAGNIFICATION
    want = IRRADIANCE * footprint ** 2 * SENSOR["qe"] * SENSOR["gain"]
    clip = min(SENSOR["full_well"] * SENSOR["gain"], 2 ** SENSOR["bits"] - 1)
    exposure = 0.5 * clip / want * 1000
    labsim = Labsim(LABSIM, tmp, ref, "DSLF", env)
    try:
        d = Daemon(tmp, "calibrate", labsim, env, illuminator=f"pattern=square\nperiod-px={PERIOD}\nduty={DUTY}\n")
        try:
            r = subprocess.run([CTL, "--address", d.sock, "calibrate", "-n", "16", "-e", f"{exposure:.0f}"],
                               capture_output=True, text=True, timeout=120)
        finally:
            d.stop()
    finally:
        labsim.stop()
    assert r.returncode == 0, "descatterctl calibrate: " + r.stderr.strip()[-500:]
    block = r.stdout.split("# descatterd.conf\n", 1)[1].split("\n\n", 1)[0]
    lines, inside = [], False
    for line in block.splitlines():
        s = line.strip()
        if s.startswith("["):
            inside = s == "[illuminator]"
        elif inside and "=" in s and not s.startswith("#"):
            lines.append(s)
    keys = dict(x.split("=", 1) for x in lines)
    got = float(keys.get("open-field-dn-per-ms", "nan"))
    print(f"     open field: {got:.4g} DN/ms at {exposure:.0f} us (the scene's radiometry: {want:.4g})", flush=True)
    check(abs(got - want) <= 0.02 * want, f"calibrate's open field {got:.4g} DN/ms is the radiometry's {want:.4g}")
    return "\n".join(lines) + "\n"


def capture(d, scene, tmp, env, what):
    with descatter.Client(d.sock) as c:
        result = c.capture(time_budget_ms=BUDGET_MS, format="f32", outputs=["transmissive", "mask"])
    op = result.meta["settings"]["operating_point"]
    achieved = achieved_error(result, scene, tmp, env)
    sc = op["scene"]
    upper = op["predicted_error_upper"]
    print(f"     {what}: transmittance {sc['open_field_transmittance']}, predicted {op['predicted_error']:.4f}"
          f" to {upper if upper is None else f'{upper:.4f}'}, achieved {achieved:.4f}"
          f" ({result.meta['settings']['estimator']} N={result.meta['settings']['phases']}"
          f" M={result.meta['settings']['averages']}); film bias upper {sc['film_bias_upper']}", flush=True)
    print(f"     {what}: {sc['open_field_note']}; {sc['film_bound_note']}", flush=True)
    return op, achieved


def capture_on(tmp, name, labsim, env, scene, what, **daemon_args):
    """One descatterd of its own configuration on labsim (Daemon's arguments), one capture."""
    d = Daemon(tmp, name, labsim, env, **daemon_args)
    try:
        return capture(d, scene, tmp, env, what)
    finally:
        d.stop()

def loss_named(op):
    return any("open field" in r and "lower bound" in r for r in op["lower_bound_reasons"])


def film_checks(tmp, env, lines):
    film = os.path.join(tmp, "film.scene")
    with open(film, "w") as f:
        f.write(scene_text("film", MEDIUM, OBJECT))
    t_truth, bias_truth = describe(film, env)
    print(f"     film: the simulator's transmittance into the lens {t_truth:.4f}, bias {bias_truth:.4f}", flush=True)
    labsim = Labsim(LABSIM, tmp, film, "DSLF", env)
    try:
        op, achieved = capture_on(tmp, "film", labsim, env, film, "film, angle known",
                                  camera=f"acceptance-half-angle-deg={CONE_DEG}\n", illuminator=lines)
        t = op["scene"]["open_field_transmittance"]
        check(t is not None and abs(t - t_truth) <= 0.03,
              f"film: the probe's transmittance {t} is the simulator's {t_truth:.4f} within 0.03")
        check(op["lower_bound"] and loss_named(op), "film: a lower bound, the light lost named among its reasons")
        check("light_scattered_into_cone" in op["assumed"], f"film: light_scattered_into_cone assumed {op['assumed']}")
        upper = op["predicted_error_upper"]
        check(upper is not None and math.isfinite(upper) and upper > op["predicted_error"],
              f"film with the angle: a finite upper end above the prediction ({upper})")
        check(op["predicted_error"] <= achieved, f"film: the prediction {op['predicted_error']:.4f} is a lower "
              f"bound of the achieved {achieved:.4f}")
        if upper is not None:
            check(achieved <= upper <= 6 * achieved,
                  f"film: the upper end {upper:.4f} holds the achieved {achieved:.4f}, within six times it")
        b = op["scene"]["film_bias_upper"]
        check(b is not None and bias_truth <= b, f"film: the bias bound {b} holds the simulator's bias "
              f"{bias_truth:.4f}")

        op, achieved = capture_on(tmp, "film-no-angle", labsim, env, film, "film, angle not known", illuminator=lines)
        check(op["lower_bound"] and loss_named(op) and "light_scattered_into_cone" in op["assumed"],
              "film without the angle: a lower bound for the light lost")
        check(op["predicted_error_upper"] is None and op["scene"]["film_bias_upper"] is None,
              "film without the angle: no upper end")
        check("acceptance angle is not known" in op["scene"]["film_bound_note"],
              "film without the angle: the note says the angle is not known")
        check(op["predicted_error"] <= achieved, f"film without the angle: the prediction "
              f"{op['predicted_error']:.4f} is a lower bound of the achieved {achieved:.4f}")
    finally:
        labsim.stop()


def clear_checks(tmp, env, lines):
    clear = os.path.join(tmp, "clear.scene")
    with open(clear, "w") as f:
        f.write(scene_text("clear", "", OBJECT))
    labsim = Labsim(LABSIM, tmp, clear, "DSLF", env)
    try:
        op, achieved = capture_on(tmp, "clear", labsim, env, clear, "clear",
                                  camera=f"acceptance-half-angle-deg={CONE_DEG}\n", illuminator=lines)
        # The same open field under another pixel format: its DN are Mono8's, so it is not used.
        other, _ = capture_on(tmp, "clear-mono16", labsim, env, clear, "clear, Mono16",
                              camera=f"acceptance-half-angle-deg={CONE_DEG}\n", illuminator=lines,
                              pixel_format="Mono16")
    finally:
        labsim.stop()
    t = op["scene"]["open_field_transmittance"]
    check(t is not None and abs(t - 1) <= 0.03, f"clear: the probe's transmittance {t} is 1 within 0.03")
    check(not loss_named(op) and "light_scattered_into_cone" not in op["assumed"]
          and op["scene"]["film_bias_upper"] is None, "clear: not flagged")
    check(other["scene"]["open_field_transmittance"] is None and other["scene"]["open_field_note"].startswith(
          "not measured: [illuminator] open-field-dn-per-ms was measured in Mono8 and the camera delivers Mono16"),
          "clear in Mono16: the open field calibrated in Mono8 is not used, the note naming both")
    ratio = achieved / op["predicted_error"]
    check(1 / 1.5 <= ratio <= 1.5, f"clear: the achieved error {achieved:.4f} is the prediction "
          f"{op['predicted_error']:.4f} within 1.5 times ({ratio:.2f})")


def main():
    with tempfile.TemporaryDirectory(prefix="ds-labsim-film-") as tmp:
        env = dict(os.environ, DESCATTER_CACHE_DIR=os.path.join(tmp, "cache"))
        lines = calibrate(tmp, env)
        print("     calibrated: " + lines.strip().replace("\n", "; "), flush=True)
        check("open-field-dn-per-ms=" in lines and "open-field-pixel-format=Mono8" in lines,
              "calibrate printed [illuminator] open-field-dn-per-ms and the pixel format it is in")
        film_checks(tmp, env, lines)
        clear_checks(tmp, env, lines)
    if failures:
        print(f"{len(failures)} check(s) failed")
        sys.exit(1)
    print("all checks passed")


if __name__ == "__main__":
    main()
