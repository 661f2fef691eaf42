"""`quadrature`: the noise-free reference air-light, adaptive Gauss-Legendre in the scattering angle.

The air-light (paper eq. 4) is split at the light's foot point x_h. Before it the variable is the
scattering angle phi (x = x_h - h cot phi), after it psi = pi - phi (x = x_h + h cot psi); both are
measured from the nearer asymptote, so they keep full relative precision for lights far along the
ray. With dx = h / sin^2 and d = h / sin, each piece becomes (METHODS.md §1, §9.2)

    Lm = (ks I / h) ∫ exp(-kt (x_h + h tan(phi/2))) Phi(cos phi) dphi      (x <= x_h)
       + (ks I / h) ∫ exp(-kt (x_h + h cot(psi/2))) Phi(-cos psi) dpsi     (x >= x_h)

whose integrands are bounded and smooth (a spot light's falloff multiplies them; the pieces are
split where the ray crosses its cone's edge and the edge of its full-intensity core, where the
smoothstep's derivatives jump, lights.py); x + d = x_h + h v is the whole optical path
light → x → camera, so nothing overflows for lights behind the camera. Each interval is
accepted when its 10- and 20-point Gauss-Legendre values agree to `rtol` relative to the interval, or
to rtol/10 of a first estimate of the whole integral per unit angle (so that negligible tails, like
the essential singularity of exp(-kt h cot(psi/2)) at psi = 0 on rays to infinity, are not chased);
all contributions are positive, so the total meets `rtol` (the 20-point value is far more accurate
than the test).

The bound (homogeneous media; docs/error_bounds.md): each accepted interval's 20-point value is
taken to be within |G20 - G10| of its integral, which the test keeps below rtol |G20| or the floor
times its width; over a segment that sums to rtol (value + estimate / 10), and BOUND_FACTOR x rtol x
value covers it while the first estimate is within 10x of the value (the positive integrands' 20-point
sums). An integral with an interval accepted at a cap is infinite. Height fog and atmospheres report
no bound yet (their closed-form transmittances carry no error bound of their own).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .. import error_bounds
from ..jit import njit
from . import AREA_LIGHTS, LIGHTS, ErrorLaw, Interiors, Method, Param, Supports, by_kind
from .geometry import (COSD, HO, MU, MUS, AtmosphereInX, atmosphere_channels, atmosphere_inscatter,
                       atmosphere_row, by_channel, cone_row, fog_inscatter, fog_rows, spot_factor)
from ..lights import cone_breaks, falloff, is_spot
from ..media import atmosphere as atmo
from ..media.adaptive import CAPPED, EVALS, INTERVALS, first_estimate, piecewise, refine, rule
from ..media.integrand import integrand_of
from ..media import Atmosphere, HeightFog, Homogeneous
from ..media.fog import column, column_distance, top_distance
from ..media.phase import phase_split, phase_value
from ..media.slab import QUAD


BOUND_FACTOR = 2.0
_N10, _W10 = np.polynomial.legendre.leggauss(10)
_N20, _W20 = np.polynomial.legendre.leggauss(20)


class AngleIntegrand(NamedTuple):
    """The homogeneous air-light in the scattering angle (module docstring): piece 0 in phi before
    the foot point, 1 in psi after it, for a unit light (x_h, h) with the cone row `cone`."""
    piece: int
    xh: float
    h: float
    kt: float
    code: int
    g: float
    cone: tuple  # cone_row


@njit
def _integrand(piece, s, xh, h, kt, code, g, cone):
    t = math.tan(0.5 * s)
    t2 = t * t
    if piece == 0:  # s = phi, before the foot point: 1 - mu = 2 t^2 / (1 + t^2)
        path = xh + h * t
        mu = (1.0 - t2) / (1.0 + t2)
        one_minus, one_plus = 2.0 * t2 / (1.0 + t2), 2.0 / (1.0 + t2)
    else:  # s = psi, after the foot point: 1 + mu = 2 t^2 / (1 + t^2)
        path = xh + h / t
        mu = -(1.0 - t2) / (1.0 + t2)
        one_minus, one_plus = 2.0 / (1.0 + t2), 2.0 * t2 / (1.0 + t2)
    f = 1.0
    if is_spot(cone[3]):  # cosine to the axis A sin(phi) - B cos(phi), sin(phi) = sin(psi) = 2t / (1 + t^2)
        f = falloff(cone[0] * 2.0 * t / (1.0 + t2) - cone[1] * mu, cone[2], cone[3], cone[4])
    return f * math.exp(-kt * path) * phase_split(code, g, mu, one_minus, one_plus)


@integrand_of(AngleIntegrand)
@njit
def _angle_value(s, r):
    return _integrand(r.piece, s, r.xh, r.h, r.kt, r.code, r.g, r.cone)


@njit
def _rule(piece, a, b, xh, h, kt, code, g, cone, nodes, weights):
    """`rule` of one piece's AngleIntegrand (analytic.py integrates spot bands with it)."""
    return rule(a, b, AngleIntegrand(piece, xh, h, kt, code, g, cone_row(cone)), nodes, weights)


