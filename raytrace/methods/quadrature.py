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
sums). An integral with an interval accepted at a cap is infinite. Height fog and atmospheres: the
same rule's rtol (value + estimate / 10) per segment (`adaptive.bounded_piecewise`), plus the
rounding of their closed-form transmittances, a first-order bound computed at every evaluation and
kept over them (`_track`, `_tracked`; docs/error_bounds.md "Height fog and atmospheres").
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .. import error_bounds
from ..jit import exact_njit, njit
from . import AREA_LIGHTS, LIGHTS, ErrorLaw, Interiors, Method, Param, Supports, by_kind
from .geometry import (COSD, HL, HO, MU, MUS, AtmosphereInX, atmosphere_channels, atmosphere_in_x, atmosphere_row,
                       by_channel, cone_row, fog_inscatter_parts, fog_rows, spot_factor)
from ..lights import cone_breaks, falloff, has_cone
from ..media import atmosphere as atmo
from ..media.chapman import relative_error as chapman_error
from ..media.adaptive import CAPPED, EVALS, INTERVALS, bounded_piecewise, first_estimate, refine, rule
from ..geometry.sorting import sort_few
from ..media.integrand import integrand_of
from ..media.gauss import N10, N20, W10, W20
from ..media import Atmosphere, HeightFog, Homogeneous
from ..media.fog import LINEAR, column, column_distance, column_error, top_distance
from ..media.phase import HG, phase_split, phase_value
from ..media.inside_rule import QUAD


BOUND_FACTOR = 2.0


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
    if has_cone(cone[3]):  # cosine to the axis A sin(phi) - B cos(phi), sin(phi) = sin(psi) = 2t / (1 + t^2)
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
    if has_cone(cone[3]):
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
        sort_few(out0, 1, n0)
        sort_few(out1, 1, n1)
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


def _kinds(lights):
    """(points, spots): the trailing arguments of `atmosphere_segments` and `fog_segments` for a
    scene's `lights`: None where it has no light of that kind (no point, spot or area light; no spot
    light), which numba then prunes the code of before typing, else True (the kind of each
    segment's light read at run time)."""
    return (None if lights.distant.all() else True), (True if np.any(lights.cone[:, 1] > -1.0) else None)


def _atmosphere(segs, atm, lights, params):
    """The air-light, its stats and its bound (`atmosphere_segments`, the spot's rounding and the
    camera ray's transmittance to a piece's start: `_atmosphere_prefix`)."""
    stats = np.zeros(3)
    dz = 4.0 * ULP * (np.linalg.norm(segs.origins, axis=1) + np.linalg.norm(atm.center)
                      + np.where(lights.distant[segs.light], 0.0,
                                 np.linalg.norm(lights.position[segs.light], axis=1)))
    phase_cond = max(phase_condition(int(c), float(g)) for c, g in zip(atm.phases, atm.gs))
    unit_bounds = {}
    kinds = _kinds(lights)

    def evaluate(rows, directional, xh, h, cone, kt, ks):
        out, bound = np.empty_like(xh), np.empty_like(xh)
        atmosphere_segments(rows, directional, xh, h, cone, kt, ks, atm.phases, atm.gs, atm.layers, float(atm.radius),
                            float(atm.top), dz, phase_cond, params["rtol"], N10, W10, N20, W20, out, bound, stats,
                            *kinds)
        unit_bounds[kt.tobytes() + ks.tobytes()] = bound
        return out

    radiance = atmosphere_channels(segs, atm, lights, evaluate)
    bound = np.zeros_like(radiance)
    for c in range(3):
        key = atm.layer_sigma_t[:, c].tobytes() + atm.layer_sigma_s[:, c].tobytes()
        if key in unit_bounds:
            i = lights.intensity[segs.light, c]
            bound[:, c] = error_bounds.product(unit_bounds[key], i)
    spot = error_bounds.spot_rounding(lights.cone[segs.light, 0])
    rel = error_bounds.ROUNDING + spot[:, None] + _atmosphere_prefix(segs, atm)
    return radiance, stats, bound + error_bounds.product(rel, np.abs(radiance))


