#!/usr/bin/python3
"""`descatterctl study --speeds`: the study's speed axis, reduced (a 128 x 96 scene, seconds).
Usage: test_study_speed.py DESCATTERCTL SCENE (tests/daemon/study-speed.scene)

Independent expectations (physics, not numbers the study printed before):
- the scene's stripes are sine and the sine estimator is exact on them: a still scene's
  systematic part is 0 at every N, and its noise falls as 1/sqrt(N), so the still scene's error
  is lowest at the largest N;
- an object moving at v crosses v x (set duration) pixels during a set, and the duration grows
  with N (the rig model: N settles and N frames): sine's noise-free (systematic) error, motion
  alone, grows with N at every speed > 0, and every estimator's grows with speed at each N;
- so at high speed a large-N set is worse than the same set of the still scene, and the N with
  the lowest error at high speed is at most the one at speed 0 (strictly lower here, where noise
  alone favours the largest N);
- every row carries its speed, the CSV's speed_px_s column; pareto.md keeps a front per speed;
- bad speeds and an object that is not in the scene are refused, naming them."""
import csv
import collections
import os
import subprocess
import sys
import tempfile

PHASES = [3, 4, 6, 8, 12, 16, 24]
SPEEDS = [0.0, 100.0, 400.0]


def main():
    ctl, scene = sys.argv[1], sys.argv[2]
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "out")
        subprocess.run([ctl, "study", "--quiet", "--no-figures", "--scene", scene, "--out", out,
                        "--phases", ",".join(map(str, PHASES)), "--averages", "1", "--exposures", "1",
                        "--periods", "scene", "--seeds", "2", "--estimators", "sine,maxmin",
                        "--speeds", ",".join(f"{v:g}" for v in SPEEDS), "--moving", "fish"], check=True)
        with open(os.path.join(out, "study.csv"), newline="") as f:
            rows = list(csv.DictReader(f))
        assert rows and "speed_px_s" in rows[0], "study.csv has no speed_px_s column"
        assert {float(r["speed_px_s"]) for r in rows} == set(SPEEDS)
        err = collections.defaultdict(list)
        sys_part = {}
        for r in rows:
            k = (r["estimator"], float(r["speed_px_s"]), int(r["phases"]))
            err[k].append(float(r["rel_rmse_transmissive"]))
            sys_part[k] = float(r["systematic_transmissive"])
        mean = {k: sum(v) / len(v) for k, v in err.items()}

        for n in PHASES:
            assert sys_part[("sine", 0.0, n)] < 1e-4, f"sine on sine stripes, still, N={n}: {sys_part[('sine', 0.0, n)]}"
        # Sine's systematic part is motion alone (0 when still); max/min's also holds its sampling
        # of the stripes at small N, which falls with N, so only sine's must grow with N.
        for v in SPEEDS[1:]:
            s = [sys_part[("sine", v, n)] for n in PHASES]
            assert all(b > a for a, b in zip(s, s[1:])), f"sine at {v} px/s: systematic not growing with N: {s}"
        for est in ("sine", "maxmin"):
            for n in PHASES:
                s = [sys_part[(est, v, n)] for v in SPEEDS[1:]]
                assert s[1] > s[0], f"{est} N={n}: systematic not growing with speed: {s}"
            big = PHASES[-1]
            assert mean[(est, SPEEDS[-1], big)] > 1.5 * mean[(est, 0.0, big)], \
                f"{est} N={big}: {mean[(est, SPEEDS[-1], big)]} at {SPEEDS[-1]} px/s against {mean[(est, 0.0, big)]} still"
        best = {v: min(PHASES, key=lambda n: mean[("sine", v, n)]) for v in SPEEDS}
        assert best[0.0] == PHASES[-1], f"still: noise alone should favour the largest N, best N = {best[0.0]}"
        assert all(best[b] <= best[a] for a, b in zip(SPEEDS, SPEEDS[1:])), f"best N against speed: {best}"
        assert best[SPEEDS[-1]] < best[0.0], f"best N against speed: {best}"
        print(f"ok   best N (sine) against speed: {best}")

        md = open(os.path.join(out, "pareto.md")).read()
        for v in SPEEDS[1:]:
            assert f"## study-speed.scene, objects moving at {v:g} px/s" in md, md
        assert "## study-speed.scene\n" in md
        print("ok   study.csv speed_px_s, one front per speed")

        for bad, words in ((["--speeds", "-5"], "--speeds"), (["--speeds", "fast"], "--speeds"),
                           (["--speeds", "10", "--moving", "shark"], "shark"), (["--moving", "fish"], "--speeds")):
            p = subprocess.run([ctl, "study", "--quiet", "--no-figures", "--scene", scene, "--out", out,
                                "--phases", "4", "--averages", "1", "--seeds", "1", "--periods", "scene",
                                "--exposures", "1"] + bad, capture_output=True, text=True)
            assert p.returncode != 0 and words in p.stderr, (bad, p.returncode, p.stderr)
        print("ok   bad speeds and a missing object refused")


if __name__ == "__main__":
    main()