@njit
def _cuts(xh, h, cone, phi_a, phi_b, psi_end, psi_start, out0, out1):
    """A spot light's cone crossings (lights.cone_breaks) as breakpoints of the two pieces: out0 the
    angles phi in (phi_a, phi_b), out1 the angles psi in (psi_end, psi_start), each ascending, between
    the piece's ends; returns their lengths."""
    out0[0], out1[0] = phi_a, psi_end
    n0 = n1 = 1
    if is_spot(cone[3]):
        for C in (cone[2], cone[3]):
            k, r1, r2 = cone_breaks(cone[0], cone[1], C)
            for i in range(k):
                v = r1 if i == 0 else r2
                if v < 1.0:
                    phi = 2.0 * math.atan(v)
                    if phi_a < phi < phi_b:
                        out0[n0] = phi
                        n0 += 1
                else:
                    psi = 2.0 * math.atan(1.0 / v)
                    if psi_end < psi < psi_start:
                        out1[n1] = psi
                        n1 += 1
        out0[1:n0].sort()
        out1[1:n1].sort()
    out0[n0], out1[n1] = phi_b, psi_start
    return n0 + 1, n1 + 1


@njit
def airlight_one(xh, h, ell, kt, ks, code, g, cone, rtol, n10, w10, n20, w20, stats):
    """Air-light of one ray segment [0, ell] for a unit-intensity light (x_h, h) in one channel,
    with a spot light's falloff if `cone` (geometry.py) has one (split at the cone's crossings)."""
    if ks == 0.0 or ell <= 0.0:
        return 0.0
    stats[EVALS] += 1.0
    phi_a = phi_b = psi_end = psi_start = 0.0
    if xh > 0.0:  # part of the segment lies before the foot point: phi in (0, pi/2]
        phi_a = math.atan2(h, xh)
        phi_b = math.atan2(h, xh - min(xh, ell))
    if ell > xh:  # part after the foot point: psi in (0, pi/2]
        psi_end = 0.0 if ell == math.inf else math.atan2(h, ell - xh)
        psi_start = math.atan2(h, max(0.0, xh) - xh)
    b0 = np.empty(6)
    b1 = np.empty(6)
    n0, n1 = _cuts(xh, h, cone, phi_a, phi_b, psi_end, psi_start, b0, b1)
    # a first estimate of the whole integral sets an absolute floor per unit angle, so that tails
    # contributing less than rtol/10 of the total are not refined to full relative accuracy
    before = AngleIntegrand(0, xh, h, kt, code, g, cone_row(cone))
    after = AngleIntegrand(1, xh, h, kt, code, g, cone_row(cone))
    width = (phi_b - phi_a) + (psi_start - psi_end)
    estimate = first_estimate(after, b1, n1, n20, w20, first_estimate(before, b0, n0, n20, w20, 0.0))
    density = 0.1 * rtol * estimate / width if width > 0.0 else 0.0
    total, ok0 = refine(before, b0, n0, rtol, density, n10, w10, n20, w20, stats, 0.0)
    total, ok1 = refine(after, b1, n1, rtol, density, n10, w10, n20, w20, stats, total)
    if not (ok0 and ok1):
        stats[CAPPED] += 1.0
    return ks / h * total


