"""Segment-light geometry and the eq. 4 integrand shared by the air-light methods (METHODS.md §1).

For a segment o + x w (|w| = 1, x = 0 at the segment's own start) and a light p: x_h = (p - o)·w is
the light's projection coordinate, h = |(p - o) x w| its distance to the ray line (from the cross
product, which keeps full relative precision when the light is near the line), d_a = |p - o|. h is
clamped to H_MIN_REL times the larger of d_a and the scene's size (`Segments.scale`): the light is
treated as a sphere of that radius, so that a ray through a light, even a camera placed on a light,
gives a large but finite air-light (a true point light on the ray gives an infinite one). Where h is
clamped, d_a is that of the clamped geometry, sqrt(h^2 + x_h^2): a segment starting at the light
(a camera on a light) has d_a = h, not 0, so the optical path x + d is at least h all along it, as
the integrand has it (with d_a = 0 analytic's folded exponentials started at e^0 where the integrand
is e^{-kt h}: NaN for kt h beyond ~745).
"""
import math
from typing import NamedTuple

import numpy as np

from ..error_bounds import channel_keys
from ..jit import njit
from ..lights import NO_CONE, SMOOTHSTEP, falloff, has_cone
from ..media import atmosphere as atmo
from ..media.atmosphere import ROW, segment_rows
from ..media.fog import above_top, attenuated_density, column
from ..media.integrand import integrand_of
from ..media.phase import phase_value

H_MIN_REL = 1e-9
POINT_ROW = np.array([0.0, 0.0, *NO_CONE, SMOOTHSTEP])  # the cone row of a point light (`segment_light_table`)


@njit
def ray_light(ox, oy, oz, wx, wy, wz, px, py, pz, scale):
    """(x_h, h, d_a) of the light (px, py, pz) relative to the ray; `scale`: the scene's size."""
    rx, ry, rz = px - ox, py - oy, pz - oz
    xh = rx * wx + ry * wy + rz * wz
    cx = ry * wz - rz * wy
    cy = rz * wx - rx * wz
    cz = rx * wy - ry * wx
    h = math.sqrt(cx * cx + cy * cy + cz * cz)
    da = math.sqrt(rx * rx + ry * ry + rz * rz)
    h_min = max(H_MIN_REL * max(da, scale), 1e-300)
    if h < h_min:  # on the sphere of radius h_min, d_a is the distance d(0) of the clamped geometry, never < h
        h = h_min
        da = math.hypot(h, xh)
    return xh, h, da


@njit
def segment_light_table(origins, dirs, lpos, laxis, lcone, light, scale):
    """(x_h, h, d_a) of every segment's light from the segment's start, each (S,), and the cone row
    (S, 5) = (A, B, cos_end, cos_start, curve) of lights.py (`lcone`: `Lights.cone`): A = n·a from
    h A = (r x w)·(w x a) (r = p - o, exact to rounding even for a light near the line), B = w·a;
    (0, 0, NO_CONE, its curve) for point lights."""
    n = origins.shape[0]
    xh, h, da = np.empty(n), np.empty(n), np.empty(n)
    cone = np.empty((n, 5))
    for s in range(n):
        li = light[s]
        ox, oy, oz = origins[s, 0], origins[s, 1], origins[s, 2]
        wx, wy, wz = dirs[s, 0], dirs[s, 1], dirs[s, 2]
        xh[s], h[s], da[s] = ray_light(ox, oy, oz, wx, wy, wz, lpos[li, 0], lpos[li, 1], lpos[li, 2], scale)
        cone[s, 2], cone[s, 3], cone[s, 4] = lcone[li, 0], lcone[li, 1], lcone[li, 2]
        cone[s, 0] = cone[s, 1] = 0.0
        if has_cone(lcone[li, 1]):
            ax, ay, az = laxis[li, 0], laxis[li, 1], laxis[li, 2]
            rx, ry, rz = lpos[li, 0] - ox, lpos[li, 1] - oy, lpos[li, 2] - oz
            cx, cy, cz = ry * wz - rz * wy, rz * wx - rx * wz, rx * wy - ry * wx
            ux, uy, uz = wy * az - wz * ay, wz * ax - wx * az, wx * ay - wy * ax
            cone[s, 0] = min(max((cx * ux + cy * uy + cz * uz) / h[s], -1.0), 1.0)
            cone[s, 1] = wx * ax + wy * ay + wz * az
    return xh, h, da, cone


