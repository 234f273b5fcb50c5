#!/usr/bin/python3
"""The per-scene tables of docs/records/accuracy-validation.md, "What the measurements say" (whose
findings docs/accuracy.md, "What the measurements say", quotes), from `descatterctl study` output:
    /usr/bin/python3 tools/study_tables.py STUDY_DIR
prints Markdown: the error of each component against N (M = 1, base exposure, the first period
of --periods: the scene's own by default), how the noise part falls with M and with exposure,
the error at each stripe period, and the clipped configurations. Seeds are averaged; every
number is read from STUDY_DIR/study.csv."""
import math
import sys

from study_csv import load, noise_part


def fmt(v, digits=4):
    return "–" if not math.isfinite(v) else f"{v:.{digits}f}"


def mark(v):
    """† where the sets did not know the edge blur: the sampling precondition refused the
    configuration with it, and the point is what descatterd does without edge-blur-px."""
    return "" if v.get("blur_known", True) else " †"


BLUR_NOTE = ("Sets know the scene's edge blur (robust's margin from the period and the blur, as descatterd "
             "with `[illuminator] edge-blur-px`); † marks a point whose configuration the sampling "
             "precondition refuses with the blur known, run with the period alone (the blur unknown), "
             "as descatterd without edge-blur-px runs it.")


def short(scene):
    return scene.replace(".scene", "")


def slope(points):
    """Least-squares slope of log(y) against log(x)."""
    pts = [(math.log(x), math.log(y)) for x, y in points if x > 0 and y > 0 and math.isfinite(y)]
    if len(pts) < 2:
        return float("nan")
    mx = sum(p[0] for p in pts) / len(pts)
    my = sum(p[1] for p in pts) / len(pts)
    sxx = sum((p[0] - mx) ** 2 for p in pts)
    return sum((p[0] - mx) * (p[1] - my) for p in pts) / sxx if sxx else float("nan")


def by_n(data, first_period, comp):
    name = "transmissive" if comp == "t" else "scattered"
    total, sys_ = (f"rel_rmse_{name}", f"systematic_{name}")
    ns = sorted({k.phases for k in data})
    print(f"\nRelative RMSE of **{name}**, total / systematic part, M = 1, base exposure, scene's own period "
          "(† blur unknown):\n")
    print("| scene (period) | estimator | " + " | ".join(f"N = {n}" for n in ns) + " |")
    print("|---|---|" + "---|" * len(ns))
    for scene in sorted(first_period):
        p = first_period[scene]
        for est in sorted({k.estimator for k in data if k.scene == scene}):
            cells = []
            for n in ns:
                v = data.get((scene, est, n, 1, 1.0, p))
                cells.append("" if v is None else f"{fmt(v[total])} / {fmt(v[sys_])}{mark(v)}")
            print(f"| {short(scene)} ({p:g} px) | {est} | " + " | ".join(cells) + " |")


def averaging(data, first_period):
    print("\nNoise part of transmissive (sqrt(total² − systematic²)) at the scene's own period, N = 8, and "
          "its log-log slope against M (base exposure) and against exposure (M = 1), clipped points left "
          "out of the slopes, and no slope where the noise part at M = 1 is below a quarter of the systematic part; −0.5 is 1/√:\n")
    ms = sorted({k.averages for k in data})
    es = sorted({k.exposure for k in data})
    cols = [(m, 1.0) for m in ms] + [(1, e) for e in es if e != 1.0]
    print("| scene | estimator | " + " | ".join(f"M = {m}, {e:g}×" for m, e in cols) +
          " | slope vs M | slope vs exposure |")
    print("|---|---|" + "---|" * (len(cols) + 2))
    for scene in sorted(first_period):
        p = first_period[scene]
        for est in sorted({k.estimator for k in data if k.scene == scene}):
            def clipped(m, e):
                return data.get((scene, est, 8, m, e, p), {}).get("saturated", 0) > 0

            def nz(m, e, unclipped_only=False):
                v = data.get((scene, est, 8, m, e, p))
                if v is None or (unclipped_only and clipped(m, e)):
                    return float("nan")
                return noise_part(v["rel_rmse_transmissive"], v["systematic_transmissive"])
            # Where the systematic part dominates, sqrt(total² − systematic²) is the difference of
            # two close numbers and no measure of noise: no slope there.
            base = data.get((scene, est, 8, 1, 1.0, p))
            trusted = base is not None and nz(1, 1.0) > 0.25 * base["systematic_transmissive"]
            sm = slope([(m, nz(m, 1.0, True)) for m in ms]) if trusted else float("nan")
            se = slope([(e, nz(1, e, True)) for e in es]) if trusted else float("nan")
            print(f"| {short(scene)} | {est} | " +
                  " | ".join(fmt(nz(m, e)) + (" clipped" if clipped(m, e) else "") for m, e in cols) +
                  f" | {fmt(sm, 2)} | {fmt(se, 2)} |")


def periods(data, first_period):
    print("\nAt each stripe period: the smallest systematic part of transmissive (any estimator and N, base "
          "exposure: what no averaging removes), and the best unclipped configuration (any estimator, N, M, "
          "exposure) with its noise + systematic parts and its time († blur unknown):\n")
    print("| scene | period (px) | systematic floor (estimator, N) | best total (noise + systematic) | "
          "estimator, N, M, exposure | time (ms) |")
    print("|---|---|---|---|---|---|")
    for scene in sorted(first_period):
        for p in sorted({k.period for k in data if k.scene == scene}):
            keys = [k for k in data if k.scene == scene and k.period == p]
            base = [k for k in keys if k.exposure == 1.0]
            if not base:
                continue
            floor = min(base, key=lambda k: data[k]["systematic_transmissive"])
            ok = [k for k in keys if not data[k]["saturated"]]
            best = min(ok or keys, key=lambda k: data[k]["rel_rmse_transmissive"])
            total, sys_ = data[best]["rel_rmse_transmissive"], data[best]["systematic_transmissive"]
            print(f"| {short(scene)} | {p:g}{' (own)' if p == first_period[scene] else ''} | "
                  f"{fmt(data[floor]['systematic_transmissive'])} ({floor.estimator}, {floor.phases}){mark(data[floor])} | "
                  f"{fmt(total)} ({fmt(noise_part(total, sys_))} + {fmt(sys_)}){'' if ok else ' clipped'}{mark(data[best])} | "
                  f"{best.estimator}, {best.phases}, {best.averages}, {best.exposure:g}× | "
                  f"{data[best]['acquisition_ms']:.1f} |")


def clipping(data, first_period):
    print("\nClipped configurations (some frame reaches the clip level; their error leaves those pixels out):\n")
    print("| scene | exposure | clipped / configurations | clipped pixels (max) |")
    print("|---|---|---|---|")
    for scene in sorted(first_period):
        for e in sorted({k.exposure for k in data if k.scene == scene}):
            keys = [k for k in data if k.scene == scene and k.exposure == e]
            clipped = [k for k in keys if data[k]["saturated"]]
            worst = max((data[k]["saturated"] for k in keys), default=0)
            pixels = data[keys[0]]["pixels"]
            print(f"| {short(scene)} | {e:g}× | {len(clipped)} / {len(keys)} | {worst} "
                  f"({100.0 * worst / pixels:.1f} %) |")


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: study_tables.py STUDY_DIR")
    data, first_period = load(sys.argv[1])
    print("\n" + BLUR_NOTE)
    by_n(data, first_period, "t")
    by_n(data, first_period, "g")
    averaging(data, first_period)
    periods(data, first_period)
    clipping(data, first_period)


if __name__ == "__main__":
    main()
