"""Seed 004's height fogs on flat ground: optical depth of a ray segment and its inverse
(docs/optical_depth.md §1). A ray is given by ``h`` = o·up - h0, the height of its origin above the
reference height, and ``mu`` = d·up; t0 <= t1 are distances along it (t1 may be inf).

* constant:    sigma(p) = sigma0                                  (eq. 25-27)
* linear:      sigma(p) = sigma0 max(0, 1 - (p·up - h0)/H)        (eq. 28-31; zero above h0 + H)
* exponential: sigma(p) = sigma0 exp(-(p·up - h0)/H)              (eq. 32-35)

Every result is a product of non-negative factors (no difference of two optical depths, no
exp of a positive argument except the density at the segment's densest end, which overflows only
when the optical depth itself exceeds the float range); infinite optical depths come out as inf.
"""
import math

import numpy as np

from ..jit import njit


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


# numpy-broadcasting wrappers (tests, Python callers); kernels should call the scalar functions
constant_optical_depth_np = np.vectorize(constant_optical_depth, otypes=[float])
constant_distance_np = np.vectorize(constant_distance, otypes=[float])
exponential_optical_depth_np = np.vectorize(exponential_optical_depth, otypes=[float])
exponential_distance_np = np.vectorize(exponential_distance, otypes=[float])
linear_optical_depth_np = np.vectorize(linear_optical_depth, otypes=[float])
linear_distance_np = np.vectorize(linear_distance, otypes=[float])
