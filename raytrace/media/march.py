"""The midpoint march shared by ray marching (methods/raymarch.py) and the kernels of media inside
shapes (slab.py), on the typed integrand records of integrand.py; the step rules stay with them."""
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