def _atmosphere_prefix(segs, atm):
    """(S, 3): the relative rounding of the atmosphere's transmittance from each camera ray's origin to
    its piece's start (0 for whole rays): its optical depth times the exponential layers' largest
    dz / H + Chapman's `relative_error` + 8 ulp, plus each tent layer's kt t0 dz / W (`depth_error`),
    dz ~eps of the positions about the centre."""
    out = np.zeros((len(segs), 3))
    if not np.any(segs.t0):
        return out
    t0 = np.asarray(segs.t0, float)
    start = segs.origins - t0[:, None] * segs.dirs
    depth = -np.log(np.maximum(atm.transmittance_on(start, segs.dirs, 0.0, t0), 1e-300))
    dz = 4.0 * ULP * (np.linalg.norm(segs.origins, axis=1) + np.linalg.norm(atm.center)) + C_OPS * ULP * (
        atm.radius + atm.top + t0)
    tent = atm.layers[:, 0] == atmo.TENT
    H = atm.layers[~tent, 1]
    rel = (dz[:, None] / H.min() if len(H) else 0.0) + (chapman_error(atm.radius / H.max()) if len(H) else 0.0)
    out += depth * (rel + 8.0 * ULP)
    for i in np.flatnonzero(tent):
        out += atm.layer_sigma_t[i][None, :] * (t0 * dz / atm.layers[i, 2])[:, None]
    return np.where(segs.t0[:, None] > 0.0, out, 0.0)


def _fog(segs, medium, lights, params):
    """The air-light, its stats and its bound (`fog_segments`), plus the rounding of the camera ray's
    transmittance to a piece's start (t0 > 0: kt column_error of that column, relative)."""
    stats = np.zeros(3)
    geo, directional = fog_rows(segs, medium, lights)
    rows = np.zeros((len(segs), FOG_ROW))
    rows[:, :geo.shape[1]] = geo
    up, h0 = np.abs(np.asarray(medium.up, float)), abs(float(medium.h0))
    rows[:, ZO] = 4.0 * ULP * (np.abs(segs.origins) @ up + h0)
    rows[:, ZL] = np.where(directional, 0.0, 4.0 * ULP * (np.abs(lights.position[segs.light]) @ up + h0))
    phase_cond = phase_condition(medium.phase, medium.g)
    kinds = _kinds(lights)

    def evaluate(xh, h, da, ell, kt, ks, cone):
        out, bound = np.empty_like(xh), np.empty_like(xh)
        fog_segments(rows, directional, xh, h, ell, kt, ks, medium.phase, medium.g, phase_cond, cone,
                     medium.scale_height, medium.profile, params["rtol"], N10, W10, N20, W20, out, bound, stats, *kinds)
        return out, bound

    radiance, bound = by_channel(segs, medium, lights, evaluate, estimated=True)
    # the prefix's rounding (kt column_error of the camera ray's column over [-t0, 0], 0 for whole
    # rays) is computed even when every piece is whole, so that the renderer's warm-up, whose rays
    # make whole pieces, compiles it
    prefix = np.empty(len(segs))
    _prefix_errors(rows, np.asarray(segs.t0, float), medium.scale_height, medium.profile, prefix)
    _add_rounding(prefix, np.asarray(medium.sigma_t, float), lights.cone[segs.light, 0], radiance, bound)
    return radiance, stats, bound


@exact_njit
def _add_rounding(prefix, kt, cos_end, radiance, bound):
    """bound[s, c] += (ROUNDING + spot_rounding(cos_end[s]) + kt[c] prefix[s]) |radiance[s, c]|, in
    place: the relative rounding of the sum, of a spot's falloff and of the camera ray's
    transmittance to the piece's start (`_prefix_errors`' unit column error times the channel's
    extinction), each product 0 where a factor is (error_bounds.product and spot_rounding's
    operations in their order: their NumPy expression's bound bit for bit)."""
    for s in range(radiance.shape[0]):
        spot = error_bounds.spot_allowance(cos_end[s])
        for c in range(radiance.shape[1]):
            before = prefix[s] * kt[c] if kt[c] != 0.0 else 0.0
            value = abs(radiance[s, c])
            bound[s, c] += (error_bounds.ROUNDING + spot + before) * value if value != 0.0 else 0.0


