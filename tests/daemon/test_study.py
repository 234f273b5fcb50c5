#!/usr/bin/python3
"""`descatterctl study --quick` end to end (the reduced form of the accuracy study that CI runs).
Usage: test_study.py DESCATTERCTL

Independent expectations:
- in the scene without scattering (clear-grid), averaging M = 2 frames per phase lowers the
  transmissive error (shot and read noise average down by sqrt(2)), and the systematic part
  (noise-free frames) of maxmin on sharp stripes with aN >= 1 is zero;
- that error is the shot-noise floor, a closed form: with no scattered light, max/min at N <= 4 and
  duty 0.5 takes the maximum of one or two lit samples, whose RMS deviation is the noise's sigma
  either way (E[max(X1, X2)^2] = 1 for standard normals), and sigma^2 = gain * Ld in DN. Over
  the scene the relative RMSE is then sqrt(gain * f / mean) / sqrt(M), f the open fraction of
  the wire grid and mean the truth's mean (the study's signal_dn), read noise 0.4 % of it;
- sine is unbiased under noise, so its total error is never below its systematic part; every
  estimator's noise part falls with M where noise dominates;
- forward-peaked scattering keeps more of the stripes at a coarser period (the scattering
  kernel is narrower against it): tissue-veins' systematic error grows from P to 2P for every
  estimator;
- every pixel with a number is scored: in a scene that does not clip (clear-grid) no pixel is
  left out of the error, whatever noise does to the darkest phase against the dark frame;
- the HDR scene saturates part of the sensor; those pixels are excluded (counted), and every
  one of its points on a Pareto front is flagged as clipped;
- the acquisition time follows the rig model's structure: it grows with N and M;
- a scene without scattering has no relative error of its (zero) scattered image: nan."""
import csv
import math
import os
import re
import subprocess
import sys
import tempfile


def read_scene(path):
    """The scene file's [section] key=value pairs (docs/scene-format.md)."""
    out, section = {}, None
    for line in open(path):
        line = line.split("#", 1)[0].strip()
        if line.startswith("[") and line.endswith("]"):
            section = out.setdefault(line[1:-1], {})
        elif "=" in line and section is not None:
            k, v = line.split("=", 1)
            section[k.strip()] = v.strip()
    return out


def same_but_last_digit(a, b):
    """The same page, numbers allowed one unit off in their last printed digit: study.csv keeps 6
    significant digits, and a noise part sqrt(total^2 - systematic^2) computed from them may round
    the other way."""
    num = re.compile(r"\d+\.\d+")
    if num.sub("#", a) != num.sub("#", b):
        return False
    xs, ys = num.findall(a), num.findall(b)
    return all(abs(float(x) - float(y)) <= 1.01 * 10 ** -len(x.split(".")[1]) for x, y in zip(xs, ys))


def table_rows(md):
    """Every row of pareto.md's tables as (scene, estimator, marked †, N, M, period, exposure, clipped)."""
    out, scene = [], None
    for line in md.splitlines():
        if line.startswith("## "):
            scene = line[3:].strip()
        elif line.startswith("| ") and not line.startswith("| estimator"):
            cells = [c.strip() for c in line.strip("|").split("|")]
            est = cells[0]
            out.append((scene, est.replace("†", "").strip(), "†" in est, int(cells[1]), int(cells[2]),
                        float(cells[3]), float(cells[4].rstrip("×")), "**clipped**" in cells[9]))
    return out


def check_front_marks(pareto, rows):
    """Clipped points never sit on a front unflagged, and † marks exactly the configurations whose
    sets ran with the blur unknown (study.csv's edge_blur_known), with the legend saying so."""
    assert "† marks a point whose configuration the sampling precondition refuses" in pareto, pareto[:800]
    assert "**clipped**" in pareto.split("\n## ")[0], "the legend explains the clipped flag"
    unknown, clipped = set(), set()
    for r in rows:
        key = (r["scene"], r["estimator"], int(r["phases"]), int(r["averages"]), float(r["period_px"]),
               float(r["exposure_factor"]))
        if r["edge_blur_known"] == "0":
            unknown.add(key)
        if int(r["saturated"]) > 0:
            clipped.add(key)
    listed = table_rows(pareto)
    assert listed, "no table rows in pareto.md"
    for scene, est, dagger, n, m, period, exposure, flagged in listed:
        key = (scene, est, n, m, period, exposure)
        assert dagger == (key in unknown), (key, dagger)
        assert flagged == (key in clipped), (key, flagged)


