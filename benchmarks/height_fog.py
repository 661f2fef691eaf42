"""Closed-form optical depth of an exponential height fog (seed 004, eq. 34) against the
numerically integrated one users write (the midpoint rule with n steps), at equal error.

    python benchmarks/height_fog.py

Random segments (heights -2 ... 10 scale heights, all directions, lengths up to 20 scale heights)
of the fog rho = exp(-h/H): the closed form (`medium.column`, verified against mpmath to ~1e-14 in
tests/test_optical_depth.py) is the reference. For each n: the median and maximum relative error
of the midpoint rule and its time per segment; then the n and the time ratio at which the rule
first reaches a maximum error of 1e-3 and 1e-6.
"""
import math
import sys
import time
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from raytrace.media.medium import EXPONENTIAL, column  # noqa: E402

H = 1.0
N_SEGMENTS = 200_000


@numba.njit(nogil=True)
def closed(h, mu, length, out):
    for i in range(h.shape[0]):
        out[i] = column(h[i], mu[i], 0.0, length[i], H, EXPONENTIAL)


@numba.njit(nogil=True)
def midpoint(h, mu, length, n, out):
    for i in range(h.shape[0]):
        dt = length[i] / n
        acc = 0.0
        for k in range(n):
            acc += math.exp(-(h[i] + mu[i] * (k + 0.5) * dt) / H)
        out[i] = acc * dt


def timed(fn, *args):
    fn(*args)  # compile
    best = math.inf
    for _ in range(3):
        start = time.perf_counter()
        fn(*args)
        best = min(best, time.perf_counter() - start)
    return best / N_SEGMENTS


def main():
    rng = np.random.default_rng(4)
    h = rng.uniform(-2.0, 10.0, N_SEGMENTS) * H
    mu = rng.uniform(-1.0, 1.0, N_SEGMENTS)
    length = rng.uniform(0.0, 20.0, N_SEGMENTS) * H
    ref = np.empty(N_SEGMENTS)
    t_closed = timed(closed, h, mu, length, ref)
    print(f"closed form (eq. 34): {t_closed * 1e9:.0f} ns per segment")
    print("| midpoint steps | median rel. error | max rel. error | ns per segment | x closed form |")
    print("|---|---|---|---|---|")
    reached = {}
    out = np.empty(N_SEGMENTS)
    for n in (1, 4, 16, 64, 256, 1024, 4096):
        t = timed(midpoint, h, mu, length, n, out)
        rel = np.abs(out - ref) / ref
        print(f"| {n} | {np.median(rel):.1e} | {rel.max():.1e} | {t * 1e9:.0f} | {t / t_closed:.0f} |")
        for target in (1e-3, 1e-6):
            if target not in reached and rel.max() <= target:
                reached[target] = (n, t / t_closed)
    for target, (n, ratio) in sorted(reached.items(), reverse=True):
        print(f"max error {target:g}: midpoint needs {n} steps, {ratio:.0f} x the closed form's time")


if __name__ == "__main__":
    main()
