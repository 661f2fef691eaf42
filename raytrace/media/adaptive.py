"""The adaptive Gauss-Legendre driver shared by the air-light methods (methods/quadrature.py) and
the kernels of media inside shapes (slab.py), on the typed integrand records of integrand.py.
"""
import math

import numpy as np

from ..jit import njit
from .integrand import integrand

MAX_INTERVALS = 4000
STACK = 200

# stats slots: evaluations, intervals, evaluations with an interval short of its tolerance
EVALS, INTERVALS, CAPPED = 0, 1, 2

@njit
def rule(a, b, rec, nodes, weights):
    """The Gauss-Legendre rule (nodes, weights on [-1, 1]) over [a, b] of the integrand `rec` names."""
    half = 0.5 * (b - a)
    mid = 0.5 * (a + b)
    acc = 0.0
    for k in range(nodes.shape[0]):
        acc += weights[k] * integrand(mid + half * nodes[k], rec)
    return acc * half


@njit
def adaptive(rec, a, b, rtol, density, n10, w10, n20, w20, stats):
    """The integral over [a, b] of the integrand `rec` names and whether every interval met its
    tolerance (False: an interval was accepted at the MAX_INTERVALS / STACK caps or at the
    resolution of doubles). An interval is accepted when its 10- and 20-point values agree to rtol
    relative or to `density` times its width."""
    if not b > a:
        return 0.0, True
    return seeded(rec, a, b, rule(a, b, rec, n20, w20), rtol, density, n10, w10, n20, w20, stats)


@njit
def seeded(rec, a, b, first, rtol, density, n10, w10, n20, w20, stats):
    """`adaptive` over [a, b] (b > a) given its 20-point value `first` (the caller's, e.g. a first
    estimate's: not evaluated again)."""
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
        coarse = rule(x0, x1, rec, n10, w10)
        fine = first if count == 0 else rule(x0, x1, rec, n20, w20)
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


@njit
def first_estimate(rec, br, m, n20, w20, acc):
    """acc plus the 20-point values of `rec` over the pieces between the ascending breakpoints br[:m]."""
    for i in range(m - 1):
        if br[i + 1] > br[i]:
            acc += abs(rule(br[i], br[i + 1], rec, n20, w20))
    return acc


@njit
def refine(rec, br, m, rtol, floor, n10, w10, n20, w20, stats, acc):
    """acc plus `adaptive` (absolute floor `floor` per unit of the variable) over each piece between
    the breakpoints br[:m]; and whether every piece converged."""
    ok = True
    for i in range(m - 1):
        if br[i + 1] > br[i]:
            val, good = adaptive(rec, br[i], br[i + 1], rtol, floor, n10, w10, n20, w20, stats)
            acc += val
            ok = ok and good
    return acc, ok


@njit
def piecewise(rec, br, m, rtol, n10, w10, n20, w20, stats):
    """The integral of `rec` over [br[0], br[m - 1]], adaptive on the pieces between the breakpoints
    br[:m] (an array or a tuple) to rtol, or to rtol/10 of a first 20-point estimate of the whole per
    unit of the variable (so that negligible tails are not refined to full relative accuracy; the
    integrands are positive, so the total meets rtol). Counts an evaluation short of its tolerance."""
    return bounded_piecewise(rec, br, m, rtol, n10, w10, n20, w20, stats)[0]


@njit
def bounded_piecewise(rec, br, m, rtol, n10, w10, n20, w20, stats):
    """`piecewise` and the bound of its rule: each accepted interval's 20-point value taken to be
    within |G20 - G10| of its integral, which the test keeps below rtol |G20| or the floor times its
    width, so rtol (|total| + first estimate / 10) for a positive integrand; inf where an interval
    was accepted at a cap. Each piece's first 20-point rule is evaluated once, for the estimate and
    as the refinement's first (`seeded`)."""
    width = br[m - 1] - br[0]
    first = np.empty(max(m - 1, 1))  # each piece's 20-point value: the estimate's, the rule's first
    estimate = 0.0
    for i in range(m - 1):
        if br[i + 1] > br[i]:
            first[i] = rule(br[i], br[i + 1], rec, n20, w20)
            estimate += abs(first[i])
    floor = 0.1 * rtol * estimate / width if width > 0.0 else 0.0
    total, ok = 0.0, True
    for i in range(m - 1):
        if br[i + 1] > br[i]:
            val, good = seeded(rec, br[i], br[i + 1], first[i], rtol, floor, n10, w10, n20, w20, stats)
            total += val
            ok = ok and good
    if not ok:
        stats[CAPPED] += 1.0
        return total, math.inf
    return total, rtol * (abs(total) + 0.1 * estimate)