def segment_geometry(segs, lights):
    """(x_h, h, d_a) arrays (S,) of a `Segments` batch and its lights, and their cone rows (S, 5)."""
    return segment_light_table(segs.origins, segs.dirs, lights.position, lights.axis, lights.cone, segs.light,
                               segs.scale)


@njit
def v_of(s, h):
    """v = tan(phi/2) at x - xh = s, cancellation-free (METHODS §1)."""
    d = math.sqrt(h * h + s * s)
    if s > 0.0:
        return (d + s) / h
    return h / (d - s)


@njit
def spot_factor(dx, d, h, cone):
    """A spot light's falloff (lights.py) toward the point at x - x_h = dx, distance d, on a segment
    with cone row `cone`: the cosine to its axis is (h A + dx B) / d; 1 for point lights."""
    if not has_cone(cone[3]):
        return 1.0
    return falloff((h * cone[0] + dx * cone[1]) / d, cone[2], cone[3], cone[4])


@njit
def eq4_integrand(x, xh, h, kt, ks, code, g, cone):
    """The air-light integrand of eq. 4 for a unit-intensity light (x_h, h) at distance x along the
    segment: ks Phi(-(x - x_h) / d) F exp(-kt (x + d)) / d^2, d = sqrt(h^2 + (x - x_h)^2), F the spot
    falloff (`spot_factor`). x + d is the whole optical path light -> x -> segment start, so nothing
    overflows for lights far behind."""
    dx = x - xh
    d2 = max(h * h + dx * dx, 1e-250)  # h is >= 1e-300: keep 1/d^2 finite when h*h underflows
    d = math.sqrt(d2)
    f = spot_factor(dx, d, h, cone)
    if f == 0.0:
        return 0.0
    return ks * f * math.exp(-kt * (x + d)) * phase_value(code, g, -dx / d) / d2


@njit
def cone_row(cone):
    """A segment's cone row (S, 5) row as the tuple the integrand records hold: a record holding an
    array costs a reference count at every integrand call (twice the time of a march step)."""
    return cone[0], cone[1], cone[2], cone[3], cone[4]


class Eq4(NamedTuple):
    """`eq4_integrand` in x: the homogeneous air-light of a unit light (x_h, h) with cone row `cone`."""
    xh: float
    h: float
    kt: float
    ks: float
    code: int
    g: float
    cone: tuple  # cone_row


@integrand_of(Eq4)
@njit
def _eq4_value(x, r):
    return eq4_integrand(x, r.xh, r.h, r.kt, r.ks, r.code, r.g, r.cone)


def by_channel(segs, medium, lights, evaluate, estimated=False):
    """Air-light (S, 3) of a segment batch. `evaluate(xh, h, da, length, kt, ks, cone)` returns the
    unit-intensity air-light (S,) for one channel's coefficients; channels with equal (kt, ks) share
    one call, channels that do not scatter are 0. With `estimated`, evaluate returns (air-light,
    its error estimate) and so does this, (S, 3) each."""
    xh, h, da, cone = segment_geometry(segs, lights)
    out = np.zeros((len(segs), 3))
    err = np.zeros((len(segs), 3)) if estimated else None
    done = {}
    dark = np.zeros(0)  # a channel that does not scatter: left 0
    units, ests = [dark] * 3, [dark] * 3
    for c, key in enumerate(channel_keys(medium)):
        if key[1] == 0.0:
            continue
        if key not in done:
            done[key] = evaluate(xh, h, da, segs.length, *key, cone)
        units[c], ests[c] = done[key] if estimated else (done[key], dark)
    _scale_channels(out, *units, lights.intensity, segs.light)
    if estimated:
        _scale_channels(err, *ests, lights.intensity, segs.light)
    return (out, err) if estimated else out