@njit
def _prefix_errors(rows, t0, H, profile, out):
    """out[s] = column_error (+ 8 ulp) of the unit column over [-t0[s], 0] of segment s's row."""
    for s in range(t0.shape[0]):
        row = rows[s]
        out[s] = 0.0
        if t0[s] > 0.0:
            col = column(row[HO], row[MU], -t0[s], 0.0, H, profile)
            dz = row[ZO] + 2.0 * ULP * (abs(row[HO]) + abs(row[MU]) * t0[s])
            out[s] = column_error(row[HO], row[MU], -t0[s], 0.0, H, profile, col, dz, 3.0 * ULP) + 8.0 * ULP * col


def _homogeneous(segs, medium, lights, params):
    """The air-light, its stats and its bound (`BOUND_FACTOR` x rtol, module docstring)."""
    stats = np.zeros(3)
    met = {}  # (kt, ks) -> whether each segment's integral converged

    def evaluate(xh, h, da, ell, kt, ks, cone):
        out = np.empty_like(xh)
        met[(kt, ks)] = np.empty(len(xh), dtype=np.bool_)
        evaluate_segments(xh, h, ell, kt, ks, medium.phase, medium.g, cone, params["rtol"], N10, W10, N20, W20,
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
                      interiors=Interiors(QUAD, exact_paths=True, lights=LIGHTS + AREA_LIGHTS,
                                          refracted=LIGHTS + AREA_LIGHTS,
                                          settings=lambda params: (params["rtol"], 1, 745.0))),
    tolerance_key="rtol",
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
    `fog_inscatter`), in u = 1 - T_cam for a directional light. `row` is the segment's bounded row
    (`_fog`): the geometry row, its heights' rounding and the slots `_track` writes."""
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
    spots: bool | None = True  # None: the scene has no spot light (`_kinds`)


# a fog row's columns past geometry.fog_rows's: the absolute rounding of the segment's start height
# and of its light's, the three that `_track` keeps (TRACK + FMAX, + ESIG, + EALL), the light's
# distance hypot(x_h, h), 1 / (1 - cos_end) of a spot's cone and the phase's `phase_condition`
# (in the row, not the record: a larger record slowed the rule ~5 %)
ZO, ZL, TRACK, DA, SPOT_WIDTH, PHASE_COND = 5, 6, 7, 10, 11, 12
FOG_ROW = 13
FMAX, ESIG, EALL = 0, 1, 2
SIGNIFICANT = 1e-6
ULP = 2.0 ** -53
C_OPS = 16.0  # ulps allowed for a few dozen operations each of whose results a term covers


def phase_condition(code, g):
    """1 + max |d log Phi / d mu|: 1 + 3|g| / (1 - |g|)^2 for Henyey-Greenstein, 2 otherwise (Rayleigh's
    2|mu| / (1 + mu^2) <= 1)."""
    return 1.0 + (3.0 * abs(g) / (1.0 - abs(g)) ** 2 if code == HG else 1.0)


@njit
def _track(a, i, value, eps):
    """Keep in a[i:i + 3] the largest value of the integrand's evaluations, the largest relative
    rounding `eps` where the value is at least SIGNIFICANT of the largest so far, and anywhere."""
    if value > a[i]:
        a[i] = value
    if value >= SIGNIFICANT * a[i] and eps > a[i + 1]:
        a[i + 1] = eps
    if eps > a[i + 2]:
        a[i + 2] = eps


@njit
def _tracked(a, i, total, width):
    """The rounding of a rule's sum `total` over `width` from what `_track` kept in a[i:i + 3]: the
    significant evaluations' largest relative rounding times the total, the largest anywhere times
    the rest's values (each below SIGNIFICANT of the largest) times the width (the positive weights'
    sum)."""
    return a[i + ESIG] * total + a[i + EALL] * SIGNIFICANT * a[i + FMAX] * width


