"""Phase functions, normalised over the sphere, as functions of mu = cos(scattering angle).

Kernels branch on a small integer code; mu = 1 is forward scattering (the camera looks at the
light through the medium), where Henyey-Greenstein with g > 0 is brightest (METHODS.md §1).
"""
import math

import numpy as np

from ..jit import njit

ISOTROPIC = 0
RAYLEIGH = 1
HG = 2

NAMES = {ISOTROPIC: "isotropic", RAYLEIGH: "rayleigh", HG: "hg"}

INV_4PI = 1.0 / (4.0 * math.pi)


@njit
def hg(g, one_minus, one_plus):
    """Henyey-Greenstein [1/sr] given 1 - mu and 1 + mu (numbers or arrays): the denominator
    1 + g^2 - 2 g mu as a sum of two non-negative terms, (1 - g)^2 + 2 g (1 - mu) for g >= 0 and
    (1 + g)^2 - 2 g (1 + mu) for g < 0, keeps full relative accuracy at the peak (the direct form
    loses 2 eps / (1 - |g|)^2 there, 2e-12 at |g| = 0.99)."""
    if g >= 0.0:
        den = (1.0 - g) * (1.0 - g) + 2.0 * g * one_minus
    else:
        den = (1.0 + g) * (1.0 + g) - 2.0 * g * one_plus
    return INV_4PI * (1.0 - g) * (1.0 + g) / (den * np.sqrt(den))


@njit
def phase_split(code, g, mu, one_minus, one_plus):
    """Phi_c(mu) [1/sr] given also 1 - mu and 1 + mu computed without cancellation."""
    if code == ISOTROPIC:
        return INV_4PI
    if code == RAYLEIGH:
        return 3.0 / (16.0 * math.pi) * (1.0 + mu * mu)
    return hg(g, one_minus, one_plus)


@njit
def phase_value(code, g, mu):
    """Phi_c(mu) [1/sr] for the phase function `code` (HG asymmetry g)."""
    return phase_split(code, g, mu, 1.0 - mu, 1.0 + mu)
