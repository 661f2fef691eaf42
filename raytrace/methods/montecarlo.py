"""`montecarlo`: unbiased single-scattering estimates of the air-light (METHODS.md §9.2).

Per camera ray, light and colour channel, `samples` distances x on the segment are drawn by
  * equiangular sampling (Kulla & Fajardo 2012): x = x_h + h tan(theta), theta uniform between the
    angles of the segment ends seen from the light; f/p is bounded (no 1/d^2 spike near lights);
  * free-path sampling: x from the transmittance exp(-kt x) truncated to the segment;
  * `mis`: one sample of each per iteration, combined by the balance heuristic (f / (p_e + p_f));
  * `cdf`: x drawn by inverting the exact air-light CDF along the segment (`_invert`), which the
    closed form gives: F(x) = analytic.airlight of the sub-segment [0, x]. Then p = f / F(ell) and
    every weight f/p is F(ell): zero variance unoccluded (per segment, hence also on the lit
    intervals of volumetric shadows), and with shadow_test = samples only the visibility's
    variance, F(ell)^2 P(1 - P) / n for a lit share P of F(ell). That is no lower bound for the
    other modes: a single-strategy mode's variance per sample minus cdf's is
    F(ell) E_cdf[(f/p - F(ell)) V], so equiangular wins where its weight f/p is below F(ell) on the
    lit parts (isotropic: the far ends of rays, f/p ~ exp(-kt (x + d))). Each cdf draw costs a few
    closed-form evaluations, F(ell) one per segment and channel, at CDF_PRECISION
    (benchmarks/mc_sampling.py).
Every mode but cdf is one sampler (`_estimate`) over a medium's paths record: homogeneous, a height
fog (seed 004; `_fog_estimate`: free-path sampling inverts the closed-form optical depth) or an
atmosphere (`_atm_estimate`: on the part of the segment inside the air, free-path distances by
safeguarded Newton on the sum of the layers' closed-form (Chapman) optical depths); a directional
light takes free-path draws only.
The estimator of eq. 4 is f(x)/p(x) with f = ks Phi(cos phi) I exp(-kt (x + d)) / d^2. Random
numbers come from `rng.uniform(ray key, dimension, seed)`, so results do not depend on threads.
A flat emitter's rows (quad, disk, flat emissive shape) move their node, in every iteration, to a point of
the emitter uniform in area, drawn in the kernel (`drawn_segments`): the sum over the rows estimates the
emitter's integral, not its cubature rule's (docs/area_lights.md), along rays where no shadow cuts the rows
(`_whole`); where one does (volumetric shadows), and with shadow_test = samples everywhere, its medium points
are those of the drawn points (`drawn_points`: homogeneous media, height fogs and atmospheres, each by its own
distance sampling and transmittance, `draw_points`), each point's shadow ray to its own drawn point
(shadows/penumbra_airlight.py `drawn`, shadows/shadow_rays.py): unbiased in penumbrae too.
Each ray also returns the variance of its mean over the `samples` draws, which the renderer turns
into per-pixel variance channels (the variance of the pixel's estimate).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..jit import njit
from ..media.integrand import integrand, record_dispatch
from ..rng import uniform
from . import AREA_LIGHTS, INSIDE_RTOL, LIGHTS, ErrorLaw, Interiors, Method, Param, Supports, by_kind
from .analytic import ANISO_EXACT, STATS_SIZE, ST_EVALS, ST_FALLBACK, airlight, make_coeffs, working_precision
from .geometry import (HL, HO, MU, AtmosphereInX, Eq4, FogInX, atmosphere_channels, atmosphere_in_x, atmosphere_row,
                       cone_row, fog_rows, segment_geometry, segment_light_table, spot_factor)
from ..errors import UserError
from ..lights.planar import emitter_pieces, emitter_point, flat_rows
from ..media import atmosphere as atmo
from ..media.atmosphere import segment_rows
from ..media import Atmosphere, HeightFog, Homogeneous
from ..media.fog import attenuated_density, column, column_distance
from ..media.phase import phase_split
from ..media.inside_rule import SAMPLE

EQUIANGULAR, FREEPATH, MIS, CDF = 0, 1, 2, 3
MODES = {"equiangular": EQUIANGULAR, "freepath": FREEPATH, "mis": MIS, "cdf": CDF}


@njit
def _strategies_used(mode, directional):
    """(equiangular?, free-path?) of a mode; the sun takes free-path draws only (equiangular needs
    a light position)."""
    return mode != FREEPATH and not directional, mode != EQUIANGULAR or directional


@njit
def _mean_var(acc, acc2, n):
    """Mean and variance of the mean of n estimates from their sum and sum of squares."""
    mean = acc / n
    return mean, max(acc2 / n - mean * mean, 0.0) / max(n - 1, 1)


@njit
def _p_equiangular(x, xh, h, th_a, th_b):
    s = x - xh
    return h / ((th_b - th_a) * (h * h + s * s))


@njit
def _p_freepath(x, kt, norm):
    """Density of exp(-kt x) truncated to the segment; norm = 1 - exp(-kt ell)."""
    return kt * math.exp(-kt * x) / norm


# --- the one sampler: equiangular, free-path or both (balance heuristic), over a medium's paths ------
#
# A paths record (HomogeneousPaths, FogPaths, AtmospherePaths below) gives the medium's part: its
# free-path draw and density, the camera's optical depth to a point (for the integrand, where it
# needs one) and the integrand f; `_sample` is one draw of one strategy with its weight f / p.

def free_path(paths, u):
    """(x, tau_cam): the free-path distance of the uniform number u and the camera's optical depth to it."""


def free_density(paths, x, tau):
    """The free-path density at x (tau: the camera's optical depth to x, where the record uses it)."""


def depth_to(paths, x):
    """The camera's optical depth to x where the record's integrand needs it (else unused)."""


def value(paths, x, tau):
    """The integrand f at x (unit light; tau as for free_density)."""


_free_path_of = record_dispatch(free_path, 0)
_free_density_of = record_dispatch(free_density, 0)
_depth_to_of = record_dispatch(depth_to, 0)
_value_of = record_dispatch(value, 0)


@njit
def _sample(paths, strategy, use_e, use_f, xh, h, th_a, th_b, lo, hi, key, dim, seed):
    """(x, f(x) / p(x)) of one draw of `strategy` (0 equiangular in [lo, hi], between the angles th_a,
    th_b seen from the light; 1 free-path), p the sum of the densities of the strategies used."""
    u = uniform(key, dim, seed)
    if strategy == 0:
        x = min(max(xh + h * math.tan(th_a + u * (th_b - th_a)), lo), hi)
        tau = depth_to(paths, x)
    else:
        x, tau = free_path(paths, u)
    p = 0.0
    if use_e:
        p += _p_equiangular(x, xh, h, th_a, th_b)
    if use_f:
        p += free_density(paths, x, tau)
    return x, (value(paths, x, tau) / p if p > 0.0 else 0.0)


@njit
def _estimate(paths, use_e, use_f, xh, h, th_a, th_b, lo, hi, n, key, dim0, seed):
    """Mean and variance of the mean of n estimates, each the sum of one draw per strategy used;
    iteration j draws the dimensions dim0 + 2 j (equiangular) and dim0 + 2 j + 1 (free-path)."""
    acc = 0.0
    acc2 = 0.0
    for j in range(n):
        est = 0.0
        for strategy in range(0 if use_e else 1, 2 if use_f else 1):
            est += _sample(paths, strategy, use_e, use_f, xh, h, th_a, th_b, lo, hi, key, dim0 + 2 * j + strategy,
                           seed)[1]
        acc += est
        acc2 += est * est
    return _mean_var(acc, acc2, n)


class HomogeneousPaths(NamedTuple):
    """A homogeneous segment [0, ell]: free paths from exp(-kt x) truncated to it (norm = 1 -
    exp(-kt ell)), f = eq. 4's integrand."""
    f: Eq4
    ell: float
    norm: float


@_free_path_of(HomogeneousPaths)
@njit
def _homogeneous_free_path(paths, u):
    return min(-math.log1p(-u * paths.norm) / paths.f.kt, paths.ell), 0.0


@_free_density_of(HomogeneousPaths)
@njit
def _homogeneous_density(paths, x, tau):
    return _p_freepath(x, paths.f.kt, paths.norm)


@_depth_to_of(HomogeneousPaths)
@njit
def _homogeneous_depth(paths, x):
    return 0.0


@_value_of(HomogeneousPaths)
@njit
def _homogeneous_value(paths, x, tau):
    return integrand(x, paths.f)


@njit
def _angles(xh, h, ell, kt):
    th_a = math.atan2(-xh, h)
    th_b = 0.5 * math.pi if ell == math.inf else math.atan2(ell - xh, h)
    return th_a, th_b, -math.expm1(-kt * ell)