@njit
def _fog_sun(s, r):
    """The directional integrand T_sun(x(u)) at u = s, and its relative rounding (docs/error_bounds.md,
    "Height fog"): the computed x is the exact point of a column off by its `column_error` (plus the
    inverse's and log1p's few ulps), which moves u, and T_sun(x) changes with x at |MU / MUS| times the
    camera's extinction; T_sun's own column off by its `column_error`."""
    row, H, profile = r.row, r.H, r.profile
    target = -math.log1p(-s) / r.kt
    x = column_distance(row[HO], row[MU], 0.0, target, H, profile)
    if x == math.inf:
        return 0.0, 0.0
    hp = row[HO] + row[MU] * x
    tl = column(hp, row[MUS], 0.0, math.inf, H, profile)
    value = math.exp(-r.kt * tl)
    if not value > 0.0:
        return value, 0.0
    dz = row[ZO] + 2.0 * ULP * (abs(row[HO]) + abs(row[MU] * x)) + 3.0 * ULP * x
    d_cam = column_error(row[HO], row[MU], 0.0, x, H, profile, target, dz, 3.0 * ULP) + 8.0 * ULP * target
    d_sun = column_error(hp, row[MUS], 0.0, math.inf, H, profile, tl, dz + 2.0 * ULP * abs(hp), 3.0 * ULP)
    return value, 2.0 * (r.kt * (d_sun + 2.0 * ULP * tl) + abs(row[MU] / row[MUS]) * r.kt * d_cam + C_OPS * ULP)


@njit
def _fog_point(s, r, spots):
    """The point or spot light's integrand fog_inscatter(x(theta)) at theta = s (the 1/h outside), and
    its relative rounding (docs/error_bounds.md, "Height fog"), first order, doubled: x = x_h + h tan
    theta is off by dx (the node's, tan's and x_h's and h's own rounding, ~eps of the light's distance
    d_a), which moves the camera's column's end (its density kt rho(x); for the exponential profile
    rho(x) x <= tc (1 + |MU| x / H), no exp to evaluate), the height at x, the light
    path's length (relative dd/d) and the scattering cosine (h dx / d^2 for a point moved along
    the ray, as cos = -(x - x_h)/d has derivative h^2/d^3, plus d's own rounding 2 (dh + 2 eps d)/d;
    times the phase's condition); the heights carry their rows' rounding, the columns their
    `column_error`; a spot's cosine to its axis moves by as much over its cone's width (its
    derivative along the ray is below h / d^2 too); 1/h is off by eps d_a / h."""
    row, H, profile, xh, h = r.row, r.H, r.profile, r.xh, r.h
    t = math.tan(s)
    x = xh + h * t
    value, hp, tc, tl, mul, d = fog_inscatter_parts(x, row, xh, h, r.kt, r.ks, r.code, r.g, r.cone, H, profile, False)
    if not value > 0.0:
        return value, 0.0
    inv_d = 1.0 / d
    dh = C_OPS * ULP * row[DA]
    dx = C_OPS * ULP * (abs(xh) + abs(x - xh) + d * d / h * abs(s)) + dh * (1.0 + abs(t))
    dd = dx + dh + 2.0 * ULP * d
    z_cam = row[ZO] + 2.0 * ULP * (abs(row[HO]) + abs(row[MU] * x))
    dhp = z_cam + 3.0 * ULP * abs(x) + abs(row[MU]) * dx
    d_cam = column_error(row[HO], row[MU], 0.0, x, H, profile, tc, z_cam, 3.0 * ULP)
    dm_l = (row[ZL] + dhp + 2.0 * ULP * abs(row[HL] - hp) + abs(mul) * dd) * inv_d + 3.0 * ULP * abs(mul)
    d_light = column_error(hp, mul, 0.0, d, H, profile, tl, dhp + 2.0 * ULP * (abs(hp) + abs(row[HL])), dm_l)
    dens = (dhp + 2.0 * ULP * abs(hp)) / H
    if profile == LINEAR:
        rho = max(0.0, 1.0 - hp / H)
        dens /= rho
    else:  # rho(x) x <= tc (1 + |MU| x / H) (the density changes by e^{MU t / H} along the ray): no exp
        rho = tc * (1.0 / x + abs(row[MU]) / H) if x > 0.0 else math.exp(-row[HO] / H)
    moved = (h * inv_d * dx + 2.0 * (dh + 2.0 * ULP * d)) * inv_d + 4.0 * ULP
    spot = moved * row[SPOT_WIDTH] if spots is not None and has_cone(r.cone[3]) else 0.0
    eps = (dens + r.kt * (d_cam + d_light + 2.0 * ULP * (tc + tl) + rho * dx + tl * dd * inv_d) + row[PHASE_COND] * moved
           + spot + dh / h + C_OPS * ULP)
    return value, 2.0 * eps


