#!/usr/bin/python3
"""The max/min separation as the ICCP 2013 authors' scripts do it, for tests/bench/separation.

Frames arrive one at a time as 2-D uint16 arrays; a running maximum and minimum are kept with
np.maximum/np.minimum per frame (in place), then direct = max - min and global = 2 * min, both
float32. Prints one line "numpy_seconds T" with the best of --reps runs (the loop and the
outputs; frame generation is not timed)."""
import argparse
import time

import numpy as np


def separate(frames):
    mx = frames[0].copy()
    mn = frames[0].copy()
    for f in frames[1:]:
        np.maximum(mx, f, out=mx)
        np.minimum(mn, f, out=mn)
    direct = (mx - mn).astype(np.float32)
    global_ = 2.0 * mn.astype(np.float32)
    return direct, global_


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--width", type=int, default=2048)
    ap.add_argument("--height", type=int, default=2048)
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--reps", type=int, default=5)
    a = ap.parse_args()
    rng = np.random.default_rng(1)
    frames = [rng.integers(0, 65536, size=(a.height, a.width), dtype=np.uint16) for _ in range(a.frames)]
    best = float("inf")
    for _ in range(a.reps):
        t0 = time.perf_counter()
        d, g = separate(frames)
        best = min(best, time.perf_counter() - t0)
    assert d.dtype == np.float32 and g.dtype == np.float32 and g.shape == frames[0].shape
    # the loop is right: against the stacked reduction on the same frames
    stack = np.stack(frames)
    assert np.array_equal(d, (stack.max(axis=0) - stack.min(axis=0)).astype(np.float32))
    print(f"numpy_seconds {best:.6f}")


if __name__ == "__main__":
    main()
