#!/usr/bin/python3
"""`descatterctl study --quick` end to end (the reduced form of the accuracy study that CI runs).
Usage: test_study.py DESCATTERCTL

Independent expectations:
- in the noise-free-systematics scene (clear-grid: no scattering), averaging M = 2 frames per
  phase lowers the transmissive error (shot and read noise average down by sqrt(2));
- the HDR scene saturates part of the sensor, and those pixels are excluded (counted);
- the acquisition time follows the rig model's structure: doubling N at M = 1 more than
  doubles nothing else, i.e. time grows with N and M;
- the operating model the study writes loads and has a row per scene and configuration."""
import csv
import os
import subprocess
import sys
import tempfile


def main():
    ctl = sys.argv[1]
    with tempfile.TemporaryDirectory() as out:
        subprocess.run([ctl, "study", "--quick", "--quiet", "--out", out], check=True)
        rows = list(csv.DictReader(open(os.path.join(out, "study.csv"))))
        assert rows, "no study points"
        scenes = {r["scene"] for r in rows}
        assert {"clear-grid.scene", "milk-disc.scene", "tissue-veins.scene", "hdr-saturation.scene"} <= scenes, scenes

        def err(scene, est, n, m):
            return [float(r["rel_rmse_transmissive"]) for r in rows
                    if r["scene"] == scene and r["estimator"] == est and int(r["phases"]) == n and int(r["averages"]) == m]

        for n in (4, 8):
            e1, e2 = err("clear-grid.scene", "maxmin", n, 1)[0], err("clear-grid.scene", "maxmin", n, 2)[0]
            assert e2 < 0.9 * e1, f"N={n}: averaging did not reduce the error ({e1} -> {e2})"
        hdr = [r for r in rows if r["scene"] == "hdr-saturation.scene"]
        assert all(int(r["saturated"]) > 0 for r in hdr), "HDR scene did not saturate"
        assert all(int(r["masked"]) >= int(r["saturated"]) for r in hdr)
        t = {(int(r["phases"]), int(r["averages"])): float(r["acquisition_ms"]) for r in rows
             if r["scene"] == "milk-disc.scene" and r["estimator"] == "maxmin"}
        assert t[(8, 1)] > t[(4, 1)] and t[(4, 2)] > t[(4, 1)], t
        model = open(os.path.join(out, "operating-model.csv")).read().splitlines()
        assert model[0].startswith("# descatter operating model") and "safety=" in model[0]
        assert len(model) - 2 == len({(r["scene"], r["estimator"], r["phases"], r["averages"]) for r in rows})
        pareto = open(os.path.join(out, "pareto.md")).read()
        assert all(f"## {s}" in pareto for s in scenes)
    print("study: ok")


if __name__ == "__main__":
    main()