@integrand_of(FogIntegrand)
@njit
def _fog_value(s, r):
    value, eps = _fog_sun(s, r) if r.directional else _fog_point(s, r, r.spots)
    _track(r.row, TRACK, value, eps)
    return value


@njit
def _cone_thetas(cone, out, n, spots):
    """Append a spot light's cone crossings as angles theta from the foot point (theta = phi -
    pi/2) to out[n:]; returns the new count. `spots`: None if the scene has no spot light (`_kinds`)."""
    if spots is not None and has_cone(cone[3]):
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
    sort_few(out, 0, m)
    return m


@njit
def _fog_breaks(row, xh, h, ell, kt, cone, H, profile, directional, out, points, spots):
    """The integration variable's breakpoints of one segment, ascending, in out; returns their count.
    `points`, `spots`: `fog_segments`'."""
    x_top = top_distance(row[HO], row[MU], H, profile)
    if points is None or directional:
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
        n = _cone_thetas(cone, out, n, spots)
    return _ends_and_inside(out, n)


@njit
def _fog_ends(row, xh, h, ell, kt, H, profile, directional):
    """A bound on the rounding of the integration variable's two ends (`_fog_breaks`): for the sun
    the camera's transmittance over the segment, 1 - T_cam(ell), off by T_cam kt column_error; for
    a point light the angles atan2 of x_h, h and ell - x_h, each off by ~eps of the light's distance."""
    if directional:
        col = column(row[HO], row[MU], 0.0, ell, H, profile)
        if col == math.inf:  # the end is 1 exactly
            return 0.0
        dz = row[ZO] + 2.0 * ULP * abs(row[HO]) + (2.0 * ULP * abs(row[MU] * ell) if ell < math.inf else 0.0)
        return math.exp(-kt * col) * kt * (column_error(row[HO], row[MU], 0.0, ell, H, profile, col, dz, 3.0 * ULP)
                                           + 8.0 * ULP * col) + 4.0 * ULP
    da = math.hypot(xh, h)
    lo = C_OPS * ULP * (1.0 + abs(math.atan2(-xh, h)))
    if ell == math.inf:
        return lo
    return lo + C_OPS * ULP * ((da + ell) / math.hypot(ell - xh, h) + 1.0)


@njit
def fog_segments(rows, directional, xh, h, ell, kt, ks, code, g, phase_cond, cone, H, profile, rtol, n10, w10, n20,
                 w20, out, bound, stats, points, spots):
    """Unit-intensity air-light of every height-fog segment for one channel's coefficients at h0, and
    its bound: the rule's (`adaptive.bounded_piecewise`) plus the rounding `_track` kept (its largest relative
    rounding where the integrand is significant times the value, the largest anywhere over the rest,
    whose values are below SIGNIFICANT of the largest, and the ends' rounding times the largest value),
    plus the factor's few ulps (the sun's phase, by its condition). `points`, `spots` (`_kinds`): None
    where the scene has no point or spot light, no spot light (their code is then pruned), else True."""
    br = np.empty(9)
    for s in range(xh.shape[0]):
        out[s] = bound[s] = 0.0
        if ks == 0.0 or not ell[s] > 0.0:
            continue
        stats[EVALS] += 1.0
        row = rows[s]
        row[TRACK:TRACK + 3] = 0.0
        row[DA] = math.hypot(xh[s], h[s])
        row[SPOT_WIDTH] = 1.0 / max(1.0 - cone[s, 2], 1e-300)
        row[PHASE_COND] = phase_cond
        m = _fog_breaks(row, xh[s], h[s], ell[s], kt, cone[s], H, profile, directional[s], br, points, spots)
        rec = FogIntegrand(row, xh[s], h[s], kt, ks, code, g, cone_row(cone[s]), H, profile, directional[s], spots)
        scale = ks / kt * phase_value(code, g, row[COSD]) if directional[s] else 1.0 / h[s]
        total, rule_bound = bounded_piecewise(rec, br, m, rtol, n10, w10, n20, w20, stats)
        rounding = (_tracked(row, TRACK, total, br[m - 1] - br[0])
                    + row[TRACK + FMAX] * _fog_ends(row, xh[s], h[s], ell[s], kt, H, profile, directional[s])
                    + (phase_cond * 3.0 + C_OPS) * ULP * total)
        out[s] = total * scale
        bound[s] = (rule_bound + rounding) * scale


