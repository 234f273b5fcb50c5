#!/usr/bin/python3
"""The automatic operating point validated through both ways a user starts descatterd
(docs/accuracy.md, "Validation"). For every generated scene S:

- path `sim`: `descatterd --sim --scene S`, the daemon knowing the simulated pattern (written as
  a configuration with the sim backends when S sets an exposure);
- path `rig`: the documented rig workflow: `descatterctl calibrate` against the daemon on the
  clear reference of S (the same illuminator, camera and sensor; no medium, objects or ambient
  light), its `[illuminator]` lines pasted into descatterd.conf, then the daemon on S.
Both paths run the camera at S's `[sensor] exposure-us` (`[camera] exposure-us`), as a user sets
the camera up for the scene in front of it.

Each request (`capture --target-error T`, `capture --time-budget-ms B`) goes to the daemon over
its socket; the transmissive image it returns is compared with the simulator's truth at the
exposure it chose (`descatter-sim render`), over the pixels its mask keeps (relative RMSE,
sqrt(sum (est - truth)^2 / sum truth^2), as proc/metrics.c and `descatterctl validate` define it).

A request is OK when:
- chosen: achieved / predicted within [1/1.5, 1.5];
- refused: the best point the refusal names, and the point it names as reaching the target
  (more frames or light, when it names one the rig can run), are run, and neither reaches it;
  nor did the other path's choice for the same scene and request (the target was then reachable
  with the rig's own candidates: an over-pessimistic refusal is a miss);
- the pilot refused with a reason the scene shows (no stripes, clipped): counted apart.
Any set that fails after the choice (a frame the phase check refused, a device error) is a miss
with its reason. Every frame of the simulated lab is right, so each frame the phase check drops
(`frames.dropped_by_reason` wrong_phase, unverifiable) is a false refusal: they are counted per
path, the rig path's calibration frames included.

Usage:
  validate_paths.py --bin DIR --generator 2 --seeds 100,101 --count 5 --out OUT
  validate_paths.py --bin DIR --scene FILE... --out OUT
Writes OUT/paths.csv (one row per request and path) and OUT/paths.md (per path: % OK, the
misses with scene and reason, the worst case); --summary OUT... prints the tables of finished
runs together. Held-out seeds (docs/accuracy.md) are run once, by the lead, after the last
change."""
import argparse
import csv
import json
import os
import re
import shutil
import subprocess
import sys
import time

IGNORE_BITS = 1 | 8 | 32  # saturated, nonfinite, dark_exceeds: the mask legend (docs/operations.md)
FACTOR = 1.5
POINT = re.compile(r"([0-9.]+)(?: to (?:[0-9.]+|unbounded))? \((maxmin|sine|robust), N=(\d+), M=(\d+), ([0-9.]+) µs, "
                   r"period ([0-9.]+) px")
FIELDS = ["scene", "path", "request", "outcome", "estimator", "phases", "averages", "exposure_us", "predicted",
          "lower_bound", "margin", "achieved", "best_achieved", "remedy", "remedy_achieved", "verdict", "reason",
          "chosen_ms", "upper", "medium"]


# ----- scene files -------------------------------------------------------------------------------
def groups(text):
    """[(group name or None, [lines])] in order."""
    out, cur = [(None, [])], None
    for line in text.splitlines():
        s = line.strip()
        if s.startswith("[") and s.endswith("]"):
            cur = s[1:-1]
            out.append((cur, []))
        else:
            out[-1][1].append(line)
    return out


def join(gs):
    lines = []
    for name, body in gs:
        if name is not None:
            lines.append(f"[{name}]")
        lines += body
    return "\n".join(lines) + "\n"


def value(text, group, key, default=None):
    for name, body in groups(text):
        if name == group:
            for line in body:
                k, _, v = line.partition("=")
                if k.strip() == key:
                    return v.strip()
    return default


def reference_scene(text):
    """The clear reference a user calibrates on: no medium, objects or ambient light."""
    keep = [(n, b) for n, b in groups(text) if n not in ("medium", "ambient") and not (n or "").startswith("object.")]
    return join(keep)


def clip_dn(text):
    bits = int(value(text, "sensor", "bit-depth", "12"))
    well = float(value(text, "sensor", "full-well-e", "20000")) * float(value(text, "sensor", "system-gain", "0.25"))
    return min(well, 2 ** bits - 1)


