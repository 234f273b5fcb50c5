#!/usr/bin/python3
"""`descatterctl validate` and `generate-scenes` in reduced form (the full run: docs/accuracy.md).
Usage: test_validate.py DESCATTERCTL DESCATTER-SIM

Independent expectations:
- generated scenes are valid scene files: the simulator's own `describe` loads each of them;
  the generator is deterministic (same seed, same text) and a seed changes the scenes;
- every automatic capture of the validation (two shipped scenes, leave one scene out) is right
  by the issue's measure, recomputed here from the CSV's numbers rather than taken from its
  verdict column: the achieved error within a factor 1.5 of the predicted one, or a refusal
  whose best reachable configuration indeed misses the target;
- --fit writes an operating model that names the scenes it was fitted on, with a scale in its
  documented range.
Generated scenes are validated by the full run only (each renders its medium by Monte Carlo at
several periods: minutes per scene): its command and totals are in docs/accuracy.md, "Validation",
its per-scene tables in docs/records/accuracy-validation.md."""
import csv
import os
import subprocess
import sys
import tempfile


def main():
    ctl, sim = sys.argv[1], sys.argv[2]
    data = os.environ["DESCATTER_DATA_DIR"]
    with tempfile.TemporaryDirectory() as out:
        a, b, c = (os.path.join(out, x) for x in ("a", "b", "c"))
        for d, seed in ((a, "11"), (b, "11"), (c, "12")):
            subprocess.run([ctl, "generate-scenes", "--count", "2", "--seed", seed, "--out", d], check=True,
                           stdout=subprocess.DEVNULL)
        for name in sorted(os.listdir(a)):
            assert open(os.path.join(a, name)).read() == open(os.path.join(b, name)).read(), name
            subprocess.run([sim, "describe", os.path.join(a, name)], check=True, stdout=subprocess.DEVNULL)
        assert sorted(os.listdir(a)) != sorted(os.listdir(c))

        v = os.path.join(out, "v")
        subprocess.run([ctl, "validate", "--quiet", "--scene", os.path.join(data, "scenes", "clear-grid.scene"),
                        "--scene", os.path.join(data, "scenes", "milk-disc.scene"), "--seed", "7",
                        "--targets", "0.03,0.1", "--budgets", "60", "--fit", "--out", v], check=True)
        rows = list(csv.DictReader(open(os.path.join(v, "validation.csv"))))
        assert len(rows) == 6, rows
        for r in rows:
            if r["outcome"] == "chosen":
                ratio = float(r["achieved"]) / float(r["predicted"])
                assert 1 / 1.5 <= ratio <= 1.5, (r["scene"], r["predicted"], r["achieved"])
            elif r["outcome"] == "refused" and r["estimator"]:
                assert float(r["achieved"]) > float(r["target_error"]), (r["scene"], r["achieved"])
        model = open(os.path.join(v, "operating-model.conf")).read()
        assert "fitted-on=clear-grid.scene;milk-disc.scene" in model, model
        scale = float([l for l in model.splitlines() if l.startswith("scale=")][0].split("=")[1])
        assert 0.5 <= scale <= 2
        md = open(os.path.join(v, "validation.md")).read()
        assert "leave one scene out" in md

        # --shipped: every shipped scene, in the order of their names (the order the leave-one-out
        # fit and the committed tables depend on), whatever the directory listing's order.
        shipped = sorted(n for n in os.listdir(os.path.join(data, "scenes"))
                         if n.endswith(".scene") and "1024" not in n)
        w = os.path.join(out, "w")
        subprocess.run([ctl, "validate", "--quiet", "--shipped", "--targets", "0.3", "--budgets", "none",
                        "--out", w], check=True)
        seen = []
        for r in csv.DictReader(open(os.path.join(w, "validation.csv"))):
            if not seen or seen[-1] != r["scene"]:
                seen.append(r["scene"])
        assert seen == shipped, (seen, shipped)
    print("validate: ok")


if __name__ == "__main__":
    main()