@njit
def evaluate_segments(xh, h, ell, kt, ks, code, g, cone, rtol, n10, w10, n20, w20, out, met, stats):
    """Unit-intensity air-light of every segment for one channel's coefficients, and whether every
    interval of each met its tolerance (`met`)."""
    for s in range(xh.shape[0]):
        capped = stats[CAPPED]
        out[s] = airlight_one(xh[s], h[s], ell[s], kt, ks, code, g, cone[s], rtol, n10, w10, n20, w20, stats)
        met[s] = stats[CAPPED] == capped


def _airlight(segs, medium, lights, params):
    return by_kind(_BY_KIND, medium)(segs, medium, lights, params)


def _atmosphere(segs, atm, lights, params):
    stats = np.zeros(3)

    def evaluate(rows, directional, xh, h, cone, kt, ks):
        out = np.empty_like(xh)
        atmosphere_segments(rows, directional, xh, h, cone, kt, ks, atm.phases, atm.gs, atm.layers, float(atm.radius),
                            float(atm.top), params["rtol"], _N10, _W10, _N20, _W20, out, stats)
        return out

    return atmosphere_channels(segs, atm, lights, evaluate), stats


def _fog(segs, medium, lights, params):
    stats = np.zeros(3)
    rows, directional = fog_rows(segs, medium, lights)

    def evaluate(xh, h, da, ell, kt, ks, cone):
        out = np.empty_like(xh)
        fog_segments(rows, directional, xh, h, ell, kt, ks, medium.phase, medium.g, cone, medium.scale_height,
                     medium.profile, params["rtol"], _N10, _W10, _N20, _W20, out, stats)
        return out

    return by_channel(segs, medium, lights, evaluate), stats


def _homogeneous(segs, medium, lights, params):
    """The air-light, its stats and its bound (`BOUND_FACTOR` x rtol, module docstring)."""
    stats = np.zeros(3)
    met = {}  # (kt, ks) -> whether each segment's integral converged

    def evaluate(xh, h, da, ell, kt, ks, cone):
        out = np.empty_like(xh)
        met[(kt, ks)] = np.empty(len(xh), dtype=np.bool_)
        evaluate_segments(xh, h, ell, kt, ks, medium.phase, medium.g, cone, params["rtol"], _N10, _W10, _N20, _W20,
                          out, met[(kt, ks)], stats)
        return out

    radiance = by_channel(segs, medium, lights, evaluate)
    return radiance, stats, error_bounds.relative_bound(radiance, BOUND_FACTOR * params["rtol"], met, medium,
                                                        lights.cone[segs.light, 0])


def _summarize(stats):
    evals = max(stats[EVALS], 1.0)
    return {"air-light evaluations": int(stats[EVALS]), "mean intervals": stats[INTERVALS] / evals,
            "evaluations not converged": int(stats[CAPPED])}


METHOD = Method(
    name="quadrature",
    summary="reference: adaptive Gauss-Legendre in the scattering angle, split at the light's foot point",
    params={"rtol": Param(1e-10, float, "relative accuracy of each integral, e.g. 1e-10", 1e-14, 0.5)},
    airlight=_airlight,
    error_law=ErrorLaw({"rtol": 1e-10}, "max", 3e-13),  # measured worst 1.8e-13 (spot_hg_narrow_through_view)
    stats_size=3,
    summarize=_summarize,
    supports=Supports(lights=LIGHTS + AREA_LIGHTS, media=(Homogeneous, HeightFog, Atmosphere),
                      interiors=Interiors(QUAD, exact_paths=True,
                                          settings=lambda params: (params["rtol"], 1, 745.0))),
)
_BY_KIND = {Homogeneous: _homogeneous, HeightFog: _fog, Atmosphere: _atmosphere}