# ----- programs ----------------------------------------------------------------------------------
class Tools:
    def __init__(self, bindir, work):
        self.ctl = os.path.join(bindir, "descatterctl")
        self.daemon = os.path.join(bindir, "descatterd")
        self.sim = os.path.join(bindir, "descatter-sim")
        self.work = work
        self.env = dict(os.environ)
        self.env.setdefault("DESCATTER_CACHE_DIR", os.path.join(work, "cache"))
        self.truths = {}

    def truth(self, scene, exposure_us):
        """The simulator's transmissive truth at this exposure (0 dB): `descatter-sim render`."""
        import tifffile
        key = (scene, round(exposure_us))
        if key not in self.truths:
            d = os.path.join(self.work, "truth")
            shutil.rmtree(d, ignore_errors=True)
            subprocess.run([self.sim, "render", scene, "--phases", "2", "--exposure-us", str(round(exposure_us)),
                            "--out", d], check=True, stdout=subprocess.DEVNULL, env=self.env)
            self.truths = {key: tifffile.imread(os.path.join(d, "truth_transmissive.tiff")).astype("float64")}
        return self.truths[key]


class Daemon:
    """One descatterd on its own socket: `--sim --scene S`, or `--config C --scene S`."""

    def __init__(self, tools, scene, conf_text=None):
        self.t = tools
        self.sock = os.path.join(tools.work, "d.sock")
        args = [tools.daemon, "--socket", self.sock, "--no-socket-activation", "--scene", scene]
        if conf_text is None:
            args.insert(1, "--sim")
        else:
            conf = os.path.join(tools.work, "d.conf")
            with open(conf, "w") as f:
                f.write(conf_text)
            args[1:1] = ["--config", conf]
        self.log = open(os.path.join(tools.work, "d.log"), "a")
        self.proc = subprocess.Popen(args, stdout=self.log, stderr=self.log, env=tools.env)
        deadline = time.time() + 300
        while True:
            r = self.ctl("status", "--json", check=False)
            if r.returncode == 0 and json.loads(r.stdout)["ready"]:
                break
            if self.proc.poll() is not None or time.time() > deadline:
                self.stop()
                raise RuntimeError("descatterd did not start: " + open(self.log.name).read()[-1500:])
            time.sleep(0.2)

    def ctl(self, *args, check=True):
        return subprocess.run([self.t.ctl, "--address", self.sock, *args], capture_output=True, text=True,
                              check=check, env=self.t.env, timeout=1800)

    def dropped(self):
        f = json.loads(self.ctl("status", "--json").stdout)["frames"]
        by = f["dropped_by_reason"]
        return f["acquired"], by.get("wrong_phase", 0) + by.get("unverifiable", 0)

    def stop(self):
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.log.close()


# ----- one capture -------------------------------------------------------------------------------
def relative_rmse(est, truth, mask):
    import numpy
    keep = ((mask & IGNORE_BITS) == 0) & numpy.isfinite(est) & numpy.isfinite(truth)
    if not keep.any():
        return float("nan")
    d = est[keep] - truth[keep]
    return float(numpy.sqrt(numpy.sum(d * d) / numpy.sum(truth[keep] ** 2)))


def capture(d, scene, args):
    """Runs one capture; (metadata, achieved) or (None, the daemon's message)."""
    import h5py
    out = os.path.join(d.t.work, "set")
    shutil.rmtree(out, ignore_errors=True)
    try:
        r = d.ctl("capture", "--quiet", "--files", "hdf5", "--out", out, *args, check=False)
    except subprocess.TimeoutExpired:
        return None, "the capture did not finish within 30 minutes"
    if r.returncode != 0:
        return None, (r.stderr.strip().split(": ", 1)[-1] or f"exit {r.returncode}")
    h5 = [f for f in os.listdir(out) if f.endswith(".h5")][0]
    with h5py.File(os.path.join(out, h5), "r") as f:
        est = f["entry/transmissive/data"][()].astype("float64")
        mask = f["entry/mask/data"][()]
        meta = json.loads(f["entry/metadata/data"][()])
    s = meta["settings"]
    truth = d.t.truth(scene, s["exposure_us"])
    return meta, relative_rmse(est, truth, mask)