@njit
def _scale_channels(out, u0, u1, u2, intensity, light):
    """`_scale_into` of the channels 0, 1, 2 whose unit values u0, u1, u2 are not empty, in one call."""
    for s in range(out.shape[0]):
        i0, i1, i2 = intensity[light[s], 0], intensity[light[s], 1], intensity[light[s], 2]
        if u0.shape[0]:
            out[s, 0] = u0[s] * i0 if i0 != 0.0 else 0.0
        if u1.shape[0]:
            out[s, 1] = u1[s] * i1 if i1 != 0.0 else 0.0
        if u2.shape[0]:
            out[s, 2] = u2[s] * i2 if i2 != 0.0 else 0.0


@njit
def _scale_into(out, c, unit, intensity, light):
    """out[s, c] = unit[s] * intensity[light[s], c] (0 for a dark light, even where the unit value
    overflowed: a camera on a light in a medium of sigma ~ 1e300)."""
    for s in range(unit.shape[0]):
        i = intensity[light[s], c]
        out[s, c] = unit[s] * i if i != 0.0 else 0.0


# a height-fog segment's row (`fog_rows`): heights above h0 and up-cosines of the ray and its light
HO, MU, HL, MUS, COSD = range(5)


def fog_rows(segs, medium, lights):
    """(S, 5) rows of a segment batch in a height fog: HO the height of the segment's start above
    h0, MU = w·up; HL a point or spot light's height above h0; for a directional light MUS, the
    up-cosine toward it, and COSD, the scattering cosine -axis·w (both 0 for other lights)."""
    up = np.asarray(medium.up, float)
    rows = np.zeros((len(segs), 5))
    rows[:, HO] = segs.origins @ up - medium.h0
    rows[:, MU] = segs.dirs @ up
    directional = lights.distant[segs.light]
    rows[:, HL] = np.where(directional, 0.0, lights.position[segs.light] @ up - medium.h0)
    axis = lights.axis[segs.light]
    rows[:, MUS] = np.where(directional, -(axis @ up), 0.0)
    rows[:, COSD] = np.where(directional, -np.einsum("ij,ij->i", axis, segs.dirs), 0.0)
    return rows, directional


@njit
def fog_inscatter(x, row, xh, h, kt, ks, code, g, cone, H, profile, directional):
    """The in-scattered radiance per unit length at distance x along a height-fog segment, unit
    light, without a point light's 1/d^2: ks rho(x) Phi(cos) F T_cam(x) T_light(x), both
    transmittances exp(-kt tau) with tau the closed-form column (media/medium.py, seed 004 eq. 34
    or 30); T_cam from the segment's start, T_light to the light or, for the sun, to infinity."""
    return fog_inscatter_parts(x, row, xh, h, kt, ks, code, g, cone, H, profile, directional)[0]


@njit
def fog_inscatter_parts(x, row, xh, h, kt, ks, code, g, cone, H, profile, directional):
    """`fog_inscatter` and what its rounding depends on (methods/quadrature.py's bound): (value,
    height of x above h0, the camera's and the light's unit columns, the light path's up-cosine,
    its length d; inf for the sun)."""
    hp = row[HO] + row[MU] * x
    if above_top(hp, H, profile):
        return 0.0, hp, 0.0, 0.0, 0.0, 0.0
    tau = column(row[HO], row[MU], 0.0, x, H, profile)
    if directional:
        tl = column(hp, row[MUS], 0.0, math.inf, H, profile)
        value = ks * phase_value(code, g, row[COSD]) * attenuated_density(hp, kt * (tau + tl), H, profile)
        return value, hp, tau, tl, row[MUS], math.inf
    dx = x - xh
    d = math.sqrt(max(h * h + dx * dx, 1e-250))
    f = spot_factor(dx, d, h, cone)
    if f == 0.0:
        return 0.0, hp, tau, 0.0, 0.0, d
    mul = (row[HL] - hp) / d
    tl = column(hp, mul, 0.0, d, H, profile)
    return ks * f * phase_value(code, g, -dx / d) * attenuated_density(hp, kt * (tau + tl), H, profile), hp, tau, tl, \
        mul, d