@njit
def estimate(xh, h, ell, kt, ks, code, g, cone, mode, n, key, dim0, seed):
    """Mean and variance of the mean of n estimates of the air-light (unit intensity)."""
    if ks == 0.0 or not ell > 0.0:
        return 0.0, 0.0
    th_a, th_b, norm = _angles(xh, h, ell, kt)
    use_e, use_f = _strategies_used(mode, False)
    return _homogeneous_estimate(xh, h, ell, kt, ks, code, g, cone, use_e, use_f, th_a, th_b, norm, n, key, dim0, seed)


@njit
def _homogeneous_estimate(xh, h, ell, kt, ks, code, g, cone, use_e, use_f, th_a, th_b, norm, n, key, dim0, seed):
    """`estimate` given its angles th_a, th_b and free-path norm (`_angles`)."""
    paths = HomogeneousPaths(Eq4(xh, h, kt, ks, code, g, cone_row(cone)), ell, norm)
    return _estimate(paths, use_e, use_f, xh, h, th_a, th_b, 0.0, ell, n, key, dim0, seed)


@njit
def airlight_segments(xh, h, ell, cone, keys, stream, seed, intensity, kt, ks, code, g, mode, n, out, var):
    """Estimates (S, 3) of every segment's air-light and their variances; segment s draws the
    dimensions 2 n stream[s] + 2 j of its ray's key."""
    for s in range(xh.shape[0]):
        for c in range(3):
            m, v = estimate(xh[s], h[s], ell[s], kt[c], ks[c], code, g, cone[s], mode, n, keys[s], 2 * n * stream[s],
                            seed)
            out[s, c] = m * intensity[s, c]
            var[s, c] = v * intensity[s, c] * intensity[s, c]


@njit
def sample_points(origins, dirs, xh, h, ell, cone, keys, stream, seed, intensity, kt, ks, code, g, mode, n, pos,
                  weight):
    """The same samples as `airlight_segments`, as points for volumetric shadows: pos[s, j, k, c] is
    the point drawn by strategy k (0 equiangular, 1 free-path) in iteration j for segment s and
    channel c (free-path distances depend on the channel's kt), weight[s, j, k, c] its I f / p."""
    use_e, use_f = _strategies_used(mode, False)
    for s in range(xh.shape[0]):
        for j in range(n):
            _iteration_points(origins[s], dirs[s], xh[s], h[s], ell[s], cone[s], keys[s], 2 * n * stream[s] + 2 * j,
                              seed, intensity[s], kt, ks, code, g, use_e, use_f, pos[s, j], weight[s, j])


@njit
def _iteration_points(o, w, xh, h, ell, cone, key, dim, seed, intensity, kt, ks, code, g, use_e, use_f, pos, weight):
    """One iteration of `sample_points` (dimensions dim, dim + 1) of the segment o + x w, 0 <= x <= ell, lit from
    (x_h, h, cone): pos (2, 3, 3), weight (2, 3) per strategy and channel (left as they are where ks = 0)."""
    for c in range(3):
        if ks[c] == 0.0 or not ell > 0.0:
            continue
        th_a, th_b, norm = _angles(xh, h, ell, kt[c])
        paths = HomogeneousPaths(Eq4(xh, h, kt[c], ks[c], code, g, cone_row(cone)), ell, norm)
        _paths_points(paths, use_e, use_f, xh, h, th_a, th_b, 0.0, ell, key, dim, seed, o, w, intensity[c], c, pos,
                      weight)


@njit
def _paths_points(paths, use_e, use_f, xh, h, th_a, th_b, lo, hi, key, dim, seed, o, w, intensity, c, pos, weight):
    """One iteration of `_estimate` over the paths record (dimensions dim, dim + 1) as points of the segment
    o + x w: pos[k, c] (3,) strategy k's point (the segment's start for a strategy not used), weight[k, c] its
    intensity f / p (0 for a strategy not used)."""
    xe = xf = we = wf = 0.0
    if use_e:
        xe, we = _sample(paths, 0, use_e, use_f, xh, h, th_a, th_b, lo, hi, key, dim, seed)
    if use_f:
        xf, wf = _sample(paths, 1, use_e, use_f, xh, h, th_a, th_b, lo, hi, key, dim + 1, seed)
    for a in range(3):
        pos[0, c, a] = o[a] + xe * w[a]
        pos[1, c, a] = o[a] + xf * w[a]
    weight[0, c] = we * intensity
    weight[1, c] = wf * intensity


# ----------------------------------------------------------------------------------------------
# cdf: distances from the exact air-light CDF
# ----------------------------------------------------------------------------------------------
# The CDF's precision: F(x) is analytic.airlight at working_precision(CDF_PRECISION) (1e-12: below
# 1e-7 analytic works 1000 times finer than asked), so F(ell), the estimate unoccluded, carries a
# relative error ~1e-12 and the CDF values that steer the Newton iteration ~1e-12 F(ell). The price:
# at 1e-12 analytic's exact mode has no usable moment block for strongly peaked HG (g = 0.9), whose
# evaluations all go to its quadrature fallback (counted: "cdf: quadrature fallback fraction").
CDF_PRECISION = 1e-9
# Newton's stopping rule: |F(x) - u F(ell)| <= NEWTON_TOL F(ell) (see `_invert`).
NEWTON_TOL = 1e-9
MAX_STEPS = 100  # safeguard only: bisection alone reaches the resolution of doubles in < 60 steps
CDF_MAX_ITER = 1000  # analytic's Fig. 2 loop cap (its default)
CDF_TERMS = 6  # not read by the exact anisotropic mode

# cdf statistics (the method's stats array)
CS_INVERSIONS, CS_NEWTON, CS_BISECT, CS_EVALS, CS_FALLBACK = range(5)
CDF_STATS = 5


@njit
def _cdf_frame(xh, h, ell):
    """(A, r2): A = theta_b - theta_a in (0, pi), the segment's extent in angle seen from the light
    (one arctangent, without the cancellation of a difference of two on segments short in angle),
    and r2 = h^2 + x_h^2, the squared distance from the light to the segment's start."""
    if ell == math.inf:
        A = math.atan2(h, -xh)
    else:
        A = math.atan2(ell * h, h * h + xh * (xh - ell))
    return A, h * h + xh * xh


@njit
def _x_of(alpha, xh, h, r2, ell):
    """Distance x along the segment of the point at angle alpha = theta - theta_a from its start:
    x = h (tan theta - tan theta_a) = r2 sin(alpha) / (h cos(alpha) + x_h sin(alpha)), free of the
    cancellation of x_h + h tan(theta) near the start when the light is far ahead."""
    sa = math.sin(alpha)
    den = h * math.cos(alpha) + xh * sa
    if not den > 0.0:
        return ell
    return min(r2 * sa / den, ell)


@njit
def _density(x, xh, h, kt, code, g, cone):
    """dF/dtheta at x for ks = 1: Phi(cos phi) exp(-kt (x + d)) / h (the 1/d^2 of eq. 4 cancels
    against dx/dtheta = d^2 / h); 1 -+ cos phi = (d +- (x - x_h)) / d without cancellation."""
    if x == math.inf:
        return 0.0
    dx = x - xh
    hh = h * h
    d = math.sqrt(hh + dx * dx)
    if dx > 0.0:
        plus = d + dx
        minus = hh / plus
    else:
        minus = d - dx
        plus = hh / minus
    f = spot_factor(dx, d, h, cone)
    return f * math.exp(-kt * (x + d)) * phase_split(code, g, -dx / d, plus / d, minus / d) / h


@njit
def _cdf(x, xh, h, da, kt, code, g, cone, precision, coeffs, astats):
    """F(x): the closed-form air-light of the sub-segment [0, x] for ks = 1 and a unit light."""
    return airlight(xh, h, da, x, kt, 1.0, 1.0, code, g, precision, CDF_MAX_ITER, ANISO_EXACT, CDF_TERMS, coeffs,
                    cone, astats)