def fixed_args(est, n, m, e):
    return ["--estimator", est, "-n", str(n), "-m", str(m), "-e", str(e)]


def check_refusal(d, scene, message, target, row):
    """Runs the best point a refusal names and the point it names as reaching the target."""
    best = POINT.search(message.split("the best reachable is", 1)[-1]) if "the best reachable is" in message else None
    if not best:
        row.update(outcome="refused", verdict="miss", reason="refusal names no point to check: " + message[:160])
        return
    pred, est, n, m, e, period = best.groups()
    row.update(outcome="refused", estimator=est, phases=n, averages=m, exposure_us=e, predicted=pred)
    meta, achieved = capture(d, scene, fixed_args(est, n, m, e))
    if meta is None:
        row.update(verdict="miss", reason="the named best point failed: " + achieved[:160])
        return
    row["best_achieved"] = f"{achieved:.4g}"
    remedy = None
    if "would reach it:" in message:
        remedy = POINT.search(message.split("would reach it:", 1)[1])
    remedy_reaches = False
    if remedy:
        rp, rest, rn, rm, re_, rperiod = remedy.groups()
        row["remedy"] = f"{rest} N={rn} M={rm} {float(re_):.0f} µs P={rperiod}"
        if abs(float(rperiod) - float(period)) > 1e-6 or int(rm) > 64 or float(re_) > 1e7:
            row["remedy"] += " (not run: another period or outside the rig's range)"
        else:
            rmeta, rach = capture(d, scene, fixed_args(rest, rn, rm, re_))
            if rmeta is not None:
                row["remedy_achieved"] = f"{rach:.4g}"
                remedy_reaches = rach <= target
    if achieved <= target:
        row.update(verdict="miss", reason=f"refused, but the named best point reaches {achieved:.4g} <= {target}")
    elif remedy_reaches:
        row.update(verdict="miss", reason=f"refused, but the point named as reaching it does ({row['remedy_achieved']})")
    else:
        row.update(verdict="ok", reason="refused; the named points miss the target")


def run_request(d, scene, req, row):
    kind, amount = req
    args = ["--target-error", str(amount)] if kind == "target" else ["--time-budget-ms", str(amount)]
    meta, achieved = capture(d, scene, args)
    if meta is None:
        msg = achieved
        if "no operating point" in msg and kind == "target":
            check_refusal(d, scene, msg, amount, row)
        elif "no operating point" in msg:
            row.update(outcome="refused", verdict="ok", reason="nothing fits the budget: " + msg[:160])
        elif "no stripes" in msg or "clip level" in msg:
            row.update(outcome="pilot-refused", verdict="ok", reason=msg[:200])
        else:
            row.update(outcome="failed", verdict="miss", reason=msg[:200])
        return
    s, op = meta["settings"], meta["settings"].get("operating_point", {})
    pred = op.get("predicted_error")
    row.update(outcome="chosen", estimator=s["estimator"], phases=s["phases"], averages=s["averages"],
               exposure_us=f"{s['exposure_us']:.0f}", predicted=f"{pred:.4g}",
               lower_bound=int(bool(op.get("lower_bound"))), margin=int(bool(op.get("target_may_be_missed"))),
               achieved=f"{achieved:.4g}", chosen_ms=f"{op.get('predicted_time_ms', 0):.0f}",
               upper=f"{op['predicted_error_upper']:.4g}" if op.get("predicted_error_upper") else "")
    ratio = achieved / pred if pred else float("inf")
    if 1 / FACTOR <= ratio <= FACTOR:
        row.update(verdict="ok", reason="")
    else:
        row.update(verdict="miss", reason=f"achieved x{ratio:.2f} the prediction")


