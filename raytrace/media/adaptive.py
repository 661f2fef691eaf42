"""The adaptive Gauss-Legendre driver shared by the air-light methods (methods/quadrature.py) and
the kernels of media inside shapes (slab.py): `adaptive` integrates `rule(a, b, args, nodes,
weights)` over [a, b], halving intervals until their 10- and 20-point values agree.

`rule` is a stub that each module owning an integrand completes with a numba overload for its
argument tuples (told apart by their lengths, which `claim` keeps distinct); the driver therefore
imports none of them, and neither package imports the other for it.
"""
import numpy as np

from ..jit import njit

MAX_INTERVALS = 4000
STACK = 200

# stats slots: evaluations, intervals, evaluations with an interval short of its tolerance
EVALS, INTERVALS, CAPPED = 0, 1, 2

_CLAIMED = set()


def claim(*lengths):
    """Reserve argument-tuple lengths for one module's overload of `rule`."""
    assert not _CLAIMED & set(lengths), "each rule's argument tuple needs a length of its own"
    _CLAIMED.update(lengths)


def rule(a, b, args, nodes, weights):
    """The Gauss-Legendre rule (nodes, weights on [-1, 1]) over [a, b] of the integrand `args` names."""


@njit
def adaptive(args, a, b, rtol, density, n10, w10, n20, w20, stats):
    """The integral over [a, b] of `rule` and whether every interval met its tolerance (False:
    an interval was accepted at the MAX_INTERVALS / STACK caps or at the resolution of doubles).
    An interval is accepted when its two values agree to rtol relative or to `density` times its
    width."""
    if not b > a:
        return 0.0, True
    converged = True
    lo = np.empty(STACK)
    hi = np.empty(STACK)
    lo[0], hi[0] = a, b
    top = 1
    total = 0.0
    count = 0
    while top > 0:
        top -= 1
        x0, x1 = lo[top], hi[top]
        coarse = rule(x0, x1, args, n10, w10)
        fine = rule(x0, x1, args, n20, w20)
        count += 1
        mid = 0.5 * (x0 + x1)
        tol = max(rtol * abs(fine), density * (x1 - x0))
        if abs(fine - coarse) <= tol or count >= MAX_INTERVALS or top + 2 > STACK or not (x0 < mid < x1):
            converged = converged and abs(fine - coarse) <= tol
            total += fine
        else:
            lo[top], hi[top] = x0, mid
            lo[top + 1], hi[top + 1] = mid, x1
            top += 2
    stats[INTERVALS] += count
    return total, converged