@njit
def _invert(u, xh, h, da, r2, ell, A, ftot, kt, code, g, cone, precision, coeffs, astats, cstats):
    """The distance x with F(x) = u F(ell): safeguarded Newton in alpha = theta - theta_a.

    Why the angle and not x: as a function of x the CDF has the shape of eq. 4's 1/d^2 peak; on a
    ray passing at h << ell from the light it rises from ~0 to ~F(ell) within a few h of x_h, a
    near-step whose derivative varies by (d_max / h)^2, so Newton from any point off the peak
    overshoots by ~ell / h, and on rays to infinity x is unbounded. In theta the 1/d^2 is absorbed
    exactly (dx = d^2 / h dtheta, the equiangular substitution): the domain is the bounded
    [0, A], A < pi, and dF/dtheta = ks Phi(cos phi) exp(-kt (x + d)) / h varies only through the
    phase function and the extinction. Where those are mild F(theta) is nearly linear and the
    equiangular guess alpha = u A (the exact answer for kt = 0 and isotropic scattering) is
    already close: Newton converges in a few steps (benchmarks/mc_sampling.py counts them).

    Bracket [lo, hi] = [0, A], narrowed by the sign of every residual F(x) - u F(ell); a Newton
    step (derivative `_density`) that leaves the bracket is replaced by bisection. Stops when
    |F(x) - u F(ell)| <= NEWTON_TOL F(ell), or when the bracket reaches the resolution of doubles.
    That tolerance bounds the Kolmogorov distance between the drawn distances' CDF and the exact
    one by 1e-9 (+ the ~1e-12 of the CDF values): an estimate weighted by a visibility of m lit
    intervals is biased by at most 2 m 1e-9 F(ell), far below any standard error a render can
    reach (1e-9 relative needs ~1e18 samples), while the CDF values' own error, ~1e-12 F(ell),
    is 1000 times smaller, so the bracket's sign decisions are sound. Newton's quadratic
    convergence makes the tolerance cheap: the last step typically goes from ~1e-5 to below it."""
    cstats[CS_INVERSIONS] += 1.0
    target = u * ftot
    tol = NEWTON_TOL * ftot
    lo, hi = 0.0, A
    alpha = u * A
    x = _x_of(alpha, xh, h, r2, ell)
    for _ in range(MAX_STEPS):
        r = _cdf(x, xh, h, da, kt, code, g, cone, precision, coeffs, astats) - target
        if abs(r) <= tol:
            break
        if r < 0.0:
            lo = alpha
        else:
            hi = alpha
        dens = _density(x, xh, h, kt, code, g, cone)
        nxt = alpha - r / dens if dens > 0.0 else hi
        if lo < nxt < hi:
            cstats[CS_NEWTON] += 1.0
        else:
            nxt = 0.5 * (lo + hi)
            cstats[CS_BISECT] += 1.0
            if not (lo < nxt < hi):  # the bracket is two adjacent doubles
                break
        alpha = nxt
        x = _x_of(alpha, xh, h, r2, ell)
    if x == math.inf:  # only if rounding put alpha at the end of a ray to infinity: its lower bracket
        x = _x_of(lo, xh, h, r2, ell)
    return x


@njit
def _totals(xh, h, da, ell, kt, ks, code, g, cone, precision, coeffs, astats, ftot):
    """ftot[c] = F(ell) of every channel for ks = 1 (0 where ks = 0; channels of equal kt share one
    evaluation)."""
    for c in range(3):
        ftot[c] = 0.0
        if ks[c] == 0.0 or not ell > 0.0:
            continue
        same = -1
        for c2 in range(c):
            if ks[c2] != 0.0 and kt[c2] == kt[c]:
                same = c2
        ftot[c] = ftot[same] if same >= 0 else _cdf(ell, xh, h, da, kt[c], code, g, cone, precision, coeffs, astats)


@njit
def airlight_segments_cdf(xh, h, da, ell, cone, intensity, kt, ks, code, g, precision, coeffs, out, var, stats):
    """`airlight_segments` for sampling = cdf: every sample's weight f/p is F(ell) wherever it
    lands (p = f / F(ell)), so unoccluded the mean of n samples is F(ell) with variance 0, and no
    distance needs to be drawn: one closed-form evaluation per segment and channel."""
    astats = np.zeros(STATS_SIZE)
    ftot = np.zeros(3)
    for s in range(xh.shape[0]):
        _totals(xh[s], h[s], da[s], ell[s], kt, ks, code, g, cone[s], precision, coeffs, astats, ftot)
        for c in range(3):
            out[s, c] = ks[c] * ftot[c] * intensity[s, c]
            var[s, c] = 0.0
    stats[CS_EVALS] += astats[ST_EVALS]
    stats[CS_FALLBACK] += astats[ST_FALLBACK]


@njit
def sample_points_cdf(origins, dirs, xh, h, da, ell, cone, keys, stream, seed, intensity, kt, ks, code, g, n,
                      precision, coeffs, pos, weight, stats):
    """`sample_points` for sampling = cdf (one strategy, k = 0): iteration j of segment s draws
    u = uniform(key, 2 n stream + 2 j, seed) (the equiangular sample's number) and, per channel,
    the distance with F(x) = u F(ell) (channels of equal kt share it); its weight is I ks F(ell)."""
    astats = np.zeros(STATS_SIZE)
    ftot = np.zeros(3)
    xs = np.zeros(3)
    for s in range(xh.shape[0]):
        _totals(xh[s], h[s], da[s], ell[s], kt, ks, code, g, cone[s], precision, coeffs, astats, ftot)
        for j in range(n):
            _cdf_iteration(origins[s], dirs[s], xh[s], h[s], da[s], ell[s], cone[s],
                           uniform(keys[s], 2 * n * stream[s] + 2 * j, seed), intensity[s], kt, ks, code, g, precision,
                           coeffs, ftot, xs, astats, stats, pos[s, j], weight[s, j])
    stats[CS_EVALS] += astats[ST_EVALS]
    stats[CS_FALLBACK] += astats[ST_FALLBACK]


@njit
def _cdf_iteration(o, w, xh, h, da, ell, cone, u, intensity, kt, ks, code, g, precision, coeffs, ftot, xs, astats,
                   cstats, pos, weight):
    """One iteration of `sample_points_cdf` of the segment o + x w, 0 <= x <= ell, lit from (x_h, h, d_a, cone),
    its totals ftot (3,) (`_totals`), the uniform number u: pos (1, 3, 3), weight (1, 3); xs (3,) scratch."""
    A, r2 = _cdf_frame(xh, h, ell)
    for c in range(3):
        if not ftot[c] > 0.0:
            continue
        same = -1
        for c2 in range(c):
            if ftot[c2] > 0.0 and kt[c2] == kt[c]:
                same = c2
        if same >= 0:
            xs[c] = xs[same]
        else:
            xs[c] = _invert(u, xh, h, da, r2, ell, A, ftot[c], kt[c], code, g, cone, precision, coeffs, astats,
                            cstats)
        for a in range(3):
            pos[0, c, a] = o[a] + xs[c] * w[a]
        weight[0, c] = ks[c] * ftot[c] * intensity[c]


def _args(segs, medium, lights, params):
    xh, h, _, cone = segment_geometry(segs, lights)
    return (xh, h, segs.length, cone, segs.keys, segs.stream, np.uint64(segs.seed), lights.intensity[segs.light],
            medium.sigma_t, medium.sigma_s, medium.phase, medium.g, MODES[params["sampling"]], params["samples"])


def cdf_setup(medium):
    """(precision, coeffs) of the CDF's closed form for this medium (analytic's exact mode)."""
    precision = working_precision(CDF_PRECISION)
    return precision, make_coeffs(medium.phase, medium.g, ANISO_EXACT, CDF_TERMS, precision)


def _airlight(segs, medium, lights, params):
    flat = _flat(segs, lights)
    if not flat.any():
        return by_kind(_BY_KIND, medium)(segs, medium, lights, params)
    out, stats, var = np.zeros((len(segs), 3)), np.zeros(CDF_STATS), np.zeros((len(segs), 3))
    for at, estimate in ((np.nonzero(~flat)[0], by_kind(_BY_KIND, medium)), (np.nonzero(flat)[0], _draws)):
        if len(at):
            out[at], st, var[at] = estimate(segs.take(at), medium, lights, params)
            stats += st
    return out, stats, var


def _atmosphere(segs, atm, lights, params):
    keys = np.ascontiguousarray(segs.keys, dtype=np.uint64)

    def evaluate(rows, directional, xh, h, cone, kt, ks):
        mean, v = np.empty_like(xh), np.empty_like(xh)
        atmosphere_segments(rows, directional, xh, h, cone, keys, segs.stream, np.uint64(segs.seed), kt, ks, atm.phases,
                            atm.gs, atm.layers, float(atm.radius), float(atm.top), MODES[params["sampling"]],
                            params["samples"], mean, v)
        return mean, v

    out, var = atmosphere_channels(segs, atm, lights, evaluate, variance=True)
    return out, np.zeros(CDF_STATS), var


def _fog(segs, medium, lights, params):
    out = np.zeros((len(segs), 3))
    var = np.zeros_like(out)
    xh, h, _, cone = segment_geometry(segs, lights)
    rows, directional = fog_rows(segs, medium, lights)
    fog_segments(rows, directional, xh, h, segs.length, cone, segs.keys, segs.stream, np.uint64(segs.seed),
                 lights.intensity[segs.light], medium.sigma_t, medium.sigma_s, medium.phase, medium.g,
                 medium.scale_height, medium.profile, MODES[params["sampling"]], params["samples"], out, var)
    return out, np.zeros(CDF_STATS), var


def _homogeneous(segs, medium, lights, params):
    out = np.zeros((len(segs), 3))
    var = np.zeros_like(out)
    stats = np.zeros(CDF_STATS)
    if params["sampling"] == "cdf":
        xh, h, da, cone = segment_geometry(segs, lights)
        airlight_segments_cdf(xh, h, da, segs.length, cone, lights.intensity[segs.light], medium.sigma_t, medium.sigma_s,
                              medium.phase, medium.g, *cdf_setup(medium), out, var, stats)
    else:
        airlight_segments(*_args(segs, medium, lights, params), out, var)
    return out, stats, var


def _strategies(params):
    return 1 if params["sampling"] == "cdf" else 2


