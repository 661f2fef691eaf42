"""`height_fog`, after "Sampling Analytic Participating Media" (its equation numbers): fog over flat
ground whose coefficients, given at the reference height h0, scale with one density of the height
p·up - h0, exponential (eq. 32) or linear (eq. 28); the transmittance along a ray is exp(-kt tau)
with tau the closed-form unit optical depth below, the same for every channel. Optical depth of a
ray segment and its inverse (docs/optical_depth.md §1): a ray is given by ``h`` = o·up - h0, the
height of its origin above the reference height, and ``mu`` = d·up; t0 <= t1 are distances along
it (t1 may be inf).

* constant:    sigma(p) = sigma0                                  (eq. 25-27)
* linear:      sigma(p) = sigma0 max(0, 1 - (p·up - h0)/H)        (eq. 28-31; zero above h0 + H)
* exponential: sigma(p) = sigma0 exp(-(p·up - h0)/H)              (eq. 32-35)

Every result is a product of non-negative factors (no difference of two optical depths, no
exp of a positive argument except the density at the segment's densest end, which overflows only
when the optical depth itself exceeds the float range); infinite optical depths come out as inf.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..jit import njit
from .medium import Medium, exp_transmittance, kernel_arrays

EXPONENTIAL, LINEAR = 0, 1  # profiles
PROFILES = {"exponential": EXPONENTIAL, "linear": LINEAR}


@dataclass(kw_only=True)
class HeightFog(Medium):
    up: np.ndarray  # unit up vector
    h0: float  # reference height (where sigma_a, sigma_s hold)
    scale_height: float
    profile: int = EXPONENTIAL

    type_name = "height_fog"
    keys = frozenset({"type", "sigma_a", "sigma_s", "phase", "up", "h0", "scale_height", "profile"})

    @classmethod
    def parse(cls, read, raw):
        """Unit `up`, reference height `h0`, `scale_height` H > 0 and the density `profile`."""
        sa = read.rgb("medium.sigma_a", raw.get("sigma_a", 0.0))
        ss = read.rgb("medium.sigma_s", raw.get("sigma_s", 0.0))
        phase = read.phase(raw.get("phase", "isotropic"), "medium.phase")
        up = read.vec3("medium.up", raw.get("up", [0.0, 1.0, 0.0]))
        norm = float(np.linalg.norm(up))
        if not norm > 0.0:
            read.fail("medium.up", "is zero", "give the direction heights are measured along, e.g. up = [0.0, 1.0, 0.0]")
        if "scale_height" not in raw:
            read.fail("medium.scale_height", "missing", "add medium.scale_height = 20.0 (the height over which the "
                      "density falls by e)")
        H = float(read.number("medium.scale_height", raw["scale_height"]))
        if not H > 0.0:
            read.fail("medium.scale_height", f"must be positive, got {H!r}", "use a height greater than 0, e.g. 20.0")
        profile = read.string("medium.profile", raw.get("profile", "exponential"), tuple(PROFILES))
        return cls(sa, ss, *phase, up=up / norm, h0=float(read.number("medium.h0", raw.get("h0", 0.0))),
                   scale_height=H, profile=PROFILES[profile])

    def describe(self):
        profile = "linear" if self.profile == LINEAR else "exponential"
        return super().describe() + [f"  {self.type_name}: coefficients at h0 = {self.h0:g} along up "
                                     f"{self.up.round(6).tolist()}, {profile} profile, scale height "
                                     f"{self.scale_height:g}"]

    def density_at(self, point):
        return float(attenuated_density(float(np.asarray(point, float) @ self.up) - self.h0, 0.0, self.scale_height,
                                        self.profile))

    def transmittance_on(self, origins, dirs, a, b):
        n = len(origins)
        tau = np.empty(n)
        ray_columns(*kernel_arrays(n, origins, dirs, a, b), *np.asarray(self.up, float).tolist(), float(self.h0),
                    float(self.scale_height), int(self.profile), tau)
        return exp_transmittance(self.sigma_t, tau)


@njit
def _one_minus_exp_over(x):
    """(1 - e^{-x}) / x for x >= 0 (1 at x = 0), without cancellation."""
    if x == 0.0:
        return 1.0
    return -math.expm1(-x) / x


@njit
def _log1p_over(q):
    """log(1 + q) / q for q > -1 (1 at q = 0), without cancellation."""
    if q == 0.0:
        return 1.0
    return math.log1p(q) / q


@njit
def constant_optical_depth(sigma0, t0, t1):
    """sigma0 (t1 - t0) (eq. 26); 0 for sigma0 = 0 even over an infinite segment."""
    if sigma0 == 0.0 or not t1 > t0:
        return 0.0
    return sigma0 * (t1 - t0)


@njit
def constant_distance(sigma0, t0, tau):
    """t0 + tau / sigma0 (eq. 27), inf for sigma0 = 0."""
    if not tau > 0.0:
        return t0
    if not sigma0 > 0.0:
        return math.inf
    return t0 + tau / sigma0


@njit
def exponential_optical_depth(sigma0, h, mu, t0, t1, scale_height):
    """sigma0 int_{t0}^{t1} exp(-(h + mu t)/H) dt (eq. 34), read from the segment's densest end
    (t0 going up, t1 going down) as e^{-h_dense/H} L (1 - e^{-|mu| L/H}) / (|mu| L/H)."""
    if sigma0 == 0.0 or not t1 > t0:
        return 0.0
    H = scale_height
    k = abs(mu) / H
    if t1 == math.inf:
        if not mu > 0.0:
            return math.inf  # horizontal or down to -inf
        return sigma0 * math.exp(-(h + mu * t0) / H) / k
    length = t1 - t0
    e = -(h + mu * (t0 if mu >= 0.0 else t1)) / H
    column = length * _one_minus_exp_over(k * length)
    if e > 700.0:  # keep exp(e) * column finite when it is
        return sigma0 * math.exp(e + math.log(column))
    return sigma0 * math.exp(e) * column


@njit
def exponential_distance(sigma0, h, mu, t0, tau, scale_height):
    """The t >= t0 where `exponential_optical_depth` from t0 reaches tau (eq. 35), inf if never
    (a rising ray holds only sigma0 e^{-h(t0)/H} H/mu). With q = (tau/sigma0)(mu/H) e^{h(t0)/H}:
    t - t0 = -log(1 - q) H/mu = (tau/sigma0) e^{h(t0)/H} log1p(-q)/(-q), exact as mu -> 0."""
    if not tau > 0.0:
        return t0
    if not sigma0 > 0.0:
        return math.inf
    H = scale_height
    x0 = (h + mu * t0) / H
    column = tau / sigma0
    if mu == 0.0:
        return t0 + column * math.exp(x0)
    k = abs(mu) / H
    lq = math.log(column * k) + x0  # log |q|
    if mu > 0.0:
        if lq >= 0.0:
            return math.inf
        q = math.exp(lq)
        if q > 1e-3:
            return t0 - math.log1p(-q) / k
        return t0 + column * math.exp(x0) * _log1p_over(-q)
    if lq > 700.0:  # log(1 + q) = log q + log1p(1/q)
        return t0 + (lq + math.log1p(math.exp(-lq))) / k
    q = math.exp(lq)
    if q > 1e-3:
        return t0 + math.log1p(q) / k
    return t0 + column * math.exp(x0) * _log1p_over(q)


@njit
def _linear_support(h, mu, t0, t1, H):
    """The part [lo, hi] of [t0, t1] where c(t) = 1 - (h + mu t)/H > 0, and c at both ends
    (lo > hi when it is empty)."""
    c0 = 1.0 - h / H
    c1 = -mu / H
    if c1 == 0.0:
        return (t0, t1, c0, c0) if c0 > 0.0 else (1.0, 0.0, 0.0, 0.0)
    t_zero = -c0 / c1
    if c1 > 0.0:
        lo, hi = max(t0, t_zero), t1
    else:
        lo, hi = t0, min(t1, t_zero)
    c_lo = 0.0 if lo == t_zero else c0 + c1 * lo
    c_hi = 0.0 if hi == t_zero else (math.inf if hi == math.inf else c0 + c1 * hi)
    return lo, hi, c_lo, c_hi


@njit
def linear_optical_depth(sigma0, h, mu, t0, t1, scale_height):
    """sigma0 int_{t0}^{t1} max(0, 1 - (h + mu t)/H) dt (eq. 30): the length of the positive part
    times the mean of its end densities (no cancellation); inf when it is unbounded."""
    if sigma0 == 0.0 or not t1 > t0:
        return 0.0
    lo, hi, c_lo, c_hi = _linear_support(h, mu, t0, t1, scale_height)
    if not hi > lo:
        return 0.0
    if hi == math.inf:
        return math.inf
    return sigma0 * (hi - lo) * 0.5 * (c_lo + c_hi)


@njit
def linear_distance(sigma0, h, mu, t0, tau, scale_height):
    """The t >= t0 where `linear_optical_depth` from t0 reaches tau, inf if never: the smaller
    root of eq. 31 in the cancellation-free form L = 2T / (c + sqrt(c^2 + 2 c' T)), T = tau/sigma0,
    counted from where the density becomes positive."""
    if not tau > 0.0:
        return t0
    if not sigma0 > 0.0:
        return math.inf
    lo, hi, c_lo, c_hi = _linear_support(h, mu, t0, math.inf, scale_height)
    if not hi > lo:
        return math.inf
    column = tau / sigma0
    c1 = -mu / scale_height
    disc = c_lo * c_lo + 2.0 * c1 * column
    if disc < 0.0:
        return math.inf
    return lo + 2.0 * column / (c_lo + math.sqrt(disc))


@njit
def attenuated_density(h, tau, H, profile):
    """The fog's density relative to h0 at the height h above h0 (eq. 32 or eq. 28) times e^{-tau},
    without inf * 0 deep below h0 (where the density overflows and tau is inf): the exponential's
    as one exp(-h/H - tau)."""
    if profile == EXPONENTIAL:
        return math.exp(-h / H - tau)
    return max(0.0, 1.0 - h / H) * math.exp(-tau)


@njit
def above_top(h, H, profile):
    """True where the density is 0: above the linear profile's top h0 + H."""
    return profile == LINEAR and h >= H


@njit
def top_distance(h, mu, H, profile):
    """The distance along a ray (height h, up-cosine mu) to the linear profile's top, where its
    density's derivative jumps; -1 when there is none."""
    return (H - h) / mu if profile == LINEAR and mu != 0.0 else -1.0


@njit
def column(h, mu, t0, t1, H, profile):
    """Unit-density optical depth over [t0, t1] of a ray starting at height h with up-cosine mu."""
    if profile == EXPONENTIAL:
        return exponential_optical_depth(1.0, h, mu, t0, t1, H)
    return linear_optical_depth(1.0, h, mu, t0, t1, H)


ULP = 2.0 ** -53  # unit roundoff of float64


@njit
def column_error(h, mu, t0, t1, H, profile, col, dz, dm):
    """An upper bound on |computed - exact| of `column` (its computed value col) over [t0, t1],
    to first order, when the ray's heights carry absolute errors up to dz and its up-cosine mu up to
    dm (docs/error_bounds.md, "Height fog"): a height at t is off by at most dz + t dm. Exponential:
    the density's relative error is that over H, and the closed form's own dozen operations add
    8 ulp (their condition is at most 1: (1 - e^-y)/y has |y d log/dy| <= 1); to infinity the
    column is H e^{-h/H}/mu, of relative condition 1 in mu (dm/|mu|). Linear: the density
    1 - height/H is off absolutely by (dz + t dm)/H over the support's length (where it ends at the
    top the column's derivative is 0: second order). The ends t0, t1 are taken exact here."""
    if not (col > 0.0 and t1 > t0):
        return 0.0
    if profile == EXPONENTIAL:
        if t1 == math.inf:
            return col * ((dz + t0 * dm) / H + dm / abs(mu) + 8.0 * ULP)
        return col * ((dz + t1 * dm) / H + 8.0 * ULP)
    lo, hi, _, _ = _linear_support(h, mu, t0, t1, H)
    if not hi > lo or hi == math.inf:
        return 0.0 if not hi > lo else math.inf
    return (hi - lo) * (dz + hi * dm) / H + 8.0 * ULP * col


@njit
def column_distance(h, mu, t0, tau, H, profile):
    """The t >= t0 where `column` from t0 reaches tau (inf if never): eq. 35 or eq. 31."""
    if profile == EXPONENTIAL:
        return exponential_distance(1.0, h, mu, t0, tau, H)
    return linear_distance(1.0, h, mu, t0, tau, H)


@njit
def ray_columns(origins, dirs, a, b, ux, uy, uz, h0, H, profile, out):
    """out[i] = `column` over [a[i], b[i]] of ray i."""
    for i in range(origins.shape[0]):
        h = origins[i, 0] * ux + origins[i, 1] * uy + origins[i, 2] * uz - h0
        mu = dirs[i, 0] * ux + dirs[i, 1] * uy + dirs[i, 2] * uz
        out[i] = column(h, mu, a[i], b[i], H, profile)


# numpy-broadcasting wrappers (tests, Python callers); kernels should call the scalar functions
constant_optical_depth_np = np.vectorize(constant_optical_depth, otypes=[float])
constant_distance_np = np.vectorize(constant_distance, otypes=[float])
exponential_optical_depth_np = np.vectorize(exponential_optical_depth, otypes=[float])
exponential_distance_np = np.vectorize(exponential_distance, otypes=[float])
linear_optical_depth_np = np.vectorize(linear_optical_depth, otypes=[float])
linear_distance_np = np.vectorize(linear_distance, otypes=[float])