class FogInX(NamedTuple):
    """A height fog's air-light integrand in x, unit light: `fog_inscatter`, divided by d^2 for
    point and spot lights."""
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


@integrand_of(FogInX)
@njit
def _fog_in_x(x, r):
    f = fog_inscatter(x, r.row, r.xh, r.h, r.kt, r.ks, r.code, r.g, r.cone, r.H, r.profile, r.directional)
    if not r.directional:
        dx = x - r.xh
        f /= max(r.h * r.h + dx * dx, 1e-250)
    return f


@njit
def atmosphere_row(row):
    """A segment's `atmosphere.segment_rows` row (ROW,) as the tuple the integrand records hold (as
    `cone_row`): with the row an array a march step took ~1.05 times as long. The layers' arrays
    stay arrays: their length, the number of layers, is known only at run time."""
    return (row[0], row[1], row[2], row[3], row[4], row[5], row[6], row[7], row[8], row[9], row[10], row[11], row[12],
            row[13])


class AtmosphereInX(NamedTuple):
    """An atmosphere's air-light integrand in x, one channel's layers, unit light (`atmosphere_in_x`
    without the camera's optical depth); `cols` is scratch for the layers' columns."""
    row: tuple  # atmosphere_row
    directional: bool
    xh: float
    h: float
    cone: tuple  # cone_row
    kt: np.ndarray
    ks: np.ndarray
    codes: np.ndarray
    gs: np.ndarray
    Hs: np.ndarray
    R: float
    top: float
    cols: np.ndarray


@njit
def atmosphere_inscatter(x, r, tau_cam):
    """`atmosphere.inscatter` at x of the AtmosphereInX record r (tau_cam as there)."""
    return atmo.inscatter(x, r.row, r.directional, r.kt, r.ks, r.codes, r.gs, r.Hs, r.R, r.top, r.cols, tau_cam)


@njit
def atmosphere_in_x(x, r, tau_cam):
    """The air-light integrand at x of the AtmosphereInX record r: `atmosphere.inscatter` (tau_cam:
    the camera's optical depth to x if known, else negative), times a spot's falloff over d^2 for
    point and spot lights."""
    f = atmosphere_inscatter(x, r, tau_cam)
    if not r.directional:
        dx = x - r.xh
        d2 = max(r.h * r.h + dx * dx, 1e-250)
        f *= spot_factor(dx, math.sqrt(d2), r.h, r.cone) / d2
    return f


@integrand_of(AtmosphereInX)
@njit
def _atmosphere_in_x(x, r):
    return atmosphere_in_x(x, r, -1.0)


def atmosphere_channels(segs, medium, lights, evaluate, variance=False):
    """Air-light (S, 3) of a segment batch in an atmosphere (media/atmosphere.py): `evaluate(rows,
    sun, xh, h, cone, kt, ks)` returns the unit-intensity air-light (S,) of one channel given its
    layers' coefficients kt, ks (K,); rows are `atmosphere.segment_rows`, channels that do not
    scatter are 0. With `variance`, evaluate returns (mean, variance) and so does this, (S, 3) each."""
    xh, h, _, cone = segment_geometry(segs, lights)
    directional = lights.distant[segs.light]
    rows = np.empty((len(segs), ROW))
    segment_rows(segs.origins, segs.dirs, np.asarray(segs.length, float), lights.position, lights.axis, segs.light,
                 directional, *(float(v) for v in medium.center), float(medium.radius), float(medium.top), rows)
    out = np.zeros((len(segs), 3))
    var = np.zeros((len(segs), 3))
    for c in range(3):
        ks = np.ascontiguousarray(medium.layer_sigma_s[:, c])
        if not np.any(ks > 0.0):
            continue
        unit = evaluate(rows, directional, xh, h, cone, np.ascontiguousarray(medium.layer_sigma_t[:, c]), ks)
        if variance:
            unit, v = unit
            _scale_into(var, c, v, lights.intensity ** 2, segs.light)
        _scale_into(out, c, unit, lights.intensity, segs.light)
    return (out, var) if variance else out