def _points(segs, medium, lights, params):
    """`Method.points`. With shadow_test = samples a flat emitter's rows (`flat_rows`) draw their light's point
    per iteration (`drawn_points`, in any medium: the renderer hands it only those rows outside homogeneous
    media) and a third array, targets (S, n, 3), says where each iteration's shadow rays go (the other rows':
    their lights); with intervals (the points of the pieces whose light crosses index-matched interiors,
    interiors/rows.py) every row keeps its node."""
    shape = (len(segs), params["samples"], _strategies(params), 3)
    flat = flat_rows(lights)[segs.light] if params["shadow_test"] == "samples" else np.zeros(len(segs), bool)
    if not flat.any():
        return _row_points(segs, medium, lights, params, shape)
    rows, at = np.nonzero(~flat)[0], np.nonzero(flat)[0]
    pos, weight = np.zeros(shape + (3,)), np.zeros(shape)
    if len(rows):
        pos[rows], weight[rows] = _row_points(segs.take(rows), medium, lights, params, (len(rows),) + shape[1:])
    targets = np.repeat(lights.position[segs.light][:, None, :], params["samples"], axis=1)
    drawn = segs.take(at)
    part = (np.zeros((len(at),) + shape[1:] + (3,)), np.zeros((len(at),) + shape[1:]), targets[at])
    drawn_points(by_kind(_RECORDS, medium)(drawn, medium, lights, params), *_emitter_args(drawn, lights),
                 params["samples"], *part)
    pos[at], weight[at], targets[at] = part
    return pos, weight, targets


def _row_points(segs, medium, lights, params, shape):
    """(pos, weight) of `_points` with every row's light at its node."""
    pos = np.zeros(shape + (3,))
    weight = np.zeros(shape)
    if params["sampling"] == "cdf":
        xh, h, da, cone = segment_geometry(segs, lights)
        sample_points_cdf(segs.origins, segs.dirs, xh, h, da, segs.length, cone, segs.keys, segs.stream, np.uint64(segs.seed),
                          lights.intensity[segs.light], medium.sigma_t, medium.sigma_s, medium.phase, medium.g,
                          params["samples"], *cdf_setup(medium), pos, weight, np.zeros(CDF_STATS))
    else:
        sample_points(segs.origins, segs.dirs, *_args(segs, medium, lights, params), pos, weight)
    return pos, weight


# ----------------------------------------------------------------------------------------------
# flat emitters (quads, disks, flat emissive shapes): each row's light drawn over the emitter per iteration
# ----------------------------------------------------------------------------------------------
DIM_EMITTER = 1 << 51  # the first random-number dimension of the flat emitters' points (rng.py)
DRAW_BLOCK = 256  # segments whose draws one pass of `drawn_segments` holds


def draw_estimate(rec, s, point, xh, h, da, cone, key, dim0, seed, est):
    """est (3,) = one iteration's unit-intensity estimate per channel of segment s of the record `rec` (a
    medium's draws: HomogeneousDraws, FogDraws, AtmosphereDraws) with its row's light at `point` (3,), of
    geometry (x_h, h, d_a, cone row) from its start, the distances drawn from the dimensions dim0 on."""


_draw_estimate_of = record_dispatch(draw_estimate, 0, inline=True)


@njit
def drawn_segments(rec, origins, dirs, axis, lcone, first, last, kind, frame, upper, keys, stream, seed, scale,
                   intensity, n, out, var):
    """Mean and variance of the mean (S, 3) over n iterations of every segment of a flat emitter's row: iteration
    j moves the row's light to a point of the emitter uniform in area (lights/planar.py `emitter_point` of
    the pieces first[s] .. last[s] - 1, numbers from the dimensions DIM_EMITTER + 2 (n stream[s] + j) and the
    next), keeps its axis and cone (axis, lcone (S, 3): the row's) and its intensity L w, and draws the
    distances of the rows' iteration j (dimensions 2 n stream[s] + 2 j on): the rows' weights of a side sum
    to its area A and the point has density 1 / A, so the sum over the rows estimates the emitter's integral
    (not its rule's)."""
    points = np.empty((DRAW_BLOCK, 3))
    index = np.arange(DRAW_BLOCK)
    acc, acc2, est = np.zeros((DRAW_BLOCK, 3)), np.zeros((DRAW_BLOCK, 3)), np.zeros(3)
    for b0 in range(0, origins.shape[0], DRAW_BLOCK):
        m = min(DRAW_BLOCK, origins.shape[0] - b0)
        acc[:] = 0.0
        acc2[:] = 0.0
        for j in range(n):
            xh, h, da, cone = _draw_block(origins, dirs, axis, lcone, first, last, kind, frame, upper, keys, stream,
                                          seed, scale, n, b0, m, j, points, index)
            for i in range(m):
                s = b0 + i
                draw_estimate(rec, s, points[i], xh[i], h[i], da[i], cone[i], keys[s], 2 * n * stream[s] + 2 * j,
                              seed, est)
                for c in range(3):
                    e = est[c] * intensity[s, c]
                    acc[i, c] += e
                    acc2[i, c] += e * e
        for i in range(m):
            for c in range(3):
                out[b0 + i, c], var[b0 + i, c] = _mean_var(acc[i, c], acc2[i, c], n)


@njit
def _draw_block(origins, dirs, axis, lcone, first, last, kind, frame, upper, keys, stream, seed, scale, n, b0, m, j,
                points, index):
    """points[:m] (DRAW_BLOCK, 3): iteration j's drawn points of the segments b0 .. b0 + m - 1 (`drawn_segments`),
    and (x_h, h, d_a, cone rows) of each segment's light moved there (`segment_light_table`)."""
    for i in range(m):
        s = b0 + i
        dim = DIM_EMITTER + 2 * (n * stream[s] + j)
        points[i, 0], points[i, 1], points[i, 2] = emitter_point(
            kind, frame, upper, first[s], last[s], uniform(keys[s], dim, seed), uniform(keys[s], dim + 1, seed))
    return segment_light_table(origins[b0:b0 + m], dirs[b0:b0 + m], points, axis[b0:b0 + m], lcone[b0:b0 + m],
                               index[:m], scale)


@njit
def drawn_points(rec, origins, dirs, axis, lcone, first, last, kind, frame, upper, keys, stream, seed, scale, intensity,
                 n, pos, weight, targets):
    """The draws of `drawn_segments` (the same points of the emitter and dimensions) as medium points for shadow
    rays (`draw_points`): pos (S, n, K, 3, 3), weight (S, n, K, 3) as `sample_points`' (cdf: `sample_points_cdf`'s),
    targets[s, j] (3,) the point of the emitter drawn in iteration j: the medium points' shadow rays go there, so
    that their visibility is the drawn point's, not the row's node's."""
    points = np.empty((DRAW_BLOCK, 3))
    index = np.arange(DRAW_BLOCK)
    for b0 in range(0, origins.shape[0], DRAW_BLOCK):
        m = min(DRAW_BLOCK, origins.shape[0] - b0)
        for j in range(n):
            xh, h, da, cone = _draw_block(origins, dirs, axis, lcone, first, last, kind, frame, upper, keys, stream,
                                          seed, scale, n, b0, m, j, points, index)
            for i in range(m):
                s = b0 + i
                targets[s, j] = points[i]
                draw_points(rec, s, points[i], xh[i], h[i], da[i], cone[i], origins[s], dirs[s], keys[s],
                            2 * n * stream[s] + 2 * j, seed, intensity[s], pos[s, j], weight[s, j])


def draw_points(rec, s, point, xh, h, da, cone, o, w, key, dim0, seed, intensity, pos, weight):
    """`draw_estimate`'s draws as points of the segment o + x w: pos (K, 3, 3) per strategy and channel, weight
    (K, 3) their intensity f / p (intensity (3,): the row's)."""


_draw_points_of = record_dispatch(draw_points, 0)


@njit
def _same_channel(kt, ks, c):
    """The first channel before c of the same coefficients (its estimate is c's), else -1."""
    for c2 in range(c):
        if kt[c2] == kt[c] and ks[c2] == ks[c]:
            return c2
    return -1


class HomogeneousDraws(NamedTuple):
    """`draw_estimate`'s record in a homogeneous medium: segment lengths ell (S,), free-path norms 1 - exp(-kt ell)
    (S, 3), coefficients kt, ks (3,), phase, sampling mode, the cdf mode's (precision, coeffs) and scratch
    (astats: analytic's counters, ftot and xs (3,), cstats: the cdf mode's counters)."""
    ell: np.ndarray
    norm: np.ndarray
    kt: np.ndarray
    ks: np.ndarray
    code: int
    g: float
    mode: int
    precision: float
    coeffs: np.ndarray
    astats: np.ndarray
    ftot: np.ndarray
    xs: np.ndarray
    cstats: np.ndarray


