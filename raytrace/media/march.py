"""The midpoint march shared by ray marching (methods/raymarch.py) and the kernels of media inside
shapes (slab.py), on the typed integrand records of integrand.py; the step rules stay with them."""
import math

from ..jit import njit
from .integrand import integrand


@njit
def march(rec, a, n, delta, xi):
    """delta times the sum of the integrand `rec` names at a + (k + xi) delta, k = 0 .. n - 1: the
    midpoint rule for xi = 1/2, one offset xi in [0, 1) shared by every cell when jittered."""
    acc = 0.0
    for k in range(n):
        acc += integrand(a + (k + xi) * delta, rec)
    return acc * delta


COARSE = 8  # the error estimate's second march takes steps COARSE times as long: 1/COARSE more samples
SAFETY = 8.0  # the estimate is SAFETY times the fine march's asymptotic error


@njit
def coarse_steps(n, delta):
    """(steps, step length) of the estimate's coarse march over the n cells of length delta."""
    m = max(1, n // COARSE)
    return m, n * delta / m


@njit
def march_error(fine, coarse, n):
    """The error estimate of an n-step march `fine` from the `coarse_steps` march over the same
    cells (Richardson's): a step r = n / m times longer has an O(delta^2) error r^2 times the fine
    one's, so the fine march is about |coarse - fine| / (r^2 - 1) off; the estimate is SAFETY times
    that. Where the coarse march does not resolve the integrand the difference is larger still (an
    alarm, not a bound); inf below 2 steps (nothing to compare)."""
    if n < 2:
        return math.inf
    r = n / coarse_steps(n, 1.0)[0]
    return SAFETY / (r * r - 1.0) * abs(coarse - fine)