# --- height fog (seed 004): the same adaptive rule on the closed-form transmittances ---------------
#
# Point and spot lights: x = x_h + h tan(theta) (theta the angle seen from the light, 0 at the foot
# point), dx / d^2 = dtheta / h, so Lm = (1/h) ∫ ks rho F Phi T_cam T_light dtheta over
# [atan(-x_h/h), atan((ell - x_h)/h)], split at 0, the cone's crossings and the linear fog's top.
# The sun: u = 1 - T_cam(x) (dx kt rho T_cam = du), so Lm = (ks/kt) Phi ∫ T_sun(x(u)) du over
# [0, 1 - T_cam(ell)], x(u) the inverse optical depth (eq. 35 / 31).


class FogIntegrand(NamedTuple):
    """A height-fog segment's air-light (above): in theta for a point or spot light (the fog's
    `fog_inscatter`), in u = 1 - T_cam for a directional light."""
    row: np.ndarray
    xh: float
    h: float
    kt: float
    ks: float
    code: int
    g: float
    cone: tuple  # cone_row
    H: float
    profile: int
    directional: bool


@integrand_of(FogIntegrand)
@njit
def _fog_value(s, r):
    row, H, profile = r.row, r.H, r.profile
    if r.directional:
        x = column_distance(row[HO], row[MU], 0.0, -math.log1p(-s) / r.kt, H, profile)
        if x == math.inf:
            return 0.0
        hp = row[HO] + row[MU] * x
        return math.exp(-r.kt * column(hp, row[MUS], 0.0, math.inf, H, profile))
    return fog_inscatter(r.xh + r.h * math.tan(s), row, r.xh, r.h, r.kt, r.ks, r.code, r.g, r.cone, H, profile, False)


@njit
def _cone_thetas(cone, out, n):
    """Append a spot light's cone crossings as angles theta from the foot point (theta = phi -
    pi/2) to out[n:]; returns the new count."""
    if is_spot(cone[3]):
        for C in (cone[2], cone[3]):
            k, r1, r2 = cone_breaks(cone[0], cone[1], C)
            for i in range(k):
                out[n] = 2.0 * math.atan(r1 if i == 0 else r2) - 0.5 * math.pi
                n += 1
    return n


@njit
def _ends_and_inside(out, n):
    """Keep of out[:n] the ends out[0], out[1] and the points strictly between them, sorted."""
    lo, hi = out[0], out[1]
    m = 0
    for i in range(n):
        if lo <= out[i] <= hi and (i < 2 or lo < out[i] < hi):
            out[m] = out[i]
            m += 1
    out[:m].sort()
    return m


@njit
def _fog_breaks(row, xh, h, ell, kt, cone, H, profile, directional, out):
    """The integration variable's breakpoints of one segment, ascending, in out; returns their count."""
    x_top = top_distance(row[HO], row[MU], H, profile)
    if directional:
        out[0] = 0.0
        out[1] = -math.expm1(-kt * column(row[HO], row[MU], 0.0, ell, H, profile))
        n = 2
        if 0.0 < x_top < ell:
            out[2] = -math.expm1(-kt * column(row[HO], row[MU], 0.0, x_top, H, profile))
            n = 3
    else:
        out[0] = math.atan2(-xh, h)
        out[1] = 0.5 * math.pi if ell == math.inf else math.atan2(ell - xh, h)
        out[2] = 0.0
        n = 3
        if 0.0 < x_top < ell:
            out[n] = math.atan2(x_top - xh, h)
            n += 1
        n = _cone_thetas(cone, out, n)
    return _ends_and_inside(out, n)