@_draw_estimate_of(HomogeneousDraws, inline=True)
@njit
def _homogeneous_draw(rec, s, point, xh, h, da, cone, key, dim0, seed, est):
    """`estimate` of one iteration per channel (the angles once, the norms of `HomogeneousDraws`); cdf: F(ell)
    (`_totals`)."""
    if rec.mode == CDF:
        _totals(xh, h, da, rec.ell[s], rec.kt, rec.ks, rec.code, rec.g, cone, rec.precision, rec.coeffs, rec.astats,
                rec.ftot)
        for c in range(3):
            est[c] = rec.ks[c] * rec.ftot[c]
        return
    ell = rec.ell[s]
    th_a, th_b, _ = _angles(xh, h, ell, 0.0)
    use_e, use_f = _strategies_used(rec.mode, False)
    for c in range(3):
        same = _same_channel(rec.kt, rec.ks, c)
        if same >= 0:
            est[c] = est[same]
        elif rec.ks[c] == 0.0 or not ell > 0.0:
            est[c] = 0.0
        else:
            est[c] = _homogeneous_estimate(xh, h, ell, rec.kt[c], rec.ks[c], rec.code, rec.g, cone, use_e, use_f, th_a,
                                           th_b, rec.norm[s, c], 1, key, dim0, seed)[0]


@_draw_points_of(HomogeneousDraws)
@njit
def _homogeneous_points(rec, s, point, xh, h, da, cone, o, w, key, dim0, seed, intensity, pos, weight):
    """`_iteration_points` (cdf: `_cdf_iteration`, its number the equiangular draw's) of the segment."""
    if rec.mode == CDF:
        _totals(xh, h, da, rec.ell[s], rec.kt, rec.ks, rec.code, rec.g, cone, rec.precision, rec.coeffs, rec.astats,
                rec.ftot)
        _cdf_iteration(o, w, xh, h, da, rec.ell[s], cone, uniform(key, dim0, seed), intensity, rec.kt, rec.ks,
                       rec.code, rec.g, rec.precision, rec.coeffs, rec.ftot, rec.xs, rec.astats, rec.cstats, pos, weight)
        return
    use_e, use_f = _strategies_used(rec.mode, False)
    _iteration_points(o, w, xh, h, rec.ell[s], cone, key, dim0, seed, intensity, rec.kt, rec.ks, rec.code, rec.g,
                      use_e, use_f, pos, weight)


class FogDraws(NamedTuple):
    """`draw_estimate`'s record in a height fog: the segments' `fog_rows` (S, 5) (a row's light height HL is
    the drawn point's), lengths ell (S,), the fog's up (3,) and h0, coefficients kt, ks (3,), phase, scale
    height, profile, sampling mode and a scratch row (5,)."""
    rows: np.ndarray
    ell: np.ndarray
    up: np.ndarray
    h0: float
    kt: np.ndarray
    ks: np.ndarray
    code: int
    g: float
    H: float
    profile: int
    mode: int
    row: np.ndarray


@_draw_estimate_of(FogDraws, inline=True)
@njit
def _fog_draw(rec, s, point, xh, h, da, cone, key, dim0, seed, est):
    """`_fog_estimate` of one iteration per channel, the light at `point`."""
    row = _fog_row(rec, s, point)
    for c in range(3):
        same = _same_channel(rec.kt, rec.ks, c)
        est[c] = est[same] if same >= 0 else _fog_estimate(row, False, xh, h, rec.ell[s], rec.kt[c], rec.ks[c],
                                                           rec.code, rec.g, cone, rec.H, rec.profile, rec.mode, 1,
                                                           key, dim0, seed)[0]


@_draw_points_of(FogDraws)
@njit
def _fog_points(rec, s, point, xh, h, da, cone, o, w, key, dim0, seed, intensity, pos, weight):
    """`_fog_draw`'s draws as points (`_paths_points`; none where a channel does not scatter)."""
    row = _fog_row(rec, s, point)
    use_e, use_f = _strategies_used(rec.mode, False)
    for c in range(3):
        paths, th_a, th_b = _fog_paths(row, False, xh, h, rec.ell[s], rec.kt[c], rec.ks[c], rec.code, rec.g, cone,
                                       rec.H, rec.profile)
        if paths.norm > 0.0:
            _paths_points(paths, use_e, use_f, xh, h, th_a, th_b, 0.0, rec.ell[s], key, dim0, seed, o, w, intensity[c],
                          c, pos, weight)


@njit
def _fog_row(rec, s, point):
    """rec.row: segment s's fog row with its light's height HL the point's."""
    row = rec.row
    row[:] = rec.rows[s]
    row[HL] = point[0] * rec.up[0] + point[1] * rec.up[1] + point[2] * rec.up[2] - rec.h0
    return row


class AtmosphereDraws(NamedTuple):
    """`draw_estimate`'s record in an atmosphere: the segments' `atmosphere.segment_rows` (S, ROW) (a row's
    light LX, LY, LZ is the drawn point's, from the planet's centre (3,)), per channel its layers'
    coefficients kt, ks (3, K), the layers' phases, radius, top, sampling mode and scratch (`_atm_estimate`'s
    cols, pieces and buf, a row (ROW,))."""
    rows: np.ndarray
    centre: np.ndarray
    kt: np.ndarray
    ks: np.ndarray
    codes: np.ndarray
    gs: np.ndarray
    Hs: np.ndarray
    R: float
    top: float
    mode: int
    cols: np.ndarray
    pieces: np.ndarray
    buf: np.ndarray
    row: np.ndarray


@_draw_estimate_of(AtmosphereDraws, inline=True)
@njit
def _atmosphere_draw(rec, s, point, xh, h, da, cone, key, dim0, seed, est):
    """`_atm_estimate` of one iteration per channel (0 where no layer scatters it), the light at `point`."""
    row = _atm_row(rec, s, point)
    for c in range(3):
        est[c] = 0.0
        if not np.any(rec.ks[c] > 0.0):
            continue
        est[c] = _atm_estimate(row, False, xh, h, cone, rec.kt[c], rec.ks[c], rec.codes, rec.gs, rec.Hs, rec.R, rec.top,
                               rec.mode, 1, key, dim0, seed, rec.cols, rec.pieces, rec.buf)[0]


@_draw_points_of(AtmosphereDraws)
@njit
def _atmosphere_points(rec, s, point, xh, h, da, cone, o, w, key, dim0, seed, intensity, pos, weight):
    """`_atmosphere_draw`'s draws as points (`_paths_points` on the part in the air; none where a channel does not
    scatter)."""
    row = _atm_row(rec, s, point)
    use_e, use_f = _strategies_used(rec.mode, False)
    for c in range(3):
        if not np.any(rec.ks[c] > 0.0):
            continue
        paths, th_a, th_b = _atm_paths(row, False, xh, h, cone, rec.kt[c], rec.ks[c], rec.codes, rec.gs, rec.Hs,
                                       rec.R, rec.top, rec.cols, rec.pieces, rec.buf)
        if paths.norm > 0.0:
            _paths_points(paths, use_e, use_f, xh, h, th_a, th_b, row[atmo.A], row[atmo.B], key, dim0, seed, o, w,
                          intensity[c], c, pos, weight)


@njit
def _atm_row(rec, s, point):
    """`atmosphere_row` of rec.row: segment s's row with its light LX, LY, LZ the point's."""
    row = rec.row
    row[:] = rec.rows[s]
    row[atmo.LX], row[atmo.LY], row[atmo.LZ] = (point[0] - rec.centre[0], point[1] - rec.centre[1],
                                                point[2] - rec.centre[2])
    return atmosphere_row(row)


def _emitter_args(segs, lights):
    """The arguments of `drawn_segments` and `drawn_points` from the segments' origins to their intensities."""
    kind, frame, upper, first, last = emitter_pieces(lights)
    owner = lights.owner[segs.light]
    return (segs.origins, segs.dirs, lights.axis[segs.light], lights.cone[segs.light], first[owner], last[owner], kind,
            frame, upper, np.ascontiguousarray(segs.keys, dtype=np.uint64), np.asarray(segs.stream, np.int64),
            np.uint64(segs.seed), float(segs.scale), lights.intensity[segs.light])


def _draws(segs, medium, lights, params):
    """`Method.airlight` of flat emitters' rows by `drawn_segments` (cdf: with its closed form's counters)."""
    rec = by_kind(_RECORDS, medium)(segs, medium, lights, params)
    out, var = np.zeros((len(segs), 3)), np.zeros((len(segs), 3))
    drawn_segments(rec, *_emitter_args(segs, lights), params["samples"], out, var)
    stats = np.zeros(CDF_STATS)
    if params["sampling"] == "cdf":  # homogeneous media only (`_check`)
        stats[CS_EVALS], stats[CS_FALLBACK] = rec.astats[ST_EVALS], rec.astats[ST_FALLBACK]
    return out, stats, var


def _homogeneous_record(segs, medium, lights, params):
    cdf = params["sampling"] == "cdf"
    ell = np.asarray(segs.length, float)
    with np.errstate(invalid="ignore"):  # kt = 0 on rays to infinity: a channel that does not scatter (ks = 0)
        norm = -np.expm1(-np.outer(ell, medium.sigma_t))
    return HomogeneousDraws(ell, norm, medium.sigma_t, medium.sigma_s, medium.phase, medium.g,
                            MODES[params["sampling"]], *(cdf_setup(medium) if cdf else (1.0, np.zeros(1))),
                            np.zeros(STATS_SIZE), np.zeros(3), np.zeros(3), np.zeros(CDF_STATS))


