#!/usr/bin/python3
"""Plots of `descatterctl study` output (docs/accuracy.md, "What the measurements say"):
    /usr/bin/python3 tools/plot_study.py STUDY_DIR
writes, per scene,
  error-vs-time-<scene>.png   transmissive (solid) and scattered (dashed) error against acquisition
                              time, one curve per estimator: for each time the best configuration
                              of that estimator (any N, M, exposure, period), seeds averaged;
                              points whose frames clip are drawn hollow and never join a curve;
  error-vs-n-<scene>.png      transmissive error against N at M = 1, base exposure, the first
                              period of --periods (the scene's own by default), with its
                              systematic part (noise-free frames) dotted;
  error-vs-period-<scene>.png the best transmissive error at each stripe period, split into its
                              noise and systematic parts: which period the medium needs."""
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from study_csv import load, noise_part  # noqa: E402


def front(points):
    """(time, error) pairs -> the points no faster point beats."""
    out, best = [], float("inf")
    for t, e in sorted(points):
        if e < best:
            best = e
            out.append((t, e))
    return out


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: plot_study.py STUDY_DIR")
    d = sys.argv[1]
    data, first_period = load(d)
    for scene in sorted({k.scene for k in data}):
        stem = scene.replace(".scene", "")
        rows = {k: v for k, v in data.items() if k.scene == scene}
        own = first_period[scene]

        fig, ax = plt.subplots(figsize=(7, 4.5))
        for i, est in enumerate(sorted({k.estimator for k in rows})):
            colour = f"C{i}"
            mine = [(v["acquisition_ms"], v) for k, v in rows.items() if k.estimator == est]
            for comp, style in (("transmissive", "-"), ("scattered", "--")):
                pts = [(ms, v[f"rel_rmse_{comp}"]) for ms, v in mine
                       if not v["saturated"] and math.isfinite(v[f"rel_rmse_{comp}"])]
                f = front(pts)
                if f:
                    ax.plot([p[0] for p in f], [p[1] for p in f], style, marker="o", ms=3, color=colour,
                            label=f"{est} {comp}")
            clipped = [(ms, v["rel_rmse_transmissive"]) for ms, v in mine
                       if v["saturated"] and math.isfinite(v["rel_rmse_transmissive"])]
            if clipped:
                ax.scatter([p[0] for p in clipped], [p[1] for p in clipped], s=14, facecolors="none",
                           edgecolors=colour, label=f"{est}: clipped frames")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("acquisition time per set (ms, rig timing model)")
        ax.set_ylabel("relative RMSE")
        ax.set_title(f"{scene}: error against time (best per estimator)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(os.path.join(d, f"error-vs-time-{stem}.png"), dpi=110)
        plt.close(fig)

        fig, ax = plt.subplots(figsize=(7, 4.5))
        for i, est in enumerate(sorted({k.estimator for k in rows})):
            pts = sorted((k.phases, v["rel_rmse_transmissive"], v["systematic_transmissive"])
                         for k, v in rows.items()
                         if k.estimator == est and k.averages == 1 and k.exposure == 1.0 and k.period == own)
            if pts:
                ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", color=f"C{i}", label=est)
                ax.plot([p[0] for p in pts], [p[2] for p in pts], ":", color=f"C{i}", label=f"{est} systematic")
        ax.set_xlabel(f"phases N (M = 1, base exposure, period {own:g} px)")
        ax.set_ylabel("relative RMSE, transmissive")
        ax.set_title(f"{scene}: error against N")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(os.path.join(d, f"error-vs-n-{stem}.png"), dpi=110)
        plt.close(fig)

        periods = sorted({k.period for k in rows})
        best = []
        for p in periods:
            cand = [v for k, v in rows.items() if k.period == p and math.isfinite(v["rel_rmse_transmissive"])]
            unclipped = [v for v in cand if not v["saturated"]] or cand
            b = min(unclipped, key=lambda v: v["rel_rmse_transmissive"])
            t, sys_t = b["rel_rmse_transmissive"], b["systematic_transmissive"]
            best.append((p, t, noise_part(t, sys_t), sys_t, b["saturated"] > 0))
        fig, ax = plt.subplots(figsize=(7, 4.5))
        ax.plot([b[0] for b in best], [b[1] for b in best], marker="o", label="best total")
        ax.plot([b[0] for b in best], [b[2] for b in best], "--", marker=".", label="its noise part")
        ax.plot([b[0] for b in best], [b[3] for b in best], ":", marker=".", label="its systematic part")
        for b in best:
            if b[4]:
                ax.annotate("clipped", (b[0], b[1]), fontsize=7)
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_xlabel("stripe period (px)")
        ax.set_ylabel("relative RMSE, transmissive")
        ax.set_title(f"{scene}: best error at each stripe period")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(os.path.join(d, f"error-vs-period-{stem}.png"), dpi=110)
        plt.close(fig)
    print(f"plots written to {d}")


if __name__ == "__main__":
    main()