# ----- the two paths -----------------------------------------------------------------------------
def calibrate_lines(tools, scene_text, counts=None):
    """`descatterctl calibrate` against the daemon on the clear reference, at an exposure that keeps
    the open field at 0.6 of the clip level; the [illuminator] lines it prints. counts (a list
    [frames, dropped], may be None) gets the reference's frames and those the phase check dropped."""
    ref = os.path.join(tools.work, "reference.scene")
    with open(ref, "w") as f:
        f.write(reference_scene(scene_text))
    e0 = float(value(scene_text, "sensor", "exposure-us", "5000"))
    top = float(tools.truth(ref, e0).max())
    exposure = max(1, min(1e7, e0 * 0.6 * clip_dn(scene_text) / top)) if top > 0 else e0
    d = Daemon(tools, ref)
    try:
        r = d.ctl("calibrate", "-n", "16", "-e", f"{exposure:.0f}", "--quiet", check=False)
        if counts is not None:
            acquired, dropped = d.dropped()
            counts[0] += acquired
            counts[1] += dropped
    finally:
        d.stop()
    if r.returncode != 0:
        raise RuntimeError("calibrate: " + r.stderr.strip()[-300:])
    lines, inside = [], False
    for line in r.stdout.splitlines():
        s = line.strip()
        if s.startswith("["):
            inside = s == "[illuminator]"
            continue
        if inside and "=" in s and not s.startswith("#"):
            lines.append(s)
    return lines


def run_path(tools, path, scene, name, requests, rows, phase):
    text = open(scene).read()
    base = [dict(scene=name, path=path, request=f"{k} {a}") for k, a in requests]
    try:
        # The camera runs at the scene's own exposure, as a user sets the camera up for what it
        # looks at; descatterd's built-in 5000 us clips the pilot of many generated scenes, whose
        # refusals would then say nothing about the model.
        exposure = value(text, "sensor", "exposure-us")
        camera = "[camera]\nbackend=sim\n" + (f"exposure-us={float(exposure):g}\n" if exposure else "")
        conf = camera + "[illuminator]\nbackend=sim\n" if exposure else None
        if path == "rig":
            lines = calibrate_lines(tools, text, phase[path])
            # A rig's user knows their lens: its acceptance cone (the scene format's default 10
            # degrees where the scene sets none) bounds a thin film's light (docs/accuracy.md).
            cone = float(value(text, "camera", "acceptance-half-angle-deg", "10"))
            conf = (camera + f"acceptance-half-angle-deg={cone:g}\n[illuminator]\nbackend=sim\n"
                    + "\n".join(lines) + "\n")
        d = Daemon(tools, scene, conf)
    except (RuntimeError, subprocess.SubprocessError) as e:
        for row in base:
            row.update(outcome="failed", verdict="miss", reason=str(e)[:200])
            rows.append(row)
        return
    try:
        for row, req in zip(base, requests):
            run_request(d, scene, req, row)
            rows.append(row)
            print(f"validate_paths: {name} {path} {row['request']}: {row['outcome']} {row.get('estimator', '')} "
                  f"predicted {row.get('predicted', '')} achieved {row.get('achieved', row.get('best_achieved', ''))}"
                  f" {row['verdict']} {row['reason']}", file=sys.stderr, flush=True)
        try:
            acquired, dropped = d.dropped()
        except (subprocess.SubprocessError, KeyError, ValueError) as e:
            # The daemon is gone: its requests already say so; its frames cannot be counted.
            print(f"validate_paths: {name} {path}: no frame counts: {e}", file=sys.stderr)
            acquired, dropped = 0, 0
        phase[path][0] += acquired
        phase[path][1] += dropped
    finally:
        d.stop()


def cross_check(rows):
    """A refusal is also wrong where the other path, on the same scene and request, chose a point that
    reached the target: the target was reachable with the rig's own candidates."""
    chosen = {(r["scene"], r["path"], r["request"]): r for r in rows if r["outcome"] == "chosen"}
    for r in rows:
        if r["outcome"] != "refused" or r["verdict"] != "ok" or not r["request"].startswith("target"):
            continue
        other = chosen.get((r["scene"], "rig" if r["path"] == "sim" else "sim", r["request"]))
        target = float(r["request"].split()[1])
        if other and other.get("achieved") and float(other["achieved"]) <= target:
            r.update(verdict="miss", reason=f"refused, but the {other['path']} path's choice {other['estimator']} "
                                            f"N={other['phases']} M={other['averages']} reached {other['achieved']}")