def _fog_record(segs, medium, lights, params):
    rows, _ = fog_rows(segs, medium, lights)
    return FogDraws(rows, np.asarray(segs.length, float), np.asarray(medium.up, float), float(medium.h0),
                    medium.sigma_t, medium.sigma_s, medium.phase, medium.g, medium.scale_height, medium.profile,
                    MODES[params["sampling"]], np.zeros(5))


def _atmosphere_record(segs, atm, lights, params):
    rows = np.empty((len(segs), atmo.ROW))
    centre = np.asarray(atm.center, float)
    segment_rows(segs.origins, segs.dirs, np.asarray(segs.length, float), lights.position, lights.axis, segs.light,
                 np.zeros(len(segs), bool), *centre, float(atm.radius), float(atm.top), rows)
    return AtmosphereDraws(rows, centre, np.ascontiguousarray(atm.layer_sigma_t.T),
                           np.ascontiguousarray(atm.layer_sigma_s.T), atm.phases, atm.gs, atm.layers, float(atm.radius),
                           float(atm.top), MODES[params["sampling"]], np.empty(atm.layers.shape[0]), np.empty((3, 4)),
                           np.empty(2), np.empty(atmo.ROW))


_RECORDS = {Homogeneous: _homogeneous_record, HeightFog: _fog_record, Atmosphere: _atmosphere_record}


def _flat(segs, lights) -> np.ndarray:
    """(S,) whether each segment is of a flat emitter's row (lights/planar.py `flat_rows`) whose side of the
    emitter is whole along its ray (`_whole`): those take `drawn_segments`, the rest keep their rows."""
    flat_row = flat_rows(lights)
    flat = flat_row[segs.light]
    if flat.any():
        flat[flat] = _whole(segs, lights, flat_row, flat)
    return flat


WHOLE_RTOL = 1e-9  # of the scene's size: how far the pieces of one emitter's rows may start and end apart


def _whole(segs, lights, flat_row, flat) -> np.ndarray:
    """(count of flat,) whether each of the segments `flat` (rows of flat emitters) lies where every row of its
    emitter's side (a two-sided emitter's sides apart) has one segment on the ray, all the same piece to
    WHOLE_RTOL: no shadow cuts the rows along the ray (as without volumetric shadows), so that the emitter's
    points off the nodes are taken as lit as they. Elsewhere (a penumbra cuts the rows' pieces) the rows stay:
    their nodes' visibility weighs their own points. `flat_row` (L,): `flat_rows(lights)`."""
    rows = np.nonzero(flat_row)[0]
    owner = lights.owner[rows]
    first = np.zeros(len(lights.emitters), np.int64)
    emitters, at_first = np.unique(owner, return_index=True)
    first[emitters] = rows[at_first]
    side = np.zeros(len(lights), np.int64)
    side[rows] = 2 * owner + (np.einsum("ij,ij->i", lights.axis[rows], lights.axis[first[owner]]) < 0.0)
    expected = np.bincount(side[rows], minlength=2 * len(lights.emitters))
    at = np.nonzero(flat)[0]
    group = side[segs.light[at]]
    _, inverse, count = np.unique(segs.ray[at].astype(np.int64) * len(expected) + group, return_inverse=True,
                                  return_counts=True)
    inverse = inverse.ravel()
    of = np.zeros(len(count), np.int64)
    of[inverse] = group
    start = segs.t0[at]
    end = start + segs.length[at]
    tol = np.zeros(len(count))
    np.maximum.at(tol, inverse, WHOLE_RTOL * (segs.scale + np.abs(start) + np.where(np.isfinite(end), end, 0.0)))
    whole = count == expected[of]
    for v in (start, end):
        hi, lo = np.full(len(count), -np.inf), np.full(len(count), np.inf)
        np.maximum.at(hi, inverse, v)
        np.minimum.at(lo, inverse, v)
        with np.errstate(invalid="ignore"):
            whole &= (hi == lo) | (hi - lo <= tol)
    return whole[inverse]




def _summarize(stats):
    """The cdf mode's counters (nothing for the other modes)."""
    if not stats[CS_EVALS] > 0.0:
        return {}
    out = {"cdf: closed-form evaluations": int(stats[CS_EVALS]),
           "cdf: quadrature fallback fraction": stats[CS_FALLBACK] / stats[CS_EVALS]}
    if stats[CS_INVERSIONS] > 0.0:
        out["cdf: newton steps per inversion"] = stats[CS_NEWTON] / stats[CS_INVERSIONS]
        out["cdf: bisection steps per inversion"] = stats[CS_BISECT] / stats[CS_INVERSIONS]
    return out



class FogPaths(NamedTuple):
    """A height-fog segment [0, ell]: free paths invert the closed-form optical depth (norm = 1 -
    T_cam(ell)), f = `geometry.FogInX`."""
    f: FogInX
    ell: float
    norm: float


@_free_path_of(FogPaths)
@njit
def _fog_free_path(paths, u):
    r = paths.f
    tau = -math.log1p(-u * paths.norm) / r.kt
    return min(column_distance(r.row[HO], r.row[MU], 0.0, tau, r.H, r.profile), paths.ell), 0.0


@_free_density_of(FogPaths)
@njit
def _fog_density(paths, x, tau):
    r = paths.f
    row, H, profile = r.row, r.H, r.profile
    return r.kt * attenuated_density(row[HO] + row[MU] * x, r.kt * column(row[HO], row[MU], 0.0, x, H, profile), H,
                                     profile) / paths.norm


@_depth_to_of(FogPaths)
@njit
def _fog_depth(paths, x):
    return 0.0


@_value_of(FogPaths)
@njit
def _fog_value(paths, x, tau):
    return integrand(x, paths.f)


@njit
def _fog_estimate(row, directional, xh, h, ell, kt, ks, code, g, cone, H, profile, mode, n, key, dim0, seed):
    """`estimate` in a height fog (seed 004): f = `fog_inscatter` (/ d^2 for point and spot lights);
    free-path draws invert the closed-form optical depth, x = column_distance(-log(1 - u N) / kt)
    with N = 1 - T_cam(ell) and p = kt rho(x) T_cam(x) / N (eq. 35 / 31); a directional light takes
    free-path draws in every mode (equiangular needs a light position)."""
    paths, th_a, th_b = _fog_paths(row, directional, xh, h, ell, kt, ks, code, g, cone, H, profile)
    if not paths.norm > 0.0:
        return 0.0, 0.0
    use_e, use_f = _strategies_used(mode, directional)
    return _estimate(paths, use_e, use_f, xh, h, th_a, th_b, 0.0, ell, n, key, dim0, seed)


@njit
def _fog_paths(row, directional, xh, h, ell, kt, ks, code, g, cone, H, profile):
    """(FogPaths, th_a, th_b) of `_fog_estimate`'s segment; the record's norm is 0 where nothing scatters."""
    norm = 0.0
    if ks != 0.0 and ell > 0.0:
        norm = -math.expm1(-kt * column(row[HO], row[MU], 0.0, ell, H, profile))
    th_a, th_b, _ = _angles(xh, h, ell, kt)
    return FogPaths(FogInX(row, xh, h, kt, ks, code, g, cone_row(cone), H, profile, directional), ell, norm), th_a, th_b


@njit
def fog_segments(rows, directional, xh, h, ell, cone, keys, stream, seed, intensity, kt, ks, code, g, H, profile,
                 mode, n, out, var):
    """`airlight_segments` in a height fog (the same random-number dimensions)."""
    for s in range(xh.shape[0]):
        for c in range(3):
            m, v = _fog_estimate(rows[s], directional[s], xh[s], h[s], ell[s], kt[c], ks[c], code, g, cone[s], H,
                                 profile, mode, n, keys[s], 2 * n * stream[s], seed)
            out[s, c] = m * intensity[s, c]
            var[s, c] = v * intensity[s, c] * intensity[s, c]


class AtmospherePaths(NamedTuple):
    """An atmosphere segment's part [A, B] inside the air, one channel: free paths over the pieces
    (lo, hi, tau(A, lo), mass) of `pieces[:m]` (norm: their total mass), by `atmosphere.free_path`;
    f = `geometry.atmosphere_in_x` at the camera's optical depth."""
    f: AtmosphereInX
    pieces: np.ndarray
    m: int
    norm: float


@_free_path_of(AtmospherePaths)
@njit
def _atm_free_path(paths, u):
    """The piece holding u N, then its optical depth from A: the target, to Newton's 1e-13."""
    pieces, m = paths.pieces, paths.m
    v = u * paths.norm
    k = 0
    while k < m - 1 and v >= pieces[k, 3]:
        v -= pieces[k, 3]
        k += 1
    v = min(v, pieces[k, 3])
    tau_cam = pieces[k, 2] - math.log1p(-v * math.exp(pieces[k, 2]))
    r = paths.f
    row = r.row
    x = atmo.free_path(row, row[atmo.A], row[atmo.B], tau_cam, r.kt, r.Hs, r.R, r.top, r.cols)
    return min(max(x, pieces[k, 0]), pieces[k, 1]), tau_cam


