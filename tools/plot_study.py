#!/usr/bin/python3
"""Plots of `descatterctl study` output (docs/accuracy.md):
    /usr/bin/python3 tools/plot_study.py STUDY_DIR
writes STUDY_DIR/error-vs-time-<scene>.png (transmissive error against acquisition time, one
curve per estimator: for each time budget the best configuration of that estimator, seeds
averaged) and STUDY_DIR/bias-vs-n-<scene>.png (error against N at M = 1, base exposure)."""
import collections
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def load(path):
    rows = list(csv.DictReader(open(path)))
    agg = collections.defaultdict(list)
    for r in rows:
        key = (r["scene"], r["estimator"], int(r["phases"]), int(r["averages"]), float(r["exposure_factor"]))
        agg[key].append((float(r["rel_rmse_transmissive"]), float(r["rel_rmse_scattered"]), float(r["acquisition_ms"])))
    out = {}
    for k, v in agg.items():
        out[k] = (sum(x[0] for x in v) / len(v), sum(x[1] for x in v) / len(v), v[0][2])
    return out


def main():
    d = sys.argv[1]
    data = load(os.path.join(d, "study.csv"))
    scenes = sorted({k[0] for k in data})
    for scene in scenes:
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for est in sorted({k[1] for k in data if k[0] == scene}):
            pts = sorted((v[2], v[0]) for k, v in data.items() if k[0] == scene and k[1] == est)
            front, best = [], float("inf")
            for t, e in pts:
                if e < best:
                    best = e
                    front.append((t, e))
            ax.plot([p[0] for p in front], [p[1] for p in front], marker="o", label=est)
            ax.scatter([p[0] for p in pts], [p[1] for p in pts], s=6, alpha=0.3)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("acquisition time per set (ms, rig timing model)")
        ax.set_ylabel("relative RMSE, transmissive")
        ax.set_title(f"{scene}: error against time (best per estimator)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
        fig.tight_layout()
        fig.savefig(os.path.join(d, f"error-vs-time-{scene.replace('.scene', '')}.png"), dpi=110)
        plt.close(fig)

        fig, ax = plt.subplots(figsize=(7, 4.5))
        for est in sorted({k[1] for k in data if k[0] == scene}):
            pts = sorted((k[2], v[0]) for k, v in data.items()
                         if k[0] == scene and k[1] == est and k[3] == 1 and k[4] == 1.0)
            if pts:
                ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", label=est)
        ax.set_xlabel("phases N (M = 1, base exposure)")
        ax.set_ylabel("relative RMSE, transmissive")
        ax.set_title(f"{scene}: error against N")
        ax.grid(True, alpha=0.3)
        ax.legend()
        fig.tight_layout()
        fig.savefig(os.path.join(d, f"error-vs-n-{scene.replace('.scene', '')}.png"), dpi=110)
        plt.close(fig)
    print(f"plots written to {d}")


if __name__ == "__main__":
    main()
