#!/usr/bin/python3
"""What `descatterctl study` writes, read by third-party readers: study.csv through Python's csv
module (and pandas when installed), the figures through Pillow (PNG) and xml.etree (SVG).
Usage: test_study_files.py DESCATTERCTL SCENE

The scene is copied to a file whose name holds a comma and double quotes, so the scene column
needs RFC 4180 quoting. Independent expectations:
- every row has the header's columns and the scene column reads back as the file name itself;
- a CSV written by Python's csv module (every field quoted, CRLF line ends) is read back by
  --fronts-from: pareto.md names the scene as it is; a quote left open is refused naming the
  file and line, and no pareto.md appears;
- each figure exists as a valid PNG (Pillow verifies it) and SVG (it parses); the axes say what
  they show with units: time in ms, error in %, period in px;
- the points marked on the error-against-time figure's Pareto front are exactly the
  configurations of the CSV that no other configuration dominates (seeds averaged; dominance
  checked pairwise here, not by the study's sort), and their markers lie in the order of their
  times and errors (left to right faster to slower, top to bottom less to more accurate)."""
import collections
import csv
import os
import re
import shutil
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET

from PIL import Image

CTL, SCENE = sys.argv[1], sys.argv[2]
NAME = 'clear, "grid".scene'
STEM = 'clear, "grid"'
SVG = "{http://www.w3.org/2000/svg}"
XLINK = "{http://www.w3.org/1999/xlink}"


def read_rows(path):
    with open(path, newline="") as f:
        reader = csv.reader(f)
        header = next(reader)
        rows = list(reader)
    assert rows, "no rows"
    for i, r in enumerate(rows):
        assert len(r) == len(header), f"row {i + 2}: {len(r)} fields, the header has {len(header)}: {r}"
    return [dict(zip(header, r)) for r in rows], header


def non_dominated(rows):
    """{(estimator, N, M, exposure factor, period)} that no other configuration beats in both
    acquisition time and transmissive error (at least as good in both, better in one)."""
    by = collections.defaultdict(list)
    for r in rows:
        k = (r["estimator"], int(r["phases"]), int(r["averages"]), float(r["exposure_factor"]), float(r["period_px"]))
        by[k].append((float(r["acquisition_ms"]), float(r["rel_rmse_transmissive"])))
    pts = {k: (sum(t for t, _ in v) / len(v), sum(e for _, e in v) / len(v)) for k, v in by.items()}
    out = {}
    for k, (t, e) in pts.items():
        if not any((t2 <= t and e2 <= e and (t2 < t or e2 < e)) for k2, (t2, e2) in pts.items() if k2 != k):
            out[k] = (t, e)
    return out


def svg_texts(root):
    return ["".join(t.itertext()) for t in root.iter(SVG + "text")]


def check_png(path):
    with Image.open(path) as im:
        im.verify()
    with Image.open(path) as im:
        assert im.format == "PNG" and im.size[0] > 200 and im.size[1] > 200, (path, im.format, im.size)


def check_figure(out, name, xlabel_re, ylabel_re):
    check_png(os.path.join(out, name + ".png"))
    root = ET.parse(os.path.join(out, name + ".svg")).getroot()
    assert root.tag == SVG + "svg", root.tag
    texts = svg_texts(root)
    assert any(re.search(xlabel_re, t) for t in texts), (name, "x label", texts)
    assert any(re.search(ylabel_re, t) for t in texts), (name, "y label", texts)
    return root


def marked_front(root):
    """{(estimator, N, M, exposure, period): (x, y) of its marker in the SVG}."""
    out = {}
    pat = re.compile(r"pareto_(\w+)_N(\d+)_M(\d+)_E([\d.e+-]+)_P([\d.e+-]+)$")
    for g in root.iter(SVG + "g"):
        m = pat.match(g.get("id", ""))
        if not m:
            continue
        uses = list(g.iter(SVG + "use"))
        assert len(uses) == 1, (g.get("id"), len(uses))
        k = (m.group(1), int(m.group(2)), int(m.group(3)), float(m.group(4)), float(m.group(5)))
        out[k] = (float(uses[0].get("x")), float(uses[0].get("y")))
    return out