@_free_density_of(AtmospherePaths)
@njit
def _atm_density(paths, x, tau):
    r = paths.f
    return atmo.extinction_at(x, r.row, r.kt, r.Hs, r.R) * math.exp(-tau) / paths.norm


@_depth_to_of(AtmospherePaths)
@njit
def _atm_depth(paths, x):
    r = paths.f
    row = r.row
    atmo.columns(row[atmo.H0], row[atmo.MU0], row[atmo.A], x, r.R, r.top, r.Hs, r.cols)
    return atmo.optical_depth(r.cols, r.kt)


@_value_of(AtmospherePaths)
@njit
def _atm_value(paths, x, tau):
    return atmosphere_in_x(x, paths.f, tau)


@njit
def _atm_estimate(row, directional, xh, h, cone, kt, ks, codes, gs, Hs, R, top, mode, n, key, dim0, seed, cols,
                  pieces, buf):
    """`estimate` in an atmosphere, one channel: on the part [A, B] of the segment inside the air,
    f = `atmosphere.inscatter` (x F / d^2 for point and spot lights); free-path draws, restricted
    for a directional light to the pieces outside the planet's shadow (`atmosphere.sunlit`:
    elsewhere f = 0), solve tau(A, x) = the target of u in that truncated distribution by
    `atmosphere.free_path`, p = kt(x) T(A, x) / N with N its mass (1 - T(A, B) for one piece); a
    directional light takes free-path draws in every mode. row: `geometry.atmosphere_row`;
    pieces (3, 4), buf (2,): scratch."""
    paths, th_a, th_b = _atm_paths(row, directional, xh, h, cone, kt, ks, codes, gs, Hs, R, top, cols, pieces, buf)
    if not paths.norm > 0.0:
        return 0.0, 0.0
    use_e, use_f = _strategies_used(mode, directional)
    return _estimate(paths, use_e, use_f, xh, h, th_a, th_b, row[atmo.A], row[atmo.B], n, key, dim0, seed)


@njit
def _atm_paths(row, directional, xh, h, cone, kt, ks, codes, gs, Hs, R, top, cols, pieces, buf):
    """(AtmospherePaths, th_a, th_b) of `_atm_estimate`'s segment (its pieces filled in `pieces`); the record's
    norm is 0 where the segment has no part in the air."""
    a, b = row[atmo.A], row[atmo.B]
    h0, mu0 = row[atmo.H0], row[atmo.MU0]
    m = 0
    if b > a:
        m = 1
        pieces[0, 0], pieces[0, 1] = a, b
        if directional:
            m = atmo.sunlit(row, R, buf, pieces)
    norm = 0.0
    for k in range(m):  # pieces[k] = (lo, hi, tau(A, lo), mass)
        atmo.columns(h0, mu0, a, pieces[k, 0], R, top, Hs, cols)
        pieces[k, 2] = atmo.optical_depth(cols, kt)
        atmo.columns(h0, mu0, pieces[k, 0], pieces[k, 1], R, top, Hs, cols)
        pieces[k, 3] = math.exp(-pieces[k, 2]) * -math.expm1(-atmo.optical_depth(cols, kt))
        norm += pieces[k, 3]
    th_a, th_b = math.atan2(a - xh, h), math.atan2(b - xh, h)
    paths = AtmospherePaths(AtmosphereInX(row, directional, xh, h, cone_row(cone), kt, ks, codes, gs, Hs, R, top, cols),
                            pieces, m, norm)
    return paths, th_a, th_b


@njit
def atmosphere_segments(rows, directional, xh, h, cone, keys, stream, seed, kt, ks, codes, gs, Hs, R, top, mode, n,
                        out, var):
    """Unit-intensity estimates and their variances of every atmosphere segment, one channel (the
    same random-number dimensions as `airlight_segments`)."""
    cols = np.empty(Hs.shape[0])
    pieces = np.empty((3, 4))
    buf = np.empty(2)
    for s in range(xh.shape[0]):
        out[s], var[s] = _atm_estimate(atmosphere_row(rows[s]), directional[s], xh[s], h[s], cone[s], kt, ks, codes,
                                       gs, Hs, R, top, mode, n, keys[s], 2 * n * stream[s], seed, cols, pieces, buf)


# ----------------------------------------------------------------------------------------------
# sphere emitters: distances along the ray, then directions in the cone the sphere subtends
# ----------------------------------------------------------------------------------------------
DIM_SPHERE = 1 << 50  # the first random-number dimension of the sphere emitters' samples (rng.py)
SPHERE_DIMS = 8  # dimensions per iteration: each strategy's distance, then its direction's two
SPHERE_DRAWS = 128  # iterations per sample: as many as the rows (2 x 8^2, lights/sphere.py) whose samples they replace


@njit
def _cone_light(x, o, d, c, R, kt, code, g, u, v):
    """One sample of the light the sphere (centre c, radius R, unit radiance) scatters at the point
    x = o + x d toward the camera: a direction w uniform in the cone it subtends (half-angle alpha,
    solid angle 2 pi (1 - cos alpha)), met by the sphere at t_y along it. Returns (2 pi (1 - cos alpha)
    Phi(d·w) exp(-kt t_y), w, t_y) (Lambertian: the radiance is L in every direction)."""
    a0, a1, a2 = c[0] - o[0] - x * d[0], c[1] - o[1] - x * d[1], c[2] - o[2] - x * d[2]
    dist = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    a0, a1, a2 = a0 / dist, a1 / dist, a2 / dist
    s2 = min(R * R / (dist * dist), 1.0)  # sin^2 alpha
    one_minus_a = s2 / (1.0 + math.sqrt(1.0 - s2))  # 1 - cos alpha
    one_minus = u * one_minus_a  # 1 - cos theta, theta the angle from the axis
    ct = 1.0 - one_minus
    st = math.sqrt(max(one_minus * (2.0 - one_minus), 0.0))
    if abs(a0) < 0.9:  # b = a unit vector across a, e = a x b
        b0, b1, b2 = 0.0, -a2, a1
    else:
        b0, b1, b2 = -a1, a0, 0.0
    nb = math.sqrt(b0 * b0 + b1 * b1 + b2 * b2)
    b0, b1, b2 = b0 / nb, b1 / nb, b2 / nb
    e0, e1, e2 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
    cp, sp = st * math.cos(2.0 * math.pi * v), st * math.sin(2.0 * math.pi * v)
    w = (ct * a0 + cp * b0 + sp * e0, ct * a1 + cp * b1 + sp * e1, ct * a2 + cp * b2 + sp * e2)
    chord = math.sqrt(max(R * R - dist * dist * st * st, 0.0))
    t_y = max(dist * dist - R * R, 0.0) / (dist * ct + chord)  # the nearer root, without cancellation
    mu = d[0] * w[0] + d[1] * w[1] + d[2] * w[2]
    f = 2.0 * math.pi * one_minus_a * phase_split(code, g, mu, 1.0 - mu, 1.0 + mu) * math.exp(-kt * t_y)
    return f, w, t_y


@njit
def _sphere_frame(o, d, ell, c, kt):
    """(x_h, h, theta_a, theta_b, 1 - exp(-kt ell)) of the ray o + x d, 0 <= x <= ell, about the centre c."""
    xh = (c[0] - o[0]) * d[0] + (c[1] - o[1]) * d[1] + (c[2] - o[2]) * d[2]
    h = 0.0
    for k in range(3):
        h += (c[k] - o[k] - xh * d[k]) ** 2
    h = max(math.sqrt(h), 1e-300)
    th_a, th_b, norm = _angles(xh, h, ell, kt)
    return xh, h, th_a, th_b, norm


@njit
def _sphere_draw(o, d, ell, c, R, kt, code, g, mode, frame, k, key, dim, seed):
    """One draw of strategy k (0 equiangular about the centre, 1 free-path; balance heuristic as
    `_sample`) of a sphere emitter's air-light along the ray o + x d, 0 <= x <= ell (outside the sphere)
    for ks = 1 and unit radiance: the distance x (dimension dim + k), a direction in the cone
    (`_cone_light`, dimensions dim + 2 + 2 k, dim + 3 + 2 k). Returns (x, exp(-kt x) times the
    direction's estimate / p(x) (0 where p is), w, t_y)."""
    xh, h, th_a, th_b, norm = frame
    use_e, use_f = _strategies_used(mode, False)
    u = uniform(key, dim + k, seed)
    if k == 0:
        x = min(max(xh + h * math.tan(th_a + u * (th_b - th_a)), 0.0), ell)
    else:
        x = min(-math.log1p(-u * norm) / kt, ell)
    p = (_p_equiangular(x, xh, h, th_a, th_b) if use_e else 0.0) + (_p_freepath(x, kt, norm) if use_f else 0.0)
    if not (p > 0.0 and x < math.inf):
        return x, 0.0, (0.0, 0.0, 1.0), 0.0
    f, w, t_y = _cone_light(x, o, d, c, R, kt, code, g, uniform(key, dim + 2 + 2 * k, seed),
                            uniform(key, dim + 3 + 2 * k, seed))
    return x, math.exp(-kt * x) * f / p, w, t_y