# --- atmosphere (seed 004, media/atmosphere.py): the same adaptive rule, one channel at a time -------
#
# The sun: in x over the part [A, B] of the segment inside the air, split at the ray's lowest point
# (the densest) and where it enters or leaves the planet's shadow (T_sun jumps there). Point and
# spot lights: in theta as in the fog (x = x_h + h tan(theta)), split at the foot point, the cone's
# crossings and the lowest point.


class AtmosphereIntegrand(NamedTuple):
    """An atmosphere segment's air-light (above), one channel's layers: in x for the sun, in theta
    for a point or spot light, of the segment's `geometry.AtmosphereInX` f, whose scratch `cols`
    holds past the layers' columns the slots `_track` writes (FMAX, ESIG, EALL from index K; a
    record whose scratch holds the columns alone gives the value only)."""
    f: AtmosphereInX
    dz: float = 0.0  # the absolute rounding of the segment's and its light's positions about the centre
    phase_cond: float = 1.0  # the largest of the layers' `phase_condition`
    cos_end: float = -2.0  # the spot's cone (<= -1 without one)
    points: bool | None = True  # None: the scene has no point or spot light (`_kinds`)
    spots: bool | None = True  # None: the scene has no spot light


@njit
def _atm_node(s, r, points, spots):
    """The integrand at s and its relative rounding (docs/error_bounds.md, "Atmospheres"), first
    order, doubled: the node's x is off by dx (for a point light as in the fog: x = x_h + h tan s,
    x_h and h ~eps of the light's distance d_a off); every altitude by the positions' rounding about
    the centre (~eps of the planet's radius and top, of x, of the light path) plus dx; the optical
    depth by `atmosphere.depth_error` (Chapman's remainder and the densities' condition), the
    scattering density by its `density_condition`, the camera's column's end by its extinction
    times dx, the scattering cosine and a spot's cosine by h dx / d^2 + 2 (dh + 2 eps d) / d (as in
    the fog); 1/h by eps d_a / h. `points`, `spots`: the record's (`_kinds`)."""
    f = r.f
    if points is None or f.directional:
        x, dx, dh, h, t = s, 2.0 * ULP * abs(s), 0.0, 1.0, 0.0
    else:
        h = f.h
        t = math.tan(s)
        x = f.xh + h * t
        dh = C_OPS * ULP * math.hypot(f.xh, h)
        dx = C_OPS * ULP * (abs(f.xh) + abs(x - f.xh) + (h * h + (x - f.xh) ** 2) / h * abs(s)) + dh * (1.0 + abs(t))
    dz = r.dz + C_OPS * ULP * (f.R + f.top + abs(x)) + dx
    value, depth, err, hx, d = atmo.inscatter_parts(x, f.row, f.directional, f.kt, f.ks, f.codes, f.gs, f.Hs, f.R,
                                                    f.top, f.cols, -1.0, dz)
    moved = 0.0
    if points is not None and not f.directional:
        u = x - f.xh
        d = math.sqrt(max(h * h + u * u, 1e-250))
        value *= (spot_factor(u, d, h, f.cone) if spots is not None else 1.0) / h
        moved = (h / d * dx + 2.0 * (dh + 2.0 * ULP * d)) / d + 4.0 * ULP
    if not value > 0.0:
        return value, 0.0
    spot = moved / max(1.0 - r.cos_end, 1e-300) if spots is not None and r.cos_end > -1.0 else 0.0
    eps = (err + 2.0 * ULP * depth + dz * atmo.density_condition(hx, f.Hs, f.ks) + dx * atmo.extinction_at(
        x, f.row, f.kt, f.Hs, f.R) + r.phase_cond * moved + spot + dh / h + C_OPS * ULP)
    return value, 2.0 * eps


@integrand_of(AtmosphereIntegrand)
@njit
def _atm_value(s, r):
    value, eps = _atm_node(s, r, r.points, r.spots)
    if r.f.cols.shape[0] >= r.f.kt.shape[0] + 3:  # scratch without the slots: the value alone
        _track(r.f.cols, r.f.kt.shape[0], value, eps)
    return value


