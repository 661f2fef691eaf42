"""Per-pixel error bounds (docs/error_bounds.md): for every pixel and channel a B with
|pixel - exact| <= B, the exact value being the single scattering of the scene as modelled (the
same camera rays, float64 geometry, lit intervals and light model) averaged over the pixel's samples.

Built from what each part of a render knows (rendering/renderer.py adds them up; all radiances are >= 0, so
bounds add by the triangle inequality, over a ray's lit segments and lights and over a pixel's
samples):
* a method whose air-light returns a bound (`Method.airlight`'s third value for a deterministic
  method; `analytic`: the requested precision times the value, `quadrature` in homogeneous media:
  twice its rtol, `relative_bound`; `quadrature` in height fog and atmospheres: its rule's bound
  plus the rounding of their closed-form transmittances, methods/quadrature.py; `raymarch` in
  homogeneous media: an estimate, media/march.py `march_error`) adds it; one that does not
  (raymarch in fog and atmospheres, lecocq, sun, the Taylor series) makes the rays it integrated
  infinite; a stochastic method's
  air-light adds nothing here: its pixels carry their standard error instead
  (`with_standard_error`, a statistical measure, not a bound);
* closed forms evaluated in float64 (surface term, transmittances, sums): ROUNDING x |value|;
* rays that enter a shape holding a medium: the inside's bound and what lies behind's (interiors/crossing.py),
  finite where `analytic` integrates a convex index-matched shape under directional lights in
  closed form (media/convex_directional.py `segments_bounded`: KERNEL_FLOOR plus the condition of
  the light's path in its inputs, times the value) and where `quadrature` (or analytic's hand-over to
  it) integrates an index-matched shape, convex of at most 64 planes or not convex (its rule's bound,
  the integrand's rounding and the errors of the light path's length: media/slab.py convex_bounded,
  interiors/paths.py segment_quadrature); infinite for every other inside integrator, in convex shapes
  of more than 64 planes and through refractive boundaries;
* the particle layer's glints: infinite;
* a float32 EXR adds its own rounding (`stored`).
"""
from __future__ import annotations

import numpy as np

from .jit import exact_njit

# relative allowance for float64 closed forms and sums (surface term, exp(-kt t), the 1/spp mean):
# each is a few dozen operations of relative error 2^-53 ~ 1.1e-16 with condition numbers up to the
# optical path kt t (< 745 where exp does not underflow): below 1e-13, so 1e-12 is an upper bound
ROUNDING = 1e-12
# the finest relative accuracy `analytic`'s kernels promise whatever the precision asked (its
# cancellation guards accept relative rounding up to 1e-12 below precision 1e-11)
KERNEL_FLOOR = 1e-11
# a spot's falloff divides the cosine to its axis (rounded to a few eps) by about 1 - cos_end, the
# cone's width in cosine: a relative allowance of SPOT_ROUNDING / (1 - cos_end) on its air-light (the
# floor every method shares, measured 2e-7 for analytic in a 0.001-degree cone, tests/test_fuzz_scenes.py)
SPOT_ROUNDING = 10.0 * 2.0 ** -52
F32_REL = 2.0 ** -24  # float32 round-to-nearest: |fl(x) - x| <= 2^-24 |x| for normal x ...
F32_ABS = 2.0 ** -149  # ... plus half the smallest subnormal step below 2^-126 (counted whole)
INFINITE_STAT = "error bound: pixels with an infinite bound"


def relative_bound(radiance: np.ndarray, precision: float, met: dict, medium, cos_end: np.ndarray) -> np.ndarray:
    """Bound (S, 3) of a segment batch's air-light `radiance` evaluated to relative `precision`:
    (max(precision, KERNEL_FLOOR) + rounding) |value|, the rounding with a spot's (`cos_end` (S,):
    the cosine of each segment's light's cone, <= -1 without one), infinite where the evaluation did
    not meet it. `met[(kt, ks)]` (S,) bool per distinct channel coefficients (geometry.by_channel's
    keys); channels that do not scatter are exactly 0."""
    bound = np.empty(radiance.shape)
    flags = [met.get(key) for key in channel_keys(medium)]
    if any(f is None for f in flags):  # a channel that does not scatter: no evaluation to have missed
        everywhere = np.ones(len(radiance), dtype=np.bool_)
        flags = [everywhere if f is None else f for f in flags]
    _relative(radiance, max(precision, KERNEL_FLOOR) + ROUNDING, cos_end, tuple(flags), bound)
    return bound