@njit
def _shared_channel(kt, ch):
    """The first channel before ch with the same extinction (its draws are ch's), else -1."""
    for c in range(ch):
        if kt[c] == kt[ch]:
            return c
    return -1


@njit
def sphere_means(origins, dirs, tmax, keys, seed, c, R, kt, code, g, mode, n, dim0, out, var):
    """Mean and variance of the mean over n iterations (each one draw per strategy used, `_sphere_draw`,
    iteration j from dimension dim0 + SPHERE_DIMS j) of every camera ray and channel, unoccluded."""
    use_e, use_f = _strategies_used(mode, False)
    for r in range(origins.shape[0]):
        for ch in range(3):
            same = _shared_channel(kt, ch)
            if same >= 0:
                out[r, ch], var[r, ch] = out[r, same], var[r, same]
                continue
            if not tmax[r] > 0.0:
                continue
            frame = _sphere_frame(origins[r], dirs[r], tmax[r], c, kt[ch])
            acc = acc2 = 0.0
            for j in range(n):
                est = 0.0
                for k in range(0 if use_e else 1, 2 if use_f else 1):
                    est += _sphere_draw(origins[r], dirs[r], tmax[r], c, R, kt[ch], code, g, mode, frame, k, keys[r],
                                        dim0 + SPHERE_DIMS * j, seed)[1]
                acc += est
                acc2 += est * est
            out[r, ch], var[r, ch] = _mean_var(acc, acc2, n)


@njit
def sphere_samples(origins, dirs, tmax, keys, seed, c, R, kt, code, g, mode, n, dim0, pos, wdir, dist, weight):
    """The draws of `sphere_means` for shadow rays: of camera ray r, iteration j, strategy k and channel ch
    the point pos[r, j, k, ch], the unit direction wdir[...] to the sphere, its distance dist[...] and
    the weight weight[...] (0 for a strategy not used); pos, wdir (P, n, 2, 3, 3), dist, weight (P, n, 2, 3)."""
    use_e, use_f = _strategies_used(mode, False)
    for r in range(origins.shape[0]):
        for ch in range(3):
            if not tmax[r] > 0.0:
                continue
            frame = _sphere_frame(origins[r], dirs[r], tmax[r], c, kt[ch])
            for j in range(n):
                for k in range(0 if use_e else 1, 2 if use_f else 1):
                    x, weight[r, j, k, ch], w, dist[r, j, k, ch] = _sphere_draw(
                        origins[r], dirs[r], tmax[r], c, R, kt[ch], code, g, mode, frame, k, keys[r],
                        dim0 + SPHERE_DIMS * j, seed)
                    for a in range(3):
                        pos[r, j, k, ch, a] = origins[r, a] + x * dirs[r, a]
                        wdir[r, j, k, ch, a] = w[a]


SPHERE_CHUNK = 1 << 16  # a sphere's samples (rays x iterations x strategies) per batch of rays


def _sphere(medium, params):
    """`Method.sphere`: in a homogeneous medium (but for cdf sampling) estimate(ball, radiance, owner, rays,
    rs, visible) -> (value, variance), each (len(rs), 3), of a sphere emitter along the camera rays rs
    (`_sphere_draw`, SPHERE_DRAWS iterations per sample, dimensions from DIM_SPHERE + owner SPHERE_DIMS
    SPHERE_DRAWS samples; `visible(points, dirs, distances)` whether each sample's sphere point is in
    sight, None: all), with either shadow test (rendering/near_emitters.py); else None."""
    if not isinstance(medium, Homogeneous) or params["sampling"] == "cdf":
        return None
    n = SPHERE_DRAWS * params["samples"]

    def estimate(ball, radiance, owner, rays, rs, visible=None):
        out, var = np.zeros((len(rs), 3)), np.zeros((len(rs), 3))
        step = max(1, SPHERE_CHUNK // (2 * n))
        for at in range(0, len(rs), step):
            out[at:at + step], var[at:at + step] = _sphere_part(medium, params["sampling"], n, ball, owner, rays,
                                                                 rs[at:at + step], visible)
        scale = medium.sigma_s * np.asarray(radiance, float)
        return out * scale, var * scale ** 2
    return estimate


def _sphere_part(medium, sampling, n, ball, owner, rays, rs, visible):
    """`_sphere`'s estimate of unit radiance and ks = 1 along the camera rays rs (one batch), n iterations."""
    origins, dirs, tmax, keys, seed = rays
    args = (np.ascontiguousarray(origins[rs]), np.ascontiguousarray(dirs[rs]),
            np.ascontiguousarray(np.asarray(tmax, float)[rs]), np.ascontiguousarray(keys[rs], dtype=np.uint64),
            np.uint64(seed), np.asarray(ball.centre, float), float(ball.radius), medium.sigma_t, medium.phase, medium.g,
            MODES[sampling], n, DIM_SPHERE + owner * SPHERE_DIMS * n)
    if visible is None:
        out, var = np.zeros((len(rs), 3)), np.zeros((len(rs), 3))
        sphere_means(*args, out, var)
        return out, var
    pos, wdir = np.zeros((len(rs), n, 2, 3, 3)), np.zeros((len(rs), n, 2, 3, 3))
    dist, weight = np.zeros((len(rs), n, 2, 3)), np.zeros((len(rs), n, 2, 3))
    sphere_samples(*args, pos, wdir, dist, weight)
    weight *= _in_sight(pos, wdir, dist, weight, visible)
    est = weight.sum(axis=2)  # (P, n, 3) per iteration
    return est.mean(axis=1), (est.var(axis=1, ddof=1) / n if n > 1 else np.zeros((len(rs), 3)))


def _in_sight(pos, wdir, dist, weight, visible) -> np.ndarray:
    """(same shape as weight) `visible` of each weighted sample; a channel whose samples are channel 0's
    (the same extinction, or equiangular draws) shares its answers."""
    out = np.zeros(weight.shape, bool)
    ask = np.any(weight != 0.0, axis=-1)
    out[..., 0][ask] = visible(pos[..., 0, :][ask], wdir[..., 0, :][ask], dist[..., 0][ask])
    for c in (1, 2):
        if np.array_equal(pos[..., c, :], pos[..., 0, :]) and np.array_equal(wdir[..., c, :], wdir[..., 0, :]):
            out[..., c] = out[..., 0]
            continue
        ask = weight[..., c] != 0.0
        out[..., c][ask] = visible(pos[..., c, :][ask], wdir[..., c, :][ask], dist[..., c][ask])
    return out


def _check(medium, params):
    if not medium.homogeneous and params["sampling"] == "cdf":
        raise UserError(f"method montecarlo: --sampling cdf inverts the homogeneous medium's closed-form air-light; "
                        f"in {medium.type_name} media use --sampling equiangular, freepath or mis")


METHOD = Method(
    name="montecarlo",
    summary="unbiased single scattering: equiangular, free-path, MIS or exact-CDF distance sampling, per-pixel "
            "variance",
    params={
        "samples": Param(4, int, "distance samples per camera ray, light and strategy", 1),
        "sampling": Param("equiangular", str, "equiangular (best near lights in thin media), freepath, mis "
                          "(balance heuristic, one sample of each), or cdf (inverting the exact air-light CDF: "
                          "zero variance unoccluded, only the visibility's with --shadow-test samples)",
                          choices=tuple(MODES)),
        "shadow_test": Param("intervals", str, "with volumetric shadows: integrate the lit intervals (exact between "
                             "shadow boundaries) or samples (a shadow ray per medium sample, the classic)",
                             choices=("intervals", "samples")),
    },
    airlight=_airlight,
    sphere=_sphere,
    error_law=ErrorLaw({"samples": 1024}, "sigma", 3.5),  # worst 1.8 over 100 seeds; at 64 samples 4.2 (g = 0.9)
    stats_size=CDF_STATS,
    summarize=_summarize,
    stochastic=True,
    points=_points,
    point_count=lambda segs, medium, params: np.full(len(segs), _strategies(params) * params["samples"]),
    check=_check,
    supports=Supports(lights=LIGHTS + AREA_LIGHTS, media=(Homogeneous, HeightFog, Atmosphere),
                      interiors=Interiors(SAMPLE, exact_paths=True, lights=LIGHTS + AREA_LIGHTS,
                                          refracted=LIGHTS + AREA_LIGHTS,
                                          settings=lambda params: (INSIDE_RTOL, params["samples"], 745.0), through="points"),
                      shadow_tests=("intervals", "samples")),
)
_BY_KIND = {Homogeneous: _homogeneous, HeightFog: _fog, Atmosphere: _atmosphere}
