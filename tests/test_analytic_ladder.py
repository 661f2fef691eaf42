"""The ladder of HG's fitted blocks and the series switch, against direct computations: each fit's
degree is the least that meets precision / 20 on its range (numpy's Chebyshev interpolation; the
fit checked on a grid three times finer than its own, one degree less missing on its own), and
`rho_switch` is min(ln(precision / (30 eps)), RHO_SWITCH_CAP) at every precision, the cap exactly."""
import math

import numpy as np
from numpy.polynomial import chebyshev

from raytrace.methods import analytic as A


def _hg(g, mu):
    return (1.0 - g * g) / (4.0 * math.pi * (1.0 + g * g - 2.0 * g * mu) ** 1.5)


def _rel_err(g, degree, phi_lo, phi_hi, mu):
    p = chebyshev.Chebyshev.interpolate(lambda m: _hg(g, m), degree, domain=[math.cos(phi_hi), math.cos(phi_lo)])
    return np.max(np.abs(p(mu) - _hg(g, mu)) / _hg(g, mu))


def test_each_fit_has_the_least_degree_that_meets_its_precision():
    for g, precision in ((0.9, 1e-3), (0.9, 1e-6), (0.95, 1e-6), (-0.9, 1e-4), (0.5, 1e-6)):
        for angle in (0.05, 0.15, 0.375, 1.0):
            phi_lo, phi_hi, _, _ = A.fitted_range(g, angle)
            c, _ = A._far_cosine_series(g, precision, phi_lo, phi_hi)
            assert c is not None, (g, precision, angle)
            degree = len(c) - 1
            fine = np.cos(np.linspace(phi_lo, phi_hi, 12001))
            assert _rel_err(g, degree, phi_lo, phi_hi, fine) <= 0.05 * precision * 1.001, (g, precision, angle)
            if degree > 2:  # one degree less misses, on the fit's own grid
                coarse = np.cos(np.linspace(phi_lo, phi_hi, 4001))
                assert _rel_err(g, degree - 1, phi_lo, phi_hi, coarse) > 0.05 * precision, (g, precision, angle)


def test_rho_switch_is_the_capped_logarithm():
    eps = 2.220446049250313e-16
    for precision in np.geomspace(1e-15, 0.1, 97):
        expected = min(math.log(precision / (30.0 * eps)), A.RHO_SWITCH_CAP)
        got = A.rho_switch(float(precision))
        if expected == A.RHO_SWITCH_CAP:
            assert got == expected, precision
        else:  # the kernel's division may round differently (fastmath's reciprocal)
            assert abs(got - expected) <= 1e-14 * max(1.0, abs(expected)), precision