@njit
def _atm_breaks(row, directional, xh, h, cone, Hs, R, out, points, spots):
    """The integration variable's breakpoints of one atmosphere segment, ascending; returns the count.
    `points`, `spots`: `atmosphere_segments`'."""
    if points is None or directional:
        out[0], out[1] = row[atmo.A], row[atmo.B]
        n = 2 + atmo.density_breaks(row, Hs, R, out[2:])
        n += atmo.planet_shadow(row, R, out[n:])
    else:
        out[0], out[1], out[2] = math.atan2(row[atmo.A] - xh, h), math.atan2(row[atmo.B] - xh, h), 0.0
        m = atmo.density_breaks(row, Hs, R, out[3:])
        for i in range(3, 3 + m):
            out[i] = math.atan2(out[i] - xh, h)
        n = _cone_thetas(cone, out, 3 + m, spots)
    return _ends_and_inside(out, n)


@njit
def _atm_ends(f, cols, K):
    """The rounding of the segment's ends in the air (`atmosphere.shell`'s distances: its top sphere's
    crossings, off by eps (top + r0)(1 + (top + r0) / sqrt(disc)), disc that of the crossing) times
    the integrand there in x, and of the sun's planet-shadow crossings (off by eps of the radius
    over the sine between the ray and the sun) times the largest value."""
    row = f.row
    r0 = f.R + row[atmo.H0]
    s0 = r0 * row[atmo.MU0]
    disc = (f.top - r0) * (f.top + r0) + s0 * s0
    moved = C_OPS * ULP * (f.top + r0) * (1.0 + (f.top + r0) / math.sqrt(max(disc, 1e-300)))
    out = 0.0
    a, b = row[atmo.A], row[atmo.B]
    if a > 0.0:
        out += abs(atmosphere_in_x(a, f, -1.0)) * (moved + C_OPS * ULP * a)
    a0, b0 = atmo.shell(row[atmo.H0], row[atmo.MU0], f.R, f.top)
    if b == b0:
        out += abs(atmosphere_in_x(b, f, -1.0)) * (moved + C_OPS * ULP * b)
    if f.directional:
        ws = row[atmo.WX] * row[atmo.LX] + row[atmo.WY] * row[atmo.LY] + row[atmo.WZ] * row[atmo.LZ]
        n = atmo.planet_shadow(row, f.R, cols[K + 3:])
        out += n * cols[K + FMAX] * C_OPS * ULP * (f.R + f.top + b) / math.sqrt(max(1.0 - ws * ws, 1e-300))
    return out


@njit
def atmosphere_segments(rows, directional, xh, h, cone, kt, ks, codes, gs, Hs, R, top, dz, phase_cond, rtol, n10,
                        w10, n20, w20, out, bound, stats, points, spots):
    """Unit-intensity air-light of every atmosphere segment for one channel's layer coefficients, and
    its bound: the rule's (`adaptive.bounded_piecewise`), the rounding `_track` kept over the evaluations
    (`_tracked`), the ends' (`_atm_ends`) and the sum's. `points`, `spots`: `fog_segments`'."""
    br = np.empty(11 + atmo.max_density_breaks(Hs))
    K = Hs.shape[0]
    cols = np.empty(K + 5)  # the layers' columns, the slots `_track` writes, scratch for the shadow's crossings
    for s in range(xh.shape[0]):
        out[s] = bound[s] = 0.0
        if not rows[s, atmo.B] > rows[s, atmo.A]:
            continue
        stats[EVALS] += 1.0
        row = atmosphere_row(rows[s])
        m = _atm_breaks(row, directional[s], xh[s], h[s], cone[s], Hs, R, br, points, spots)
        cols[K:K + 3] = 0.0
        f = AtmosphereInX(row, directional[s], xh[s], h[s], cone_row(cone[s]), kt, ks, codes, gs, Hs, R, top, cols)
        total, rule_bound = bounded_piecewise(AtmosphereIntegrand(f, dz[s], phase_cond, cone[s, 2], points, spots), br,
                                              m, rtol, n10, w10, n20, w20, stats)
        out[s] = total
        bound[s] = rule_bound + _tracked(cols, K, total, br[m - 1] - br[0]) + _atm_ends(f, cols, K) + C_OPS * ULP * total
