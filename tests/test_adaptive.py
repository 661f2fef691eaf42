"""The adaptive driver dispatches on the integrand record's type at compile time (media/adaptive.py)."""
import math
from typing import NamedTuple

import numpy as np
import pytest
from numba.core.errors import TypingError

from raytrace.media import adaptive, slab

N20, W20 = np.polynomial.legendre.leggauss(20)


class Unregistered(NamedTuple):
    kt: float
    ks: float
    phase: float
    a: float
    b: float


def test_unknown_record_is_a_compile_time_error():
    """A record class without a registered integrand does not compile, even with the fields of one
    that has (slab.DistantSlab): no fall-through to another integrand."""
    with pytest.raises(TypingError, match="integrand: nothing is registered"):
        adaptive.rule(0.0, 1.0, Unregistered(1.0, 1.0, 1.0, 1.0, 1.0), N20, W20)


def test_subclass_record_takes_its_own_integrand():
    """slab.PlanarBehind has PlanarTheta's fields and its own integrand (u = 1 / (x - x_h))."""
    args = (-3.0, 0.5, 0.4, 0.3, 0, 0.0, 0.0, 0.6, 2.0, 0.1)
    theta, behind = slab.PlanarTheta(*args), slab.PlanarBehind(*args)
    a, b = 0.05, 0.3
    got_t = adaptive.rule(a, b, theta, N20, W20)
    got_b = adaptive.rule(a, b, behind, N20, W20)
    mid, half = 0.5 * (a + b), 0.5 * (b - a)
    ref_t = half * sum(w * slab._planar_theta.py_func(mid + half * x, theta) for x, w in zip(N20, W20))
    ref_b = half * sum(w * slab._planar_behind.py_func(mid + half * x, behind) for x, w in zip(N20, W20))
    assert got_t != got_b
    assert math.isclose(got_t, ref_t, rel_tol=1e-14) and math.isclose(got_b, ref_b, rel_tol=1e-14)


def test_piecewise_over_a_tuple_of_breakpoints_matches_the_closed_form():
    """Eq. 5's integrand by `piecewise` on (lo, hi) against slab_distant's closed form."""
    kt, ks, phase, a, b, ell = 0.7, 0.4, 0.08, 0.6, 0.8, 3.0
    got = adaptive.piecewise(slab.DistantSlab(kt, ks, phase, a, b), (0.0, ell), 2, 1e-12,
                             *np.polynomial.legendre.leggauss(10), N20, W20, np.zeros(3))
    assert math.isclose(got, slab.slab_distant(kt, ks, phase, a / b, ell), rel_tol=1e-12)