def main():
    with tempfile.TemporaryDirectory() as tmp:
        scene = os.path.join(tmp, NAME)
        shutil.copy(SCENE, scene)
        out = os.path.join(tmp, "out")
        subprocess.run([CTL, "study", "--quick", "--quiet", "--scene", scene, "--out", out], check=True)

        rows, header = read_rows(os.path.join(out, "study.csv"))
        assert {r["scene"] for r in rows} == {NAME}, {r["scene"] for r in rows}
        print(f"ok   study.csv: {len(rows)} rows of {len(header)} columns, the scene named {NAME!r}")
        try:
            import pandas
        except ImportError:
            print("skip pandas is not installed")
        else:
            df = pandas.read_csv(os.path.join(out, "study.csv"))
            assert list(df.columns) == header and len(df) == len(rows) and set(df["scene"]) == {NAME}
            print("ok   pandas reads study.csv")

        root = check_figure(out, f"error-vs-time-{STEM}", r"acquisition time.*\(ms", r"RMSE.*\(%\)")
        check_figure(out, f"error-vs-period-{STEM}", r"stripe period.*\(px\)", r"RMSE.*\(%\)")
        check_figure(out, f"error-vs-n-{STEM}", r"phases N", r"RMSE.*\(%\)")
        check_figure(out, f"examples-{STEM}", r"x \(px\)", r"y \(px\)")
        print("ok   figures: valid PNG and SVG, axes labelled with units")

        want = non_dominated(rows)
        got = marked_front(root)
        assert set(got) == set(want), f"marked {sorted(got)}, non-dominated {sorted(want)}"
        order = sorted(want, key=lambda k: want[k])
        xs = [got[k][0] for k in order]
        ys = [got[k][1] for k in order]
        assert xs == sorted(xs) and ys == sorted(ys), (xs, ys)  # faster first; SVG y grows downwards
        print(f"ok   the Pareto front marked: {len(got)} non-dominated configurations, in place")

        # Python's csv module writes, descatterctl reads.
        mine = os.path.join(tmp, "written-by-python.csv")
        with open(mine, "w", newline="") as f:
            w = csv.writer(f, quoting=csv.QUOTE_ALL)
            w.writerow(header)
            for r in rows:
                w.writerow([r[c] for c in header])
        again = os.path.join(tmp, "again")
        r = subprocess.run([CTL, "study", "--fronts-from", mine, "--out", again, "--no-figures"],
                           capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        md = open(os.path.join(again, "pareto.md"), encoding="utf-8").read()
        assert f"\n## {NAME}\n" in md, md[:2000]
        print("ok   --fronts-from reads a CSV Python's csv module wrote (all quoted, CRLF)")

        bad = os.path.join(tmp, "bad.csv")
        text = open(mine, newline="").read().split("\r\n")
        text[3] = text[3].replace('""grid""', '"grid', 1)  # the scene's field: a quote closes it early
        open(bad, "w", newline="").write("\r\n".join(text[:4]) + '\r\n"unclosed,1\r\n')
        r = subprocess.run([CTL, "study", "--fronts-from", bad, "--out", os.path.join(tmp, "bad")],
                           capture_output=True, text=True)
        assert r.returncode == 1 and re.search(re.escape(bad) + r":4: text after a quoted field", r.stderr), r.stderr
        assert not os.path.exists(os.path.join(tmp, "bad", "pareto.md")), "a bad CSV wrote fronts"
        open(bad, "w", newline="").write("\r\n".join(text[:3]) + '\r\n"unclosed,1\r\n')
        r = subprocess.run([CTL, "study", "--fronts-from", bad, "--out", os.path.join(tmp, "bad")],
                           capture_output=True, text=True)
        assert r.returncode == 1 and f"{bad}:4: a quoted field is never closed" in r.stderr, r.stderr
        print("ok   a broken CSV is refused naming file and line")
    print("study files: ok")


if __name__ == "__main__":
    main()
