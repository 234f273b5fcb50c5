#!/usr/bin/python3
"""`descatterctl study` on square stripes at the sampling limit (3 px): every configuration gets a
row, and one that cannot separate the scene says so and why instead of ending the study.
Usage: test_study_sampling_limit.py DESCATTERCTL

Independent expectations (closed form, docs/estimators.md "Sampling"):
- maxmin and robust need a pixel fully lit in some phase and fully dark in another. Square
  stripes of duty a and period P light a band aP px wide: at P = 3, a = 0.3 it is 0.9 px, under
  the whole pixel's 1 px, so no pixel is ever fully lit at any N or phase: every N is refused,
  with the precondition's reason;
- sine takes every N >= 3 on any period: scored at N = 4 and 8;
- an exposure 2000 times the scene's puts every pixel above the sensor's full well (the scene's
  brightest pixel is well within it at 1x, so at 2000x even the darkest lit one is beyond): no
  pixel is left to score, the row says `cannot-separate` with every pixel clipped, and the
  study goes on to the other configurations (exit status 0)."""
import csv
import os
import subprocess
import sys
import tempfile

SCENE = """[scene]
name=square stripes at the sampling limit
[sensor]
width=48
height=32
bit-depth=12
pixel-pitch-um=5
quantum-efficiency=0.4
system-gain=0.25
read-noise-e=6
full-well-e=20000
exposure-us=2000
[illuminator]
pattern=square
period-px=3
duty=0.3
irradiance=1
[camera]
magnification=0.05
"""


def main():
    ctl = sys.argv[1]
    with tempfile.TemporaryDirectory() as d:
        scene = os.path.join(d, "square-3px.scene")
        with open(scene, "w") as f:
            f.write(SCENE)
        out = os.path.join(d, "study")
        r = subprocess.run([ctl, "study", "-s", scene, "--phases", "2,4,8", "--averages", "1", "--exposures",
                            "1,2000", "--periods", "scene", "--seeds", "1", "--no-figures", "-q", "-o", out],
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        with open(os.path.join(out, "study.csv"), newline="") as f:
            rows = list(csv.DictReader(f))
    by = {(row["estimator"], int(row["phases"]), float(row["exposure_factor"])): row for row in rows}
    for est in ("maxmin", "robust"):
        for n in (2, 4, 8):
            for f in (1.0, 2000.0):
                row = by[(est, n, f)]
                assert row["status"] == "refused", row
                assert "fully lit" in row["reason"], row["reason"]
                assert row["rel_rmse_transmissive"] == "nan", row
    for n in (4, 8):
        row = by[("sine", n, 1.0)]
        assert row["status"] == "ok" and float(row["rel_rmse_transmissive"]) >= 0, row
    clipped = [row for row in rows if float(row["exposure_factor"]) == 2000 and row["status"] != "refused"]
    assert clipped, rows
    for row in clipped:
        assert row["status"] == "cannot-separate", row
        assert "100 % clipped" in row["reason"], row["reason"]
        assert int(row["valid"]) == 0, row
    ok = [row for row in rows if row["status"] == "ok"]
    assert all(row["reason"] == "" for row in ok)
    print("%d rows: %d scored, %d refused, %d cannot separate" % (
        len(rows), len(ok), sum(row["status"] == "refused" for row in rows), len(clipped)))


if __name__ == "__main__":
    main()
