"""Phase functions, normalised over the sphere, as functions of mu = cos(scattering angle).

Kernels branch on a small integer code; mu = 1 is forward scattering (the camera looks at the
light through the medium), where Henyey-Greenstein with g > 0 is brightest (METHODS.md §1).
"""
import math

from ..jit import njit

ISOTROPIC = 0
RAYLEIGH = 1
HG = 2

NAMES = {ISOTROPIC: "isotropic", RAYLEIGH: "rayleigh", HG: "hg"}

INV_4PI = 1.0 / (4.0 * math.pi)


@njit
def phase_value(code, g, mu):
    """Phi_c(mu) [1/sr] for the phase function `code` (HG asymmetry g)."""
    if code == ISOTROPIC:
        return INV_4PI
    if code == RAYLEIGH:
        return 3.0 / (16.0 * math.pi) * (1.0 + mu * mu)
    denom = 1.0 + g * g - 2.0 * g * mu
    return INV_4PI * (1.0 - g * g) / (denom * math.sqrt(denom))
