"""The penumbrae's strata per point or cut pair (raytrace/shading.py `choose_strata`), against the rule
docs/area_lights.md states for it: the smallest k of LADDER at which the pilot's standard error σ,
scaled by (PILOT / k)^(3/2), is at most the tolerance times its estimate v in every channel; the cap
where v is 0 but σ is not; channels with σ = 0 ask for nothing."""
from __future__ import annotations

import numpy as np
import pytest

from raytrace import shading


def brute_force(value, var, tol) -> np.ndarray:
    """`choose_strata` rung by rung: each k of LADDER tested in turn."""
    out = []
    for v, s2 in zip(value, var):
        ask = s2 > 0.0
        if np.any(ask & (v <= 0.0)):
            out.append(shading.LADDER[-1])
            continue
        meets = [k for k in shading.LADDER
                 if np.all(np.sqrt(s2[ask]) * (shading.PILOT / k) ** 1.5 <= tol * v[ask])]
        out.append(meets[0] if meets else shading.LADDER[-1])
    return np.array(out)


@pytest.mark.parametrize("tol", [1e-1, 1e-2, 1e-3])
def test_the_strata_are_the_smallest_rung_that_meets_the_tolerance(tol):
    """2000 random pilots (σ / v spread over five decades, some channels exact, some estimates 0):
    the chosen strata equal the brute force's, and every rung of LADDER is chosen somewhere."""
    rng = np.random.default_rng(3)
    value = rng.uniform(0.5, 2.0, (2000, 3))
    var = (value * tol * 10.0 ** rng.uniform(-2.0, 3.0, (2000, 3))) ** 2
    var[rng.random((2000, 3)) < 0.1] = 0.0
    value[rng.random(2000) < 0.02, 1] = 0.0
    got = shading.choose_strata(value, var, tol)
    np.testing.assert_array_equal(got, brute_force(value, var, tol))
    assert set(got.tolist()) == set(shading.LADDER)
