#!/usr/bin/python3
"""Totals over several `descatterctl validate` outputs: the command and the latest totals are in
docs/accuracy.md, "Validation"; every round's totals and per-scene tables in
docs/records/accuracy-validation.md, "Validation on scenes nobody tuned for".
Usage: validation_summary.py DIR...   (each DIR holds a validation.csv)

Recomputes every verdict from the CSV's numbers (not its verdict column): a chosen point is
right when achieved/predicted lies within [1/1.5, 1.5]; a refusal is right when the best
reachable point it names indeed misses the target (or nothing fits the budget). A target chosen on
the margin (the CSV's target_may_be_missed: no point predicted to meet it, the target within the
best one's uncertainty) is judged as any chosen point, on its prediction; how many of them missed
the target is counted on its own. A prediction
marked as a lower bound (the CSV's lower_bound) is judged the same way: achieved above 1.5 x a
lower bound is a miss, not a hit because the bound held; lower bounds are counted on their own
too. Prints a Markdown summary per kind of scene (given, generated) and the worst cases by
ratio."""
import csv
import os
import sys


def verdict(r):
    if r["outcome"] == "chosen":
        ratio = float(r["achieved"]) / float(r["predicted"])
        return ("within" if 1 / 1.5 <= ratio <= 1.5 else "off"), ratio
    if r["outcome"] == "refused":
        if not r["target_error"] and not r["time_budget_ms"]:
            return "pilot-refused", None  # the pilot frames themselves were refused (named in the CSV)
        if not r["estimator"]:
            return "refused-right", None  # nothing fits the budget, or the pilot itself refused
        target = float(r["target_error"])
        if target <= 0:
            return "refused-right", None
        return ("refused-right" if float(r["achieved"]) > target else "refused-wrong"), None
    return r["outcome"], None


def main():
    rows = []
    for d in sys.argv[1:]:
        with open(os.path.join(d, "validation.csv")) as f:
            rows += list(csv.DictReader(f))
    # A fixed configuration its estimator refuses on a scene tests no prediction: left out.
    rows = [r for r in rows if not (r["outcome"] == "refused" and r["estimator"] and
                                    float(r["target_error"] or 0) <= 0 and float(r["time_budget_ms"] or 0) <= 0)]
    for kind in sorted({r["kind"] for r in rows}, key=lambda k: k == "generated"):
        sel = [r for r in rows if r["kind"] == kind]
        if not sel:
            continue
        scenes = sorted({r["scene"] for r in sel})
        counts = {}
        worst = []
        for r in sel:
            v, ratio = verdict(r)
            counts[v] = counts.get(v, 0) + 1
            if ratio is not None:
                worst.append((max(ratio, 1 / ratio), ratio, r))
        good = counts.get("within", 0) + counts.get("refused-right", 0) + counts.get("pilot-refused", 0)
        print(f"**{kind} scenes** ({len(scenes)} scenes, {len(sel)} requests): {good} "
              f"({100 * good / len(sel):.0f} %) within a factor 1.5 or correctly refused "
              f"({counts.get('within', 0)} within, {counts.get('refused-right', 0)} correctly refused, "
              f"{counts.get('pilot-refused', 0)} scenes whose pilot frames were refused with a reason); "
              f"{counts.get('off', 0)} outside the factor, {counts.get('refused-wrong', 0)} refused wrongly.")
        lower = [r for r in sel if r.get("lower_bound") == "1" and r["outcome"] in ("chosen", "refused")]
        if lower:
            lv = [verdict(r)[0] for r in lower]
            print(f"Lower bounds: {len(lower)} of the {len(sel)} predictions were marked as lower bounds "
                  f"({lv.count('within')} within the factor, {lv.count('off')} outside it, "
                  f"{lv.count('refused-right')} correctly refused, {lv.count('refused-wrong')} refused wrongly); "
                  f"they are counted above as any other.")
        margin = [r for r in sel if r.get("target_may_be_missed") == "1" and r["outcome"] == "chosen"]
        if margin:
            mv = [verdict(r)[0] for r in margin]
            missed = sum(1 for r in margin if float(r["achieved"]) > float(r["target_error"]))
            print(f"On the margin: {len(margin)} targets were chosen although no point was predicted to meet "
                  f"them (within the best prediction's uncertainty; {mv.count('within')} within the factor, "
                  f"{mv.count('off')} outside it); {missed} of them missed the target, "
                  f"{len(margin) - missed} met it.")
        worst.sort(key=lambda w: -w[0])
        for _, ratio, r in worst[:3]:
            req = f"target {r['target_error']}" if float(r["target_error"]) > 0 else f"budget {r['time_budget_ms']} ms"
            print(f"- {r['scene']}, {req}: {r['estimator']} N={r['phases']} M={r['averages']}, predicted "
                  f"{float(r['predicted']):.4f} (noise {float(r['noise']):.4f}, sampling {float(r['sampling']):.4f}, "
                  f"stripes {float(r['scattered_stripes']):+.4f}), achieved {float(r['achieved']):.4f} "
                  f"(systematic {float(r['achieved_systematic']):.4f}): x{ratio:.2f}")
        print()


if __name__ == "__main__":
    main()
