"""The figures of `descatterctl study` (docs/operations.md, "Study figures"), which runs this
with Debian's python3 and matplotlib after it wrote study.csv and pareto.md:
    /usr/bin/python3 /usr/share/descatter/plot_study.py STUDY.CSV OUT_DIR
(installed under the data dir, found there by descatterctl; from a source tree etc/). Writes,
per scene, each as PNG and SVG:
  error-vs-time-<scene>    transmissive (solid) and scattered (dashed) error against
                           acquisition time, one curve per estimator (for each time the best
                           configuration of that estimator, seeds averaged); points whose
                           frames clip are hollow and join no curve; the scene's Pareto front
                           of pareto.md (no other configuration both faster and more accurate
                           in transmissive) marked with black diamonds, each marker's SVG id
                           naming its configuration (pareto_<estimator>_N<n>_M<m>_E<exposure
                           factor>_P<period px>);
  error-vs-period-<scene>  the best transmissive error at each stripe period with its noise
                           and systematic parts: which period the medium needs;
  error-vs-n-<scene>       transmissive error against N at M = 1, base exposure, the first
                           period of --periods, with its systematic part dotted;
  error-vs-n-speed-<scene> with --speeds: transmissive error against N at each speed (M = 1,
                           base exposure, first period), the lowest error of each curve
                           starred: how the best N falls as objects move faster;
  examples-<scene>         the example previews of OUT_DIR/examples (when there are any), each
                           titled with estimator, N and component, axes in pixels.
The first three figures draw the scene's lowest speed (still, unless every speed moves).
Errors are relative RMSEs against the simulator's truth (a moving scene's at each set's
middle), drawn in percent."""
import collections
import csv
import glob
import math
import os
import re
import sys

import matplotlib

matplotlib.use("Agg")
matplotlib.rcParams["svg.fonttype"] = "none"  # text stays text in the SVG (searchable, parseable)
matplotlib.rcParams["svg.hashsalt"] = "descatter"  # the same CSV gives the same SVG
import matplotlib.pyplot as plt  # noqa: E402

Key = collections.namedtuple("Key", "scene estimator phases averages exposure period speed")
TIME_LABEL = "acquisition time per set (ms, rig timing model)"
ERROR_LABEL = "relative RMSE against the truth (%)"


def number(text):
    try:
        return float(text)
    except ValueError:
        return float("nan")


def load(csv_path):
    """{Key: {column: mean over seeds}}, "saturated" the most clipped pixels of any seed, and
    {scene: the period of its first row} (the scene's own period with the default --periods)."""
    seeds, first_period = collections.defaultdict(list), {}
    with open(csv_path, newline="") as f:
        for row in csv.DictReader(f):
            if row.get("status", "ok") != "ok":
                continue  # a configuration that could not separate the scene: no error to plot
            first_period.setdefault(row["scene"], float(row["period_px"]))
            # speed_px_s: absent from a CSV written before the speed axis (still scenes).
            k = Key(row["scene"], row["estimator"], int(row["phases"]), int(row["averages"]),
                    float(row["exposure_factor"]), float(row["period_px"]), float(row.get("speed_px_s") or 0))
            seeds[k].append(row)
    data = {}
    for k, rows in seeds.items():
        c = {col: sum(number(r[col]) for r in rows) / len(rows)
             for col in ("rel_rmse_transmissive", "rel_rmse_scattered", "systematic_transmissive", "acquisition_ms")}
        c["saturated"] = max(int(r["saturated"]) for r in rows)
        data[k] = c
    return data, first_period


def noise_part(total, systematic):
    if not (math.isfinite(total) and math.isfinite(systematic)):
        return float("nan")
    return math.sqrt(max(0.0, total * total - systematic * systematic))


def front(points):
    """(time, error, ...) tuples -> those no faster-or-as-fast point beats in error, by time:
    pareto.md's rule (sorted by time then error, each kept when it is more accurate than every
    one before it)."""
    out, best = [], float("inf")
    for p in sorted(points, key=lambda p: (p[0], p[1])):
        if p[1] < best:
            best = p[1]
            out.append(p)
    return out


