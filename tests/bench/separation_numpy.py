#!/usr/bin/python3
"""The max/min separation written the straightforward numpy way, for tests/bench/separation.

Frames arrive as a list of 2-D uint16 arrays; the usual script stacks them and reduces:
direct = max - min, global = 2 * min, both float32. Prints one line "numpy_seconds T" with
the best of --reps runs (stack + reductions + outputs; frame generation is not timed)."""
import argparse
import time

import numpy as np


def separate(frames):
    stack = np.stack(frames)
    mx = stack.max(axis=0)
    mn = stack.min(axis=0)
    direct = mx.astype(np.float32) - mn.astype(np.float32)
    global_ = 2.0 * mn.astype(np.float32)
    return direct, global_


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=2048)
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--reps", type=int, default=5)
    a = ap.parse_args()
    rng = np.random.default_rng(1)
    frames = [rng.integers(0, 65536, size=(a.size, a.size), dtype=np.uint16) for _ in range(a.frames)]
    best = float("inf")
    for _ in range(a.reps):
        t0 = time.perf_counter()
        d, g = separate(frames)
        best = min(best, time.perf_counter() - t0)
    assert d.dtype == np.float32 and g.shape == frames[0].shape
    print(f"numpy_seconds {best:.6f}")


if __name__ == "__main__":
    main()