@njit
def fog_segments(rows, directional, xh, h, ell, kt, ks, code, g, cone, H, profile, rtol, n10, w10, n20, w20, out,
                 stats):
    """Unit-intensity air-light of every height-fog segment for one channel's coefficients at h0."""
    br = np.empty(9)
    for s in range(xh.shape[0]):
        out[s] = 0.0
        if ks == 0.0 or not ell[s] > 0.0:
            continue
        stats[EVALS] += 1.0
        m = _fog_breaks(rows[s], xh[s], h[s], ell[s], kt, cone[s], H, profile, directional[s], br)
        rec = FogIntegrand(rows[s], xh[s], h[s], kt, ks, code, g, cone_row(cone[s]), H, profile, directional[s])
        scale = ks / kt * phase_value(code, g, rows[s, COSD]) if directional[s] else 1.0 / h[s]
        out[s] = piecewise(rec, br, m, rtol, n10, w10, n20, w20, stats) * scale


# --- atmosphere (seed 004, media/atmosphere.py): the same adaptive rule, one channel at a time -------
#
# The sun: in x over the part [A, B] of the segment inside the air, split at the ray's lowest point
# (the densest) and where it enters or leaves the planet's shadow (T_sun jumps there). Point and
# spot lights: in theta as in the fog (x = x_h + h tan(theta)), split at the foot point, the cone's
# crossings and the lowest point.


class AtmosphereIntegrand(NamedTuple):
    """An atmosphere segment's air-light (above), one channel's layers: in x for the sun, in theta
    for a point or spot light, of the segment's `geometry.AtmosphereInX` f."""
    f: AtmosphereInX


@integrand_of(AtmosphereIntegrand)
@njit
def _atm_value(s, r):
    f = r.f
    if f.directional:
        return atmosphere_inscatter(s, f, -1.0)
    h = f.h
    dx = h * math.tan(s)
    d = math.sqrt(h * h + dx * dx)
    spot = spot_factor(dx, d, h, f.cone)
    if spot == 0.0:
        return 0.0
    return spot * atmosphere_inscatter(f.xh + dx, f, -1.0) / h


@njit
def _atm_breaks(row, directional, xh, h, cone, Hs, R, out):
    """The integration variable's breakpoints of one atmosphere segment, ascending; returns the count."""
    if directional:
        out[0], out[1] = row[atmo.A], row[atmo.B]
        n = 2 + atmo.density_breaks(row, Hs, R, out[2:])
        n += atmo.planet_shadow(row, R, out[n:])
    else:
        out[0], out[1], out[2] = math.atan2(row[atmo.A] - xh, h), math.atan2(row[atmo.B] - xh, h), 0.0
        m = atmo.density_breaks(row, Hs, R, out[3:])
        for i in range(3, 3 + m):
            out[i] = math.atan2(out[i] - xh, h)
        n = _cone_thetas(cone, out, 3 + m)
    return _ends_and_inside(out, n)


@njit
def atmosphere_segments(rows, directional, xh, h, cone, kt, ks, codes, gs, Hs, R, top, rtol, n10, w10, n20, w20, out,
                        stats):
    """Unit-intensity air-light of every atmosphere segment for one channel's layer coefficients."""
    br = np.empty(11 + atmo.max_density_breaks(Hs))
    cols = np.empty(Hs.shape[0])
    for s in range(xh.shape[0]):
        out[s] = 0.0
        if not rows[s, atmo.B] > rows[s, atmo.A]:
            continue
        stats[EVALS] += 1.0
        row = atmosphere_row(rows[s])
        m = _atm_breaks(row, directional[s], xh[s], h[s], cone[s], Hs, R, br)
        f = AtmosphereInX(row, directional[s], xh[s], h[s], cone_row(cone[s]), kt, ks, codes, gs, Hs, R, top, cols)
        out[s] = piecewise(AtmosphereIntegrand(f), br, m, rtol, n10, w10, n20, w20, stats)
