"""jit.Kernel types a call from compiled code on its arguments' non-literal types: one specialisation
for a constant argument and a variable one (also for a variable whose type numba settles only later,
`m = 0` then `m += 1`), and the literal still where the callee needs the constant."""
import numba
import numpy as np
import pytest

from raytrace import jit


def kernels():
    """Fresh kernels (uncached: each test counts its own compilations)."""
    @jit.njit(cache=False)
    def head(a, first, end):
        s = 0.0
        for i in range(first, end):
            s += a[i]
        return s

    @jit.njit(cache=False)
    def both(a):
        m = 0
        for i in range(a.shape[0]):
            if a[i] > 0.0:
                m += 1
        return head(a, 0, m) + head(a, m, a.shape[0])

    @jit.njit(cache=False)
    def pick(t, k):
        return t[k]  # a heterogeneous tuple: numba needs k's value

    @jit.njit(cache=False)
    def picks(x):
        return pick((1, x), 1) + pick((1, x), 0)

    return head, both, pick, picks


@pytest.mark.skipif(not jit.CUTS, reason="plain numba.njit where numba's internals differ")
def test_a_constant_and_a_settling_variable_share_one_specialisation():
    head, both, _, _ = kernels()
    a = np.array([1.0, 2.0, -3.0, 4.0])
    assert both(a) == 1.0 + 2.0 + -3.0 + 4.0
    assert [str(t) for sig in head.overloads for t in sig] == ["array(float64, 1d, C)", "int64", "int64"]


@pytest.mark.skipif(not jit.CUTS, reason="plain numba.njit where numba's internals differ")
def test_a_callee_that_needs_the_constant_gets_the_literal():
    _, _, pick, picks = kernels()
    assert picks(2.5) == 3.5
    assert sorted(str(sig[1]) for sig in pick.overloads) == ["Literal[int](0)", "Literal[int](1)"]
    assert all(isinstance(sig[1], numba.types.Literal) for sig in pick.overloads)
