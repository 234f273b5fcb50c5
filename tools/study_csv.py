"""Reading `descatterctl study` output (STUDY_DIR/study.csv) for tools/study_tables.py (the
tables of docs/records/accuracy-validation.md, "What the measurements say"). The study's
figures average the rows in the same way (etc/plot_study.py, run by descatterctl study).

study.csv has one row per configuration and seed. load() returns
  configurations  {Key: {column: value}}, the seeds of each configuration averaged;
  first_period    {scene: period_px of its first row}: the study runs the periods in the order
                  of --periods, whose default starts with the scene's own period."""
import collections
import csv
import math
import os

Key = collections.namedtuple("Key", "scene estimator phases averages exposure period speed")

# Columns averaged over seeds; "nan" (a component the scene does not have) stays nan.
MEAN_COLUMNS = ("rel_rmse_transmissive", "rel_rmse_scattered", "systematic_transmissive",
                "systematic_scattered", "acquisition_ms")


def number(text):
    try:
        return float(text)
    except ValueError:
        return float("nan")


def key(row):
    # speed_px_s: absent from a CSV written before the speed axis (still scenes).
    return Key(row["scene"], row["estimator"], int(row["phases"]), int(row["averages"]),
               float(row["exposure_factor"]), float(row["period_px"]), float(row.get("speed_px_s") or 0))


def load(study_dir):
    """Each configuration maps MEAN_COLUMNS to their means over its seeds, "saturated" to the
    most clipped pixels of any seed (0: no frame of any seed clipped), "pixels" to the
    pixels judged (valid + masked) and "blur_known" to whether its sets knew the edge blur."""
    seeds = collections.defaultdict(list)
    first_period = {}
    with open(os.path.join(study_dir, "study.csv"), newline="") as f:
        for row in csv.DictReader(f):
            if row.get("status", "ok") != "ok":
                continue  # a configuration that could not separate the scene: no error to plot
            first_period.setdefault(row["scene"], float(row["period_px"]))
            seeds[key(row)].append(row)
    configurations = {}
    for k, rows in seeds.items():
        c = {col: sum(number(r[col]) for r in rows) / len(rows) for col in MEAN_COLUMNS}
        c["saturated"] = max(int(r["saturated"]) for r in rows)
        c["pixels"] = int(rows[0]["valid"]) + int(rows[0]["masked"])
        # The set knew the scene's edge blur (robust's margin from it), as descatterd with
        # [illuminator] edge-blur-px; 0 where the sampling precondition refused that and the
        # point is the period alone (the blur unknown). Older CSVs: unknown throughout.
        c["blur_known"] = all(r.get("edge_blur_known", "0") == "1" for r in rows)
        configurations[k] = c
    return configurations, first_period


def noise_part(total, systematic):
    """The noise part of an error: sqrt(total² − systematic²), the two adding in quadrature;
    nan where either is unknown."""
    if not (math.isfinite(total) and math.isfinite(systematic)):
        return float("nan")
    return math.sqrt(max(0.0, total * total - systematic * systematic))
