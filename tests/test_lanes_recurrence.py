"""`cosine_moments_lanes` (the recurrence on D_k = k E_k, two steps a pass) against the recurrence on E_k itself
(legendre_moments' module docstring, step 3) run in 30-digit mpmath on the same inputs: the same sum to within
the forward recurrence's rounding, for every length of series from 1 to 40 terms (an odd and an even number of
steps, a last single step) and segments to infinity and finite ones. The bound is the rounding of the tests of
test_legendre_moments.py, capped as theirs at 1e-11 (measured worst: 9.1e-14)."""
import math

import mpmath as mp
import numpy as np
import pytest

from raytrace.media.legendre_moments import (FORWARD_ERR_PER_LOSS, cosine_moments_lanes, forward_loss, hg_legendre,
                                             legendre_to_cosine)


def _exact(H, va, vb, K1, L1, ea, eb, c):
    """sum_k c_k Re E_k with (k+1) E_{k+1} + 2(k + iH) E_k + (k-1) E_{k-1} = -2i B_k in 30 digits."""
    with mp.workdps(30):
        H, va, K1, L1, ea, eb = (mp.mpf(x) for x in (H, va, K1, L1, ea, eb))
        ta = 1 / (1 + va * va)
        za = mp.mpc(2 * ta - 1, 2 * va * ta)
        if vb == math.inf:
            tb, zb, vbt = mp.mpf(0), mp.mpc(-1, 0), mp.mpf(0)
        else:
            vb = mp.mpf(vb)
            tb = 1 / (1 + vb * vb)
            zb, vbt = mp.mpc(2 * tb - 1, 2 * vb * tb), eb * tb * vb
        prev = mp.mpc(2 * K1, 0)
        cur = mp.mpc(2 * (vbt - ea * ta * va) + 2 * H * L1, -2 * (H * K1 + eb * tb - ea * ta))
        total = c[0] * prev.real + (c[1] * cur.real if len(c) > 1 else 0)
        for k in range(1, len(c) - 1):
            b = 2 * eb * tb * zb ** k - 2 * ea * ta * za ** k
            prev, cur = cur, (-2j * b - 2 * (k + 1j * H) * cur - (k - 1) * prev) / (k + 1)
            total += c[k + 1] * cur.real
        return float(total)


@pytest.mark.parametrize("n", range(1, 41))
def test_lanes_vs_the_recurrence_on_e_k(n):
    c = legendre_to_cosine(hg_legendre(0.9, n - 1))
    rng = np.random.default_rng(n)
    rows = []
    for _ in range(6):
        H = float(10 ** rng.uniform(-3, 0))
        va = float(rng.uniform(0.0, 2.0))
        vb = math.inf if rng.random() < 0.3 else va + float(10 ** rng.uniform(-2, 1))
        K1, L1 = float(rng.uniform(0.1, 1.0)), float(rng.uniform(-1.0, 1.0))  # S is linear in them
        rows.append((H, va, vb, K1, L1, 1.0, 0.0 if vb == math.inf else math.exp(-H * (vb - va))))
    args = np.array(rows)
    out = np.empty(len(rows))
    cosine_moments_lanes(args, np.arange(len(rows)), c, out)
    for row, s in zip(rows, out):
        ref = _exact(*row, [mp.mpf(float(x)) for x in c])
        bound = 30 * FORWARD_ERR_PER_LOSS * forward_loss(row[0], c) * np.abs(c).sum() * max(row[3], 1.0) / abs(ref)
        assert abs(s / ref - 1.0) <= min(bound, 1e-11), (n, row, s, ref, bound)
