#!/usr/bin/python3
"""tools/validate_paths.py in reduced form (the full run: docs/accuracy.md, "Validation"): both
start-up paths on one clear shipped scene and one generated scene, a few requests; well under a
minute of acquisition.
Usage: test_validate_paths.py TOOL BINDIR SCENE

Independent expectations:
- the error metric: relative RMSE against closed forms (an estimate 10 % high everywhere is 0.1;
  pixels flagged saturated, non-finite or dark-exceeds are left out, other flags are not);
- a clear scene (no medium, nothing to hide the stripes) is predicted within the factor on both
  paths: its error is noise and sampling only, which the model holds in closed form;
- every verdict of the CSV follows from its numbers by the issue's measure, recomputed here;
- the simulated lab's frames are all right, so the phase check drops none of them;
- the report's per-path totals are the CSV's, counted here, and so is its split by the medium a
  generated scene draws (the description's last clause, read here);
- the generated scene comes from generator version 2 (its description says so)."""
import csv
import importlib.util
import json
import os
import subprocess
import sys
import tempfile


def check_metric(tool):
    import numpy
    spec = importlib.util.spec_from_file_location("validate_paths", tool)
    vp = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(vp)
    truth = numpy.linspace(10, 100, 64).reshape(8, 8)
    mask = numpy.zeros((8, 8), dtype=numpy.uint8)
    assert abs(vp.relative_rmse(truth * 1.1, truth, mask) - 0.1) < 1e-12
    est = truth * 1.1
    est[0, 0], mask[0, 0] = 1e6, 1      # saturated: left out
    est[0, 1], mask[0, 1] = 1e6, 32     # dark exceeds: left out
    est[0, 2], mask[0, 2] = numpy.nan, 8
    assert abs(vp.relative_rmse(est, truth, mask) - 0.1) < 1e-12
    mask[0, 3] = 2                      # dark: kept, and its error counts
    est[0, 3] = truth[0, 3] * 3
    keep = numpy.ones((8, 8), bool)
    keep[0, :3] = False
    d = (est - truth)[keep]
    expect = (numpy.sum(d * d) / numpy.sum(truth[keep] ** 2)) ** 0.5
    assert abs(vp.relative_rmse(est, truth, mask) - expect) < 1e-12


def main():
    tool, bindir, clear = sys.argv[1], sys.argv[2], sys.argv[3]
    check_metric(tool)
    with tempfile.TemporaryDirectory() as out:
        env = dict(os.environ)
        env.setdefault("DESCATTER_CACHE_DIR", os.path.join(out, "cache"))
        a, b = os.path.join(out, "a"), os.path.join(out, "b")
        subprocess.run([sys.executable, tool, "--bin", bindir, "--scene", clear, "--targets", "0.1", "--budgets", "60",
                        "--out", a], check=True, env=env)
        # A development seed (never a held-out one: docs/accuracy.md); a budget alone keeps it short.
        subprocess.run([sys.executable, tool, "--bin", bindir, "--generator", "2", "--seeds", "500", "--count", "1",
                        "--targets", "none", "--budgets", "40", "--out", b], check=True, env=env)
        scene = [f for f in os.listdir(os.path.join(b, "scenes")) if f.endswith(".scene")]
        assert scene == ["gen-500-00.scene"], scene
        assert "description=generator 2:" in open(os.path.join(b, "scenes", scene[0])).read()
        rows = []
        for d in (a, b):
            rows += list(csv.DictReader(open(os.path.join(d, "paths.csv"))))
            for path, (frames, dropped) in json.load(open(os.path.join(d, "phase.json"))).items():
                assert frames > 0 and dropped == 0, (d, path, frames, dropped)
        assert {(r["scene"], r["path"]) for r in rows} == {
            (os.path.basename(clear), "sim"), (os.path.basename(clear), "rig"), (scene[0], "sim"), (scene[0], "rig")}
        for r in rows:
            if r["outcome"] == "chosen":
                ratio = float(r["achieved"]) / float(r["predicted"])
                assert (r["verdict"] == "ok") == (1 / 1.5 <= ratio <= 1.5), r
            if r["scene"] == os.path.basename(clear):
                assert r["outcome"] == "chosen" and r["verdict"] == "ok", r
        for d in (a, b):
            sel = list(csv.DictReader(open(os.path.join(d, "paths.csv"))))
            md = open(os.path.join(d, "paths.md")).read()
            for path in ("sim", "rig"):
                mine = [r for r in sel if r["path"] == path]
                ok = sum(r["verdict"] == "ok" for r in mine)
                assert f"| {len(mine)} | {ok} | {100 * ok / len(mine):.0f} % |" in md, (path, md)
                if d == a:
                    medium = "not generated"
                else:
                    text = open(os.path.join(b, "scenes", scene[0])).read()
                    line = [x for x in text.splitlines() if x.startswith("description=")][0]
                    medium = line.rsplit(", ", 1)[1].strip()
                assert all(r["medium"] == medium for r in mine), (path, medium)
                assert f"| {medium} | {len(mine)} | {ok} | {100 * ok / len(mine):.0f} % |" in md, (path, medium, md)
    print("validate-paths: ok")


if __name__ == "__main__":
    main()