def lit_fraction(period, duty, blur, aperture=1.0, samples=401):
    """The best-placed pixel's share of the full level on the lit run of blurred square stripes
    (Gaussian edges of sigma `blur`, the pixel integrating over `aperture`): a pixel is never
    fully lit when even the one centred on the run falls short of 1."""
    def phi(z):
        return 0.5 * (1 + math.erf(z / math.sqrt(2)))
    run, total = duty * period, 0.0
    for i in range(samples):
        x = -aperture / 2 + aperture * i / (samples - 1)
        total += phi((run / 2 - x) / blur) - phi((-run / 2 - x) / blur)
    return total / samples


def blur_marks_closed_form(ctl):
    """† against the sampling precondition computed here: on tissue-veins' stripes (duty 0.5,
    edge blur 0.5 px) no pixel is fully lit at 4 px (the centred pixel reaches about 93 % of the
    level), so max/min cannot run with the blur known there and its point is marked; at 8 px it
    reaches over 99.5 % and is not; sine has no such precondition and is never marked."""
    path = os.path.join(os.environ["DESCATTER_DATA_DIR"], "scenes", "tissue-veins.scene")
    spec = read_scene(path)["illuminator"]
    duty, blur = float(spec["duty"]), float(spec["edge-blur-px"])
    for est, periods in (("maxmin", (4, 8)), ("sine", (4,))):
        with tempfile.TemporaryDirectory() as out:
            subprocess.run([ctl, "study", "--quiet", "--scene", path, "--phases", "16", "--averages", "1",
                            "--exposures", "1", "--periods", ",".join(map(str, periods)), "--seeds", "1",
                            "--estimators", est, "--out", out], check=True)
            md = open(os.path.join(out, "pareto.md")).read()
            best = md.split("Best at each stripe period")[1]
            rows = {r[5]: r for r in table_rows(best)}
            assert sorted(rows) == list(periods), (est, sorted(rows))
            for period in periods:
                lit = min(lit_fraction(period, duty, blur), lit_fraction(period, 1 - duty, blur))
                assert lit < 0.97 or lit > 0.995, (period, lit)  # clear-cut cases only
                expect = est != "sine" and lit < 0.97
                assert rows[period][2] == expect, (est, period, lit, rows[period])