# ----- report ------------------------------------------------------------------------------------
def scene_medium(path):
    """The medium a generated scene draws (its description's last clause, as generate-scenes writes
    it: "no medium", "slab", "thin forward-peaked film"); "not generated" for any other scene."""
    try:
        text = open(path).read()
    except OSError:
        return "not generated"
    m = re.search(r"^description=generator \d+: .*, ([^,\n]+)$", text, re.M)
    return m.group(1).strip() if m else "not generated"


def report(rows, phase, header):
    md = [header, ""]
    for path in ("sim", "rig"):
        sel = [r for r in rows if r["path"] == path]
        if not sel:
            continue
        ok = [r for r in sel if r["verdict"] == "ok"]
        title = {"sim": "`descatterd --sim --scene S`", "rig": "calibrated rig (`descatterctl calibrate`, then S)"}[path]
        md.append(f"## Path {path}: {title}")
        md.append("")
        counts = {o: sum(1 for r in sel if r["outcome"] == o) for o in ("chosen", "refused", "pilot-refused", "failed")}
        md.append("| requests | OK | % OK | chosen | refused | pilot refused | failed | frames | phase check false refusals |")
        md.append("|---|---|---|---|---|---|---|---|---|")
        acq, drop = phase.get(path, (0, 0))
        md.append(f"| {len(sel)} | {len(ok)} | {100 * len(ok) / len(sel):.0f} % | {counts['chosen']} | "
                  f"{counts['refused']} | {counts['pilot-refused']} | {counts['failed']} | {acq} | {drop} |")
        md.append("")
        # The outcome by the medium the scene draws: a class whose error the frames do not show
        # (thin forward-peaked films, docs/accuracy.md "Limits") is told apart from the rest.
        md.append("| scene's medium | requests | OK | % OK |")
        md.append("|---|---|---|---|")
        for medium in sorted({r["medium"] for r in sel}):
            mine = [r for r in sel if r["medium"] == medium]
            n_ok = sum(1 for r in mine if r["verdict"] == "ok")
            md.append(f"| {medium} | {len(mine)} | {n_ok} | {100 * n_ok / len(mine):.0f} % |")
        md.append("")
        misses = [r for r in sel if r["verdict"] != "ok"]
        if misses:
            md.append("| miss: scene | request | choice | predicted | achieved | reason |")
            md.append("|---|---|---|---|---|---|")
            for r in misses:
                choice = f"{r.get('estimator', '')} N={r.get('phases', '')} M={r.get('averages', '')}" \
                    if r.get("estimator") else "–"
                md.append(f"| {r['scene']} | {r['request']} | {choice} | {r.get('predicted', '')} | "
                          f"{r.get('achieved') or r.get('best_achieved', '')} | {r['reason']} |")
            md.append("")
        # How many misses the daemon said could be missed: a chosen point flagged a lower bound (its
        # prediction is not an estimate of the error); the optimistic ones are those it matters for.
        flagged = [r for r in misses if r["outcome"] == "chosen" and str(r.get("lower_bound")) == "1"]
        optimistic = [r for r in misses if r["outcome"] == "chosen" and r.get("predicted") and r.get("achieved")
                      and float(r["achieved"]) > FACTOR * float(r["predicted"])]
        md.append(f"Misses flagged as lower bounds: {len(flagged)} of {len(misses)} misses; "
                  f"{sum(1 for r in optimistic if str(r.get('lower_bound')) == '1')} of {len(optimistic)} optimistic ones "
                  f"(achieved above x{FACTOR} the prediction).")
        # A prediction the daemon gave as an interval (a lower bound with an upper end) is scored
        # above by its lower end like any other; how many misses the interval itself held is told
        # apart, with the same factor at each end.
        held = [r for r in flagged if r.get("upper") and r.get("achieved")
                and float(r["predicted"]) / FACTOR <= float(r["achieved"]) <= FACTOR * float(r["upper"])]
        with_upper = [r for r in sel if r["outcome"] == "chosen" and r.get("upper") and str(r.get("lower_bound")) == "1"]
        md.append(f"Chosen points given as a lower bound with an upper end: {len(with_upper)}; misses whose "
                  f"achieved error lies within their interval (x{FACTOR} at each end): {len(held)} of {len(flagged)} "
                  "flagged.")
        md.append("")
        chosen = [r for r in sel if r["outcome"] == "chosen" and r.get("predicted") and r.get("achieved")]
        if chosen:
            def far(r):
                q = float(r["achieved"]) / float(r["predicted"])
                return max(q, 1 / q) if q > 0 else float("inf")
            w = max(chosen, key=far)
            md.append(f"Worst chosen point: {w['scene']}, {w['request']}: {w['estimator']} N={w['phases']} "
                      f"M={w['averages']}, predicted {w['predicted']}, achieved {w['achieved']} "
                      f"(x{float(w['achieved']) / float(w['predicted']):.2f}).")
            md.append("")
    return "\n".join(md) + "\n"


