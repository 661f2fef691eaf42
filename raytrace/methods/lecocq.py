"""`lecocq`: Lecocq et al. 2000 / Biri et al. 2003-2006 angular formulation with a Taylor expansion
of the whole integrand about the light's foot point (METHODS.md §1, §8; PP09 Table 1 comparison).

With theta = arctan((x - x_h) / h) in (-pi/2, pi/2) (the angle at the light, measured from the
perpendicular to the ray; phi = theta + pi/2) the air-light of a unit-intensity light is

    Lm = (ks / h) exp(-kt x_h) * int_{theta_a}^{theta_b} exp(-H (tan theta + sec theta)) Phi_c(-sin theta) dtheta,

H = kt h. The method replaces the integrand by its Taylor polynomial about theta = 0 (the foot
point), with `terms` terms (degree terms - 1):

    exp(-H (tan + sec)) Phi_c(-sin) = exp(-H) * sum_k c_k(H) theta^k + O(theta^terms),
    Lm ~ (ks / h) exp(-kt (x_h + h)) * sum_k c_k (theta_b^{k+1} - theta_a^{k+1}) / (k + 1).

The coefficients are computed by truncated power-series arithmetic, not typed by hand:
T(theta) = tan + sec from the series of sin and cos (sec = 1/cos, tan = sin * sec; its
coefficients are the zigzag numbers / n!), exp(-H (T - 1)) by the exp recurrence, and the phase
series Phi_c(-sin theta) (isotropic: constant; Rayleigh: 3/(16 pi) (1 + sin^2); Henyey-Greenstein:
(1 - g^2)/(4 pi) (1 + g^2 + 2 g sin)^(-3/2) by the power recurrence), multiplied and truncated.
Defaults (PP09's description of Lecocq's method): 5 terms isotropic, 3 terms Rayleigh; we use 3
for HG too (not compared in PP09).

FAITHFUL, NOT FIXED: the results are the raw values of the truncated expansion -- no clamping to
non-negative, no fallback. Far from the foot point (looking away from the light, theta_a > 0, or
larger H) the polynomial is not the integrand, and the method returns negative estimates and
large over-evaluations: PP09's "ghosting ... negative estimates followed by large
over-evaluations". The prefactor exp(-kt (x_h + h)) is the optical path light -> foot point ->
camera; it exceeds 1 for lights behind the camera (x_h < 0), which is exactly where the
polynomial fails to supply the missing exp(-2 kt |x_h|). It is combined with the polynomial in log
space, so nothing over/underflows on the way; the only non-raw case is a result whose magnitude
exceeds SATURATE (1e300, optical depths of ~690 behind the camera), which is saturated to
+-SATURATE and counted in the stats so images stay finite.
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from . import ErrorLaw, Method, Param
from .geometry import by_channel
from ..media.phase import HG, INV_4PI, ISOTROPIC, RAYLEIGH

MAX_TERMS = 16
SATURATE = 1e300
_LOG_SATURATE = math.log(SATURATE)
DEFAULT_TERMS = {ISOTROPIC: 5, RAYLEIGH: 3, HG: 3}

# stats slots
EVALS, NEGATIVE, SATURATED = 0, 1, 2


# ---- truncated power series (coefficient arrays, index = power) ----

@njit
def ser_mul(a, b, n):
    out = np.zeros(n)
    for i in range(min(n, a.shape[0])):
        for j in range(min(n - i, b.shape[0])):
            out[i + j] += a[i] * b[j]
    return out


@njit
def ser_recip(a, n):
    """1/a, a[0] != 0."""
    out = np.zeros(n)
    out[0] = 1.0 / a[0]
    for k in range(1, n):
        acc = 0.0
        for j in range(1, min(k, a.shape[0] - 1) + 1):
            acc += a[j] * out[k - j]
        out[k] = -acc / a[0]
    return out


@njit
def ser_pow(b, alpha, n):
    """b^alpha, b[0] > 0 (J.C.P. Miller's recurrence): p_k = sum_j ((alpha+1) j - k) b_j p_{k-j} / (k b_0)."""
    out = np.zeros(n)
    out[0] = b[0] ** alpha
    for k in range(1, n):
        acc = 0.0
        for j in range(1, min(k, b.shape[0] - 1) + 1):
            acc += ((alpha + 1.0) * j - k) * b[j] * out[k - j]
        out[k] = acc / (k * b[0])
    return out


def _sin_cos(n):
    s, c = np.zeros(n), np.zeros(n)
    for k in range(n):
        v = (-1.0) ** (k // 2) / math.factorial(k)
        if k % 2:
            s[k] = v
        else:
            c[k] = v
    return s, c


def tan_sec_series(n=MAX_TERMS):
    """Coefficients of tan(theta) + sec(theta) (= 1, 1, 1/2, 2/3!, 5/4!, 16/5!, ... zigzag / n!)."""
    s, c = _sin_cos(n)
    sec = ser_recip(c, n)
    return ser_mul(s, sec, n) + sec


def phase_series(code, g, n=MAX_TERMS):
    """Coefficients of Phi_c(-sin theta) in theta (mu = -sin theta is the cosine of the scattering angle)."""
    s, _ = _sin_cos(n)
    if code == ISOTROPIC:
        out = np.zeros(n)
        out[0] = INV_4PI
        return out
    if code == RAYLEIGH:
        out = ser_mul(s, s, n)
        out[0] += 1.0
        return 3.0 / (16.0 * math.pi) * out
    base = 2.0 * g * s  # 1 + g^2 - 2 g mu, mu = -sin
    base[0] += 1.0 + g * g
    return (1.0 - g * g) * INV_4PI * ser_pow(base, -1.5, n)


@njit
def coeffs_into(H, tsec, pser, terms, work):
    """c_k (k < terms) into work[:terms], using work[MAX_TERMS:] as scratch; no allocation.
    exp(-H (tan + sec)) Phi_c(-sin) = exp(-H) sum_k c_k theta^k + O(theta^terms)."""
    e = work[MAX_TERMS:]
    e[0] = 1.0  # exp(-H (T - 1)): e_k = (1/k) sum_j j q_j e_{k-j}, q_j = -H T_j
    for k in range(1, terms):
        acc = 0.0
        for j in range(1, k + 1):
            acc += j * tsec[j] * e[k - j]
        e[k] = -H * acc / k
    for k in range(terms):
        acc = 0.0
        for j in range(k + 1):
            acc += e[j] * pser[k - j]
        work[k] = acc


@njit
def integrand_coeffs(H, tsec, pser, terms):
    """c_k, k < terms (allocating wrapper of coeffs_into)."""
    work = np.zeros(2 * MAX_TERMS)
    coeffs_into(H, tsec, pser, terms, work)
    return work[:terms].copy()


@njit
def airlight_one(xh, h, ell, kt, ks, tsec, pser, terms, work, stats):
    """Lecocq's truncated-Taylor air-light of the segment [0, ell] (ell may be inf), unit light, one channel.
    tsec, pser: series of tan + sec and of the phase (length MAX_TERMS); work: scratch of 2 MAX_TERMS."""
    if ks == 0.0 or not ell > 0.0:
        return 0.0
    stats[EVALS] += 1.0
    h = max(h, 1e-300)
    H = kt * h
    ta = math.atan2(-xh, h)
    tb = 0.5 * math.pi if ell == math.inf else math.atan2(ell - xh, h)
    coeffs_into(H, tsec, pser, terms, work)
    s = 0.0
    pa, pb = ta, tb
    for k in range(terms):
        s += work[k] * (pb - pa) / (k + 1)
        pa *= ta
        pb *= tb
    if s == 0.0:
        return 0.0
    if s < 0.0:
        stats[NEGATIVE] += 1.0
    logmag = math.log(ks) - math.log(h) - kt * (xh + h) + math.log(abs(s))
    if logmag > _LOG_SATURATE:
        stats[SATURATED] += 1.0
        return math.copysign(SATURATE, s)
    return math.copysign(math.exp(logmag), s)


@njit
def evaluate_segments(xh, h, ell, kt, ks, tsec, pser, terms, out, stats):
    """Unit-intensity air-light of every segment for one channel's coefficients."""
    work = np.zeros(2 * MAX_TERMS)
    for s in range(xh.shape[0]):
        out[s] = airlight_one(xh[s], h[s], ell[s], kt, ks, tsec, pser, terms, work, stats)


_TSEC = tan_sec_series(MAX_TERMS)


def effective_terms(code, terms):
    return DEFAULT_TERMS[code] if not terms else int(terms)


def _airlight(segs, medium, lights, params):
    stats = np.zeros(3)
    terms = effective_terms(medium.phase, params["terms"])
    pser = phase_series(medium.phase, float(medium.g), MAX_TERMS)

    def evaluate(xh, h, da, ell, kt, ks, cone):
        out = np.empty_like(xh)
        evaluate_segments(xh, h, ell, kt, ks, _TSEC, pser, terms, out, stats)
        return out

    return by_channel(segs, medium, lights, evaluate), stats


def _summarize(stats):
    return {"air-light evaluations": int(stats[EVALS]), "negative estimates": int(stats[NEGATIVE]),
            "saturated estimates": int(stats[SATURATED])}


METHOD = Method(
    name="lecocq",
    summary="Lecocq et al. 2000: Taylor polynomial of the whole angular integrand about the foot point (raw, unclamped)",
    params={"terms": Param(0, int, "Taylor terms (0 = 5 isotropic, 3 Rayleigh/HG), at most 16", 0, MAX_TERMS)},
    airlight=_airlight,
    error_law=ErrorLaw({}, "median", 0.75),  # measured worst 0.50 (thick: about half the air-light); zeros give 1
    stats_size=3,
    summarize=_summarize,
)