def channel_keys(medium) -> list[tuple[float, float]]:
    """(sigma_t, sigma_s) of each of the medium's three channels, as Python floats: the keys under
    which channels with equal coefficients share one evaluation (geometry.by_channel)."""
    return list(zip(np.asarray(medium.sigma_t, np.float64).tolist(), np.asarray(medium.sigma_s, np.float64).tolist()))


@exact_njit
def _relative(radiance, rel, cos_end, met, out):
    """out = (rel + spot_rounding(cos_end)[:, None]) |radiance|, inf in channel c where met[c] (S,)
    is False (a GIL-free kernel, the NumPy expressions' bits: tests/test_exact_kernels.py)."""
    for s in range(radiance.shape[0]):
        spot = spot_allowance(cos_end[s])
        for c in range(radiance.shape[1]):
            out[s, c] = (rel + spot) * abs(radiance[s, c]) if met[c][s] else np.inf


@exact_njit
def spot_allowance(cos_end):
    """`spot_rounding` of one cosine, for kernels (the same operations)."""
    return SPOT_ROUNDING / max(1.0 - cos_end, 1e-300) if cos_end > -1.0 else 0.0


def spot_rounding(cos_end: np.ndarray) -> np.ndarray:
    """(S,) relative allowance of a spot's falloff on its air-light, SPOT_ROUNDING / (1 - cos_end) (0
    for lights without a cone, cos_end <= -1)."""
    return np.where(cos_end > -1.0, SPOT_ROUNDING / np.maximum(1.0 - cos_end, 1e-300), 0.0)


def product(bound: np.ndarray, factor: np.ndarray) -> np.ndarray:
    """bound x factor (broadcast), 0 where the factor is 0: a value multiplied by an exact 0 (a light
    of zero intensity, a channel without extinction) has no error, however large the bound of what it
    multiplied (inf x 0 would be NaN); inf where the product overflows."""
    bound, factor = np.broadcast_arrays(bound, factor)
    out = np.zeros(bound.shape)
    with np.errstate(over="ignore"):
        np.multiply(bound, factor, out=out, where=factor != 0.0)
    return out


def rays_with(ray_index: np.ndarray, n_rays: int) -> np.ndarray:
    """(N,) bool: the rays that own at least one of the segments whose ray indices are given."""
    out = np.zeros(n_rays, dtype=bool)
    out[ray_index] = True
    return out


def with_standard_error(bound: np.ndarray, variance: np.ndarray) -> np.ndarray:
    """A stochastic method's error channel: the deterministic parts' float32 bound plus the standard
    error sqrt(variance), rounded up, in place in `bound` (still infinite where it was)."""
    for b in _bands(bound):
        bound[b] = _up(bound[b] + np.sqrt(np.maximum(variance[b], 0.0)))
    return bound


def add_up(total: np.ndarray, bound: np.ndarray, divide: float = 1.0):
    """total += bound / divide in place, float32 rounded up (a bound of the exact sum), in bands."""
    for b in _bands(total):
        total[b] = _up(total[b] + np.asarray(bound[b], np.float64) / divide)


def _up(x: np.ndarray) -> np.ndarray:
    """float32 of x (float64) rounded toward +inf (inf beyond float32's range)."""
    with np.errstate(over="ignore"):
        low = x.astype(np.float32)
    up = low.astype(np.float64) < x
    low[up] = np.nextafter(low[up], np.float32(np.inf))
    return low


def stored(image: np.ndarray, bound: np.ndarray) -> np.ndarray:
    """float32 bound (3, H, W), channel-major for the EXR, of the float32 copy of `image` (H, W, 3):
    `bound` plus float32's rounding of each value, itself rounded up, so that |float32(image) - exact|
    <= result wherever |image - exact| <= bound. Computed in bands of rows (small temporaries)."""
    out = np.empty((3,) + image.shape[:-1], dtype=np.float32)
    for b in _bands(image):
        out[:, b] = np.moveaxis(_up(bound[b] + F32_REL * np.abs(image[b]) + F32_ABS), -1, 0)
    return out


BAND_VALUES = 1 << 20  # values per band of the image-sized computations above


def _bands(a: np.ndarray):
    rows = max(1, BAND_VALUES // max(1, a[0].size)) if len(a) else 1
    return [slice(r, r + rows) for r in range(0, len(a), rows)]


def summary(bound: np.ndarray) -> dict:
    """The render statistics of a bound image (H, W, 3): pixels with an infinite bound in any channel."""
    return {INFINITE_STAT: int(np.count_nonzero(np.isinf(bound).any(axis=-1)))}