def read_runs(dirs):
    """The rows and frame counts of finished runs. A run written before rows named their medium
    has it read from its DIR/scenes (a scene given with --scene, not kept there, reads "not
    generated")."""
    rows, phase = [], {}
    for d in dirs:
        mine = list(csv.DictReader(open(os.path.join(d, "paths.csv"))))
        rows += mine
        for r in mine:
            if not r.get("medium"):
                r["medium"] = scene_medium(os.path.join(d, "scenes", r["scene"]))
        for path, v in json.load(open(os.path.join(d, "phase.json"))).items():
            p = phase.setdefault(path, [0, 0])
            p[0] += v[0]
            p[1] += v[1]
    return rows, phase


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bin", help="folder holding descatterctl, descatterd and descatter-sim")
    ap.add_argument("--generator", type=int, default=2)
    ap.add_argument("--seeds", default="", help="comma-separated generator seeds")
    ap.add_argument("--count", type=int, default=10, help="scenes per seed")
    ap.add_argument("--scene", action="append", default=[], help="a scene file (repeat)")
    ap.add_argument("--targets", default="0.03,0.1,0.3")
    ap.add_argument("--budgets", default="60")
    ap.add_argument("--paths", default="sim,rig")
    ap.add_argument("--out")
    ap.add_argument("--summary", nargs="+", help="print the tables of these finished runs together")
    a = ap.parse_args()
    if a.summary:
        rows, phase = read_runs(a.summary)
        cross_check(rows)
        sys.stdout.write(report(rows, phase, "# Validation through both start-up paths (" +
                                ", ".join(a.summary) + ")"))
        return 0
    if not a.bin or not a.out:
        ap.error("--bin and --out are needed (or --summary)")
    os.makedirs(a.out, exist_ok=True)
    work = os.path.abspath(os.path.join(a.out, "work"))
    os.makedirs(work, exist_ok=True)
    tools = Tools(a.bin, work)
    scenes = [(os.path.abspath(s), os.path.basename(s)) for s in a.scene]
    sdir = os.path.join(a.out, "scenes")
    for seed in [s for s in a.seeds.split(",") if s]:
        r = subprocess.run([tools.ctl, "generate-scenes", "--generator", str(a.generator), "--seed", seed,
                            "--count", str(a.count), "--out", sdir], check=True, capture_output=True, text=True,
                           env=tools.env)
        scenes += [(os.path.abspath(p), os.path.basename(p)) for p in r.stdout.split()]
    requests = [("target", float(t)) for t in a.targets.split(",") if t and t != "none"] + \
               [("budget", float(b)) for b in a.budgets.split(",") if b and b != "none"]
    rows, phase = [], {p: [0, 0] for p in a.paths.split(",")}
    for scene, name in scenes:
        for path in a.paths.split(","):
            run_path(tools, path, scene, name, requests, rows, phase)
    cross_check(rows)
    media = {name: scene_medium(scene) for scene, name in scenes}
    for r in rows:
        r["medium"] = media[r["scene"]]
    with open(os.path.join(a.out, "paths.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, FIELDS, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    with open(os.path.join(a.out, "phase.json"), "w") as f:
        json.dump(phase, f)
    cmd = "tools/validate_paths.py " + " ".join(sys.argv[1:])
    with open(os.path.join(a.out, "paths.md"), "w") as f:
        f.write(report(rows, phase, f"# Validation through both start-up paths\n\nMade by `{cmd}` "
                                    f"({len(scenes)} scenes, generator {a.generator})."))
    shutil.rmtree(work, ignore_errors=True)
    print(f"validate_paths: {len(rows)} requests; {a.out}/paths.md", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