def save(fig, out_dir, name):
    fig.tight_layout()
    fig.savefig(os.path.join(out_dir, name + ".png"), dpi=110)
    fig.savefig(os.path.join(out_dir, name + ".svg"), metadata={"Date": None})
    plt.close(fig)


def error_vs_time(scene, rows, out_dir, stem):
    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    for i, est in enumerate(sorted({k.estimator for k in rows})):
        colour = f"C{i}"
        mine = [v for k, v in rows.items() if k.estimator == est]
        for comp, style in (("transmissive", "-"), ("scattered", "--")):
            pts = [(v["acquisition_ms"], 100 * v[f"rel_rmse_{comp}"]) for v in mine
                   if not v["saturated"] and math.isfinite(v[f"rel_rmse_{comp}"])]
            f = front(pts)
            if f:
                ax.plot([p[0] for p in f], [p[1] for p in f], style, marker="o", ms=3, color=colour,
                        label=f"{est} {comp}")
        clipped = [(v["acquisition_ms"], 100 * v["rel_rmse_transmissive"]) for v in mine
                   if v["saturated"] and math.isfinite(v["rel_rmse_transmissive"])]
        if clipped:
            ax.scatter([p[0] for p in clipped], [p[1] for p in clipped], s=14, facecolors="none",
                       edgecolors=colour, label=f"{est}: clipped frames")
    pareto = front([(v["acquisition_ms"], 100 * v["rel_rmse_transmissive"], k) for k, v in rows.items()
                    if math.isfinite(v["rel_rmse_transmissive"])])
    ax.plot([p[0] for p in pareto], [p[1] for p in pareto], color="black", lw=0.8, alpha=0.5, drawstyle="steps-post",
            label="Pareto front (transmissive, pareto.md)")
    for t, e, k in pareto:
        ax.plot([t], [e], "D", ms=6, mfc="none", mec="black", mew=1.2,
                gid=f"pareto_{k.estimator}_N{k.phases}_M{k.averages}_E{k.exposure:g}_P{k.period:g}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(TIME_LABEL)
    ax.set_ylabel(ERROR_LABEL)
    ax.set_title(f"{scene}: error against acquisition time")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    save(fig, out_dir, f"error-vs-time-{stem}")


def error_vs_period(scene, rows, out_dir, stem):
    best = []
    for p in sorted({k.period for k in rows}):
        cand = [v for k, v in rows.items() if k.period == p and math.isfinite(v["rel_rmse_transmissive"])]
        if not cand:
            continue
        b = min([v for v in cand if not v["saturated"]] or cand, key=lambda v: v["rel_rmse_transmissive"])
        t, sys_t = b["rel_rmse_transmissive"], b["systematic_transmissive"]
        best.append((p, 100 * t, 100 * noise_part(t, sys_t), 100 * sys_t, b["saturated"] > 0))
    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    ax.plot([b[0] for b in best], [b[1] for b in best], marker="o", label="best total")
    ax.plot([b[0] for b in best], [b[2] for b in best], "--", marker=".", label="its noise part")
    ax.plot([b[0] for b in best], [b[3] for b in best], ":", marker=".", label="its systematic part")
    for b in best:
        if b[4]:
            ax.annotate("clipped", (b[0], b[1]), fontsize=7)
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xlabel("stripe period on the sensor (px)")
    ax.set_ylabel("transmissive " + ERROR_LABEL)
    ax.set_title(f"{scene}: best error at each stripe period")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    save(fig, out_dir, f"error-vs-period-{stem}")


def error_vs_n(scene, rows, own, out_dir, stem):
    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    for i, est in enumerate(sorted({k.estimator for k in rows})):
        pts = sorted((k.phases, 100 * v["rel_rmse_transmissive"], 100 * v["systematic_transmissive"])
                     for k, v in rows.items()
                     if k.estimator == est and k.averages == 1 and k.exposure == 1.0 and k.period == own)
        if pts:
            ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", color=f"C{i}", label=est)
            ax.plot([p[0] for p in pts], [p[2] for p in pts], ":", color=f"C{i}", label=f"{est} systematic")
    ax.set_xlabel(f"phases N (count; M = 1, base exposure, period {own:g} px)")
    ax.set_ylabel("transmissive " + ERROR_LABEL)
    ax.set_title(f"{scene}: error against N")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    save(fig, out_dir, f"error-vs-n-{stem}")


def error_vs_n_speed(scene, rows, own, out_dir, stem):
    speeds = sorted({k.speed for k in rows})
    ests = sorted({k.estimator for k in rows})
    styles = ("-", "--", ":", "-.")
    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    for i, v in enumerate(speeds):
        for j, est in enumerate(ests):
            pts = sorted((k.phases, 100 * val["rel_rmse_transmissive"]) for k, val in rows.items()
                         if k.speed == v and k.estimator == est and k.averages == 1 and k.exposure == 1.0
                         and k.period == own and math.isfinite(val["rel_rmse_transmissive"]))
            if not pts:
                continue
            ax.plot([p[0] for p in pts], [p[1] for p in pts], styles[j % len(styles)], marker="o", ms=3,
                    color=f"C{i}", label=f"{est}, {v:g} px/s")
            best = min(pts, key=lambda p: p[1])
            ax.plot([best[0]], [best[1]], "*", ms=11, color=f"C{i}", mec="black", mew=0.6,
                    gid=f"best_{est}_v{v:g}_N{best[0]}")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xlabel(f"phases N (count; M = 1, base exposure, period {own:g} px)")
    ax.set_ylabel("transmissive " + ERROR_LABEL)
    ax.set_title(f"{scene}: error against N at each object speed (* lowest)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    save(fig, out_dir, f"error-vs-n-speed-{stem}")


def examples(out_dir, stem):
    """The 8-bit previews the study wrote (examples/<scene>-<estimator>-N<n>-<component>.png) in
    one labelled figure."""
    pat = re.compile(re.escape(stem) + r"-([a-z]+)-N(\d+)-(transmissive|scattered)\.png$")
    found = {}
    for path in glob.glob(os.path.join(glob.escape(os.path.join(out_dir, "examples")), "*.png")):
        m = pat.match(os.path.basename(path))
        if m:
            found[(m.group(1), int(m.group(2)), m.group(3))] = path
    sets = sorted({(e, n) for e, n, _ in found})
    if not sets:
        return
    fig, axes = plt.subplots(len(sets), 2, figsize=(7.5, 2.9 * len(sets)), squeeze=False)
    for row, (est, n) in enumerate(sets):
        for col, comp in enumerate(("transmissive", "scattered")):
            ax = axes[row][col]
            path = found.get((est, n, comp))
            if path is None:
                ax.set_axis_off()
                continue
            im = ax.imshow(plt.imread(path), cmap="gray", vmin=0, vmax=1)
            ax.set_title(f"{comp}: {est}, N = {n}, M = 1", fontsize=9)
            ax.set_xlabel("x (px)", fontsize=8)
            ax.set_ylabel("y (px)", fontsize=8)
            ax.tick_params(labelsize=7)
            cb = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04)
            cb.set_label("display level (0.5–99.5 percentile stretch)", fontsize=7)
            cb.ax.tick_params(labelsize=7)
    fig.suptitle(f"{stem}: example separations (previews, not calibrated values)", fontsize=10)
    save(fig, out_dir, f"examples-{stem}")


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: plot_study.py STUDY.CSV OUT_DIR")
    csv_path, out_dir = sys.argv[1], sys.argv[2]
    data, first_period = load(csv_path)
    if not data:
        sys.exit(f"{csv_path}: no points")
    for scene in sorted({k.scene for k in data}):
        stem = scene.split(".", 1)[0]  # as descatterctl names the examples: up to the first dot
        every = {k: v for k, v in data.items() if k.scene == scene}
        slowest = min(k.speed for k in every)
        rows = {k: v for k, v in every.items() if k.speed == slowest}
        error_vs_time(scene, rows, out_dir, stem)
        error_vs_period(scene, rows, out_dir, stem)
        error_vs_n(scene, rows, first_period[scene], out_dir, stem)
        if len({k.speed for k in every}) > 1:
            error_vs_n_speed(scene, every, first_period[scene], out_dir, stem)
        examples(out_dir, stem)


if __name__ == "__main__":
    main()
