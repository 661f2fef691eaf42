"""The exact mode's sum S = sum_k c_k Re E_k is linear in its start values K1, L1 (legendre_moments, step
3): `start_sensitivity` against the kernel's own response to them, and the blocks' tables
(`analytic._sensitivity`, read by `_block_at`) bound it at every H up to the block's limit."""
import math

import numpy as np
import pytest

from raytrace.methods import analytic as A
from raytrace.media.legendre_moments import cosine_moments_forward, start_sensitivity
from raytrace.media.phase import HG, RAYLEIGH


@pytest.mark.parametrize("code,g,precision", [(HG, 0.9, 1e-3), (HG, -0.5, 1e-6), (RAYLEIGH, 0.0, 1e-6)])
def test_sensitivity_is_the_kernels_response_to_its_start_values(code, g, precision):
    """|dS/dK1| + |dS/dL1| of `cosine_moments_forward` by central differences (exact up to rounding: S is
    linear), whatever the segment's ends, against `start_sensitivity` of H alone."""
    rng = np.random.default_rng(5)
    for block in A.coefficient_blocks(A.exact_coeffs(code, g, precision)):
        c = block[A.B_C:]
        for _ in range(20):
            H = float(rng.uniform(0.0, block[A.B_HMAX]))
            va = float(rng.uniform(0.0, 2.0))
            vb = math.inf if rng.random() < 0.3 else va + float(rng.uniform(0.01, 20.0))
            K1, L1, ea, eb = rng.uniform(0.1, 1.0, 4)
            eb = 0.0 if vb == math.inf else eb

            def s(k, l):
                return cosine_moments_forward(H, va, vb, k, l, ea, eb, c)

            d = 1e-3
            dk = (s(K1 + d, L1) - s(K1 - d, L1)) / (2 * d)
            dl = (s(K1, L1 + d) - s(K1, L1 - d)) / (2 * d)
            want = start_sensitivity(np.array([H]), c)[0]
            assert abs(dk) + abs(dl) == pytest.approx(want, rel=1e-7, abs=1e-9 * np.sum(np.abs(c)))


@pytest.mark.parametrize("g,precision", [(0.9, 1e-3), (0.9, 1e-6), (0.95, 1e-6), (-0.9, 1e-6), (0.5, 1e-9)])
def test_tables_bound_the_sensitivity(g, precision):
    """`_block_at`'s value for a point light's piece (at = B_HMAX) is at least the sensitivity / (2 sum
    |c_k|) at 2000 values of H per block, denser than the table's samples, and at most twice it at half
    of them (a bound that errs far high would waste the series' iterations)."""
    co = A.exact_coeffs(HG, g, precision)
    starts = co[-1 - int(co[-1]):-1].astype(int)
    for start, block in zip(starts, A.coefficient_blocks(co)):
        c, hmax = block[A.B_C:], block[A.B_HMAX]
        H = np.concatenate((hmax * np.random.default_rng(1).random(1000), np.linspace(0.0, hmax, 1000)))
        true = start_sensitivity(H, c) / (2.0 * np.sum(np.abs(c)))
        lo, hi = block[A.B_VLO], block[A.B_VHI]
        v1, v2 = lo, (hi if hi < math.inf else math.inf)
        got = np.array([A._block_at(co, v1, v2, x, A.B_HMAX) for x in H])
        mine = got[:, 0] == start  # the pieces this block serves (a later, narrower one may serve others)
        assert mine.any()
        assert np.all(got[mine, 2] >= true[mine]), (g, precision, len(c))
        over = got[mine, 2] / true[mine]
        assert np.median(over) <= 2.0, (g, precision, len(c))