def main():
    ctl = sys.argv[1]
    with tempfile.TemporaryDirectory() as out:
        subprocess.run([ctl, "study", "--quick", "--quiet", "--out", out], check=True)
        rows = list(csv.DictReader(open(os.path.join(out, "study.csv"))))
        assert rows, "no study points"
        order = list(dict.fromkeys(r["scene"] for r in rows))
        assert order == sorted(order), f"scenes not run in name order: {order}"
        scenes = set(order)
        assert {"clear-grid.scene", "milk-disc.scene", "tissue-veins.scene", "hdr-saturation.scene"} <= scenes, scenes

        def pick(scene, est, n, m, period=None):
            got = [r for r in rows if r["scene"] == scene and r["estimator"] == est and int(r["phases"]) == n
                   and int(r["averages"]) == m and (period is None or float(r["period_px"]) == period)]
            assert got, (scene, est, n, m, period)
            return got[0]

        for n in (4, 8):
            e1 = float(pick("clear-grid.scene", "maxmin", n, 1, 12)["rel_rmse_transmissive"])
            e2 = float(pick("clear-grid.scene", "maxmin", n, 2, 12)["rel_rmse_transmissive"])
            assert e2 < 0.9 * e1, f"N={n}: averaging did not reduce the error ({e1} -> {e2})"
            assert float(pick("clear-grid.scene", "maxmin", n, 1, 12)["systematic_transmissive"]) < 1e-4
            assert math.isnan(float(pick("clear-grid.scene", "maxmin", n, 1, 12)["rel_rmse_scattered"]))
        scene = read_scene(os.path.join(os.environ["DESCATTER_DATA_DIR"], "scenes", "clear-grid.scene"))
        pitch, line = float(scene["object.grid"]["pitch"]), float(scene["object.grid"]["line-width"])
        open_fraction = ((pitch - line) / pitch) ** 2
        for m in (1, 2):
            r = pick("clear-grid.scene", "maxmin", 4, m, 12)
            floor = math.sqrt(float(scene["sensor"]["system-gain"]) * open_fraction / float(r["signal_dn"]) / m)
            got = float(r["rel_rmse_transmissive"])
            assert 0.9 * floor < got < 1.1 * floor, f"clear-grid maxmin N=4 M={m}: {got} against shot noise {floor}"
        clear = [r for r in rows if r["scene"] == "clear-grid.scene"]
        assert all(int(r["masked"]) == 0 and int(r["saturated"]) == 0 for r in clear), \
            [(r["estimator"], r["phases"], r["averages"], r["masked"]) for r in clear if int(r["masked"])]
        for r in rows:
            if r["estimator"] == "sine" and r["scene"] != "hdr-saturation.scene":
                assert float(r["rel_rmse_transmissive"]) >= 0.97 * float(r["systematic_transmissive"]), r
        # The noise part is sqrt(total^2 - systematic^2): trusted where noise dominates.
        checked = 0
        for r in rows:
            if int(r["averages"]) != 1 or r["scene"] == "hdr-saturation.scene":
                continue
            n1, s1 = float(r["noise_transmissive"]), float(r["systematic_transmissive"])
            if not n1 > 2 * s1:
                continue
            n2 = float(pick(r["scene"], r["estimator"], int(r["phases"]), 2, float(r["period_px"]))["noise_transmissive"])
            assert n2 < 0.85 * n1, (r["scene"], r["phases"], n1, n2)
            checked += 1
        assert checked >= 2, checked
        tissue = sorted({float(r["period_px"]) for r in rows if r["scene"] == "tissue-veins.scene"})
        assert len(tissue) == 2 and tissue[1] == 2 * tissue[0], tissue
        for est in ("maxmin", "sine", "robust"):
            s1 = float(pick("tissue-veins.scene", est, 8, 1, tissue[0])["systematic_transmissive"])
            s2 = float(pick("tissue-veins.scene", est, 8, 1, tissue[1])["systematic_transmissive"])
            assert s2 > 1.5 * s1, (est, s1, s2)
        hdr = [r for r in rows if r["scene"] == "hdr-saturation.scene"]
        assert all(int(r["saturated"]) > 0 for r in hdr), "HDR scene did not saturate"
        assert all(int(r["masked"]) >= int(r["saturated"]) for r in hdr)
        t = {(int(r["phases"]), int(r["averages"])): float(r["acquisition_ms"]) for r in rows
             if r["scene"] == "milk-disc.scene" and r["estimator"] == "maxmin"}
        assert t[(8, 1)] > t[(4, 1)] and t[(4, 2)] > t[(4, 1)], t
        pareto = open(os.path.join(out, "pareto.md")).read()
        assert all(f"## {s}" in pareto for s in scenes)
        hdr_md = pareto.split("## hdr-saturation.scene")[1].split("\n## ")[0]
        table_rows = [line for line in hdr_md.splitlines() if line.startswith("| ") and line[2:4] != "es"]
        assert table_rows and all("**clipped**" in line for line in table_rows), hdr_md
        assert "Best at each stripe period" in pareto
        assert all(r["edge_blur_known"] in ("0", "1") for r in rows)
        check_front_marks(pareto, rows)
        # The fronts again from the CSV alone (how docs/accuracy/pareto.md gets new marks without
        # the 25-minute sweep): the same page.
        again = os.path.join(out, "again")
        subprocess.run([ctl, "study", "--fronts-from", os.path.join(out, "study.csv"), "--out", again], check=True,
                       capture_output=True)
        assert same_but_last_digit(open(os.path.join(again, "pareto.md")).read(), pareto), \
            "--fronts-from wrote other fronts"
        bad = os.path.join(out, "bad.csv")
        lines = open(os.path.join(out, "study.csv")).read().splitlines()
        cells = lines[2].split(",")
        cells[2] = "four"
        open(bad, "w").write("\n".join(lines[:2] + [",".join(cells)]) + "\n")
        r = subprocess.run([ctl, "study", "--fronts-from", bad, "--out", os.path.join(out, "bad")],
                           capture_output=True, text=True)
        assert r.returncode == 1 and f"{bad}:3: column phases" in r.stderr, r.stderr
        assert not os.path.exists(os.path.join(out, "bad", "pareto.md")), "a bad CSV wrote fronts"
    # The sets know the scene's edge blur, as descatterd's with [illuminator] edge-blur-px: robust's
    # windows then stay inside the fully lit and fully dark runs at any N, where every noise-free
    # sample equals the level max/min picks, so its systematic part is max/min's. milk-disc (6 px,
    # blur 0.5 px) at N = 32: with the one-phase margin of an unknown blur it was 0.20 against 0.017.
    with tempfile.TemporaryDirectory() as out:
        scene = os.path.join(os.environ["DESCATTER_DATA_DIR"], "scenes", "milk-disc.scene")
        subprocess.run([ctl, "study", "--quiet", "--scene", scene, "--phases", "32", "--averages", "1",
                        "--exposures", "1", "--periods", "scene", "--seeds", "1", "--estimators", "maxmin,robust",
                        "--out", out], check=True)
        got = {r["estimator"]: r for r in csv.DictReader(open(os.path.join(out, "study.csv")))}
        assert got["robust"]["edge_blur_known"] == "1", got["robust"]
        sys_maxmin = float(got["maxmin"]["systematic_transmissive"])
        sys_robust = float(got["robust"]["systematic_transmissive"])
        assert sys_robust < 1.05 * sys_maxmin + 1e-4, (sys_robust, sys_maxmin)
    blur_marks_closed_form(ctl)
    print("study: ok")


if __name__ == "__main__":
    main()
