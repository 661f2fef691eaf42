"""Counter-based random numbers keyed by (ray key, dimension, seed), as pbrt's IndependentSampler.

The ray key is pixel * spp + sample (see rendering/renderer.py). The same key, dimension and seed always
give the same number, whatever thread computes it, so images do not depend on the thread count.
The hash is SplitMix64's finaliser applied to a combination of the three counters.
"""
import numpy as np

from .jit import njit

_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)


@njit
def mix64(x):
    x = (x ^ (x >> np.uint64(30))) * _M1
    x = (x ^ (x >> np.uint64(27))) * _M2
    return x ^ (x >> np.uint64(31))


@njit
def uniform(key, dim, seed):
    """A float64 in [0, 1) from the counters (53 random bits)."""
    x = mix64(np.uint64(key) * _GOLDEN + mix64(np.uint64(dim) + mix64(np.uint64(seed) + _GOLDEN)))
    return float(x >> np.uint64(11)) * (1.0 / 9007199254740992.0)
