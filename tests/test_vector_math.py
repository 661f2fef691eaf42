"""`expint.vector_math` (glibc's libmvec through an intrinsic, VECTOR_BLOCK doubles a call, the Fig. 2 lanes' setup
and `analytic._pending_series`' exponentials): within LIBM_ULPS ulp of 30-digit mpmath, entry by entry (the same
result whatever its neighbours), and the scalar variant (width 0, where libmvec cannot be called) the scalar libm's
bits."""
import math

import mpmath
import numpy as np
import pytest
from numba import njit

from raytrace.media import expint as E

FUNCTIONS = {"sin": (E.vector_sin, mpmath.sin, (-40.0, 40.0)), "cos": (E.vector_cos, mpmath.cos, (-40.0, 40.0)),
             "log": (E.vector_log, mpmath.log, (1e-5, 1e5)), "atan": (E.vector_atan, mpmath.atan, (-50.0, 50.0)),
             "exp": (E.vector_exp, mpmath.exp, (-740.0, 700.0))}


def _caller(f):
    """A kernel applying f to buf, `block` entries a call (buf's length a multiple of it: whole vectors)."""
    @njit
    def apply(buf, block):
        for i in range(0, buf.shape[0], block):
            f(buf, i)
    return apply


def _inputs(name, n, seed):
    lo, hi = FUNCTIONS[name][2]
    rng = np.random.default_rng(seed)
    x = np.exp(rng.uniform(math.log(lo), math.log(hi), n)) if name == "log" else rng.uniform(lo, hi, n)
    return x


@pytest.mark.parametrize("name", sorted(FUNCTIONS))
def test_within_libm_ulps_of_mpmath(name):
    f, ref, _ = FUNCTIONS[name]
    x = _inputs(name, 64 * E.VECTOR_BLOCK, 1)
    y = x.copy()
    _caller(f)(y, E.VECTOR_BLOCK)
    mpmath.mp.dps = 30
    worst = 0.0
    for xi, yi in zip(x, y):
        r = ref(mpmath.mpf(float(xi)))
        worst = max(worst, float(abs(mpmath.mpf(float(yi)) - r)) / np.spacing(abs(float(r))))
    assert worst <= E.LIBM_ULPS, worst


def test_special_values():
    y = np.array([-math.inf, 0.0, -0.0, 1e-320] + [0.0] * (E.VECTOR_BLOCK * 4 - 4))  # whole vectors
    _caller(E.vector_exp)(y, E.VECTOR_BLOCK)
    assert y[0] == 0.0 and y[1] == 1.0 and y[2] == 1.0 and y[3] == 1.0
    y = np.array([math.inf, -math.inf] + [0.0] * (E.VECTOR_BLOCK * 2 - 2))
    _caller(E.vector_atan)(y, E.VECTOR_BLOCK)
    assert y[0] == 0.5 * math.pi and y[1] == -0.5 * math.pi and y[2] == 0.0


@pytest.mark.parametrize("name", sorted(FUNCTIONS))
def test_entry_by_entry(name):
    f = FUNCTIONS[name][0]
    x = _inputs(name, 16 * E.VECTOR_BLOCK, 2)
    y = x.copy()
    call = _caller(f)
    call(y, E.VECTOR_BLOCK)
    rng = np.random.default_rng(3)
    for order in (rng.permutation(len(x)), np.roll(np.arange(len(x)), 1), np.repeat(np.arange(E.VECTOR_BLOCK), 16)):
        z = x[order]
        call(z, E.VECTOR_BLOCK)
        assert np.array_equal(z, y[order])


@pytest.mark.parametrize("name", sorted(FUNCTIONS))
def test_scalar_variant_is_libm(name):
    x = _inputs(name, 40, 4)
    y = x.copy()
    _caller(E._vector_math(name, 0))(y, 1)
    assert np.array_equal(y, [getattr(math, name)(v) for v in x])
