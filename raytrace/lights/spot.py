"""The spot light: a point light (point.py) that emits I F(cos) toward a direction at cosine `cos`
from its axis, with the falloff F = 1 within `falloff_start`, 0 beyond `cone_angle`, and between
them one of three curves (`falloff`, docs/spot_lights.md): pbrt-v4's SpotLight, smoothstep in the
cosine (SMOOTHSTEP); Mitsuba 3's spot, linear in the angle (MITSUBA); KHR_lights_punctual's, the
linear ramp in the cosine squared (GLTF).

Along a ray segment seen from a light (geometry.py: foot point distance h, x - x_h = h tan(theta)),
the direction from the light is cos(theta) n + sin(theta) w, with n the unit vector from the light
to the foot point and w the ray's direction, so the cosine to the spot axis a is

    c = A cos(theta) + B sin(theta) = A sin(phi) - B cos(phi),     A = n·a, B = w·a,

in the paper's scattering angle phi = theta + pi/2 (docs/spot_lights.md). `cone_breaks` finds where
c crosses a given cosine, in the paper's variable v = tan(phi / 2).
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from . import point
from .light import Light, one_row

NAME = "spot"
CODE = 1
KEYS = frozenset({"type", "position", "intensity", "look_at", "direction", "cone_angle", "falloff_start", "falloff"})
rows = one_row  # its own one sample

SMOOTHSTEP = 0  # the falloff curves (`falloff`; Light's default curve); the scene file's names:
MITSUBA = 1
GLTF = 2
CURVES = {"smoothstep": SMOOTHSTEP, "mitsuba": MITSUBA, "gltf": GLTF}
# not a scene file's curve: an area light's emitter point (area.py), a Lambertian emitter whose
# intensity toward a direction at cosine c to its normal is I max(c, 0): cone 90 deg, core 0 deg, F = t
LAMBERT = 3

CUT_TOL = 1e-12  # relative: cone crossings this close to a segment's end are that end


def parse(read, key, raw) -> Light:
    """A spot light: its position and intensity (point.py), its axis from look_at or direction, cone
    and falloff angles in degrees (0 <= falloff_start <= cone_angle < 180; pbrt-v4's defaults: 30
    and 25) and the falloff curve between them (CURVES; default pbrt-v4's smoothstep)."""
    pos, intensity = point.position_intensity(read, key, raw)
    if ("look_at" in raw) == ("direction" in raw):
        read.fail(key, "a spot light needs exactly one of look_at or direction",
                  "write look_at = [x, y, z] (a point on the axis) or direction = [x, y, z]")
    if "look_at" in raw:
        axis = read.vec3(f"{key}.look_at", raw["look_at"]) - pos
        what = "look_at equals position"
    else:
        axis = read.vec3(f"{key}.direction", raw["direction"])
        what = "direction is zero"
    norm = float(np.linalg.norm(axis))
    if not norm > 1e-12 * max(1.0, float(np.linalg.norm(pos))):
        read.fail(f"{key}.{'look_at' if 'look_at' in raw else 'direction'}", what,
                  "give the axis a length (a point away from the light, or a non-zero direction)")
    cone = float(read.number(f"{key}.cone_angle", raw.get("cone_angle", 30.0)))
    if not 0.0 < cone < 180.0:
        read.fail(f"{key}.cone_angle", f"must be in (0, 180) degrees, got {cone!r}", "use e.g. cone_angle = 30")
    start = float(read.number(f"{key}.falloff_start", raw.get("falloff_start", max(cone - 5.0, 0.0))))
    if not 0.0 <= start <= cone:
        read.fail(f"{key}.falloff_start", f"must be in [0, cone_angle = {cone:g}] degrees, got {start!r}",
                  "use a value at most cone_angle (equal: a hard edge)")
    curve = CURVES[read.string(f"{key}.falloff", raw.get("falloff", "smoothstep"), tuple(CURVES))]
    return Light(pos, intensity, CODE, axis / norm, math.cos(math.radians(cone)), math.cos(math.radians(start)),
                 curve)


def describe(light) -> str:
    return (f"{NAME} {point.at(light)}, axis {light.axis.round(6).tolist()}, cone "
            f"{math.degrees(math.acos(light.cos_end)):g} deg, falloff from {math.degrees(math.acos(light.cos_start)):g} deg")


def irradiance(lights, index, to_points, dist):
    """The point light's I / d^2 times the falloff toward each point."""
    cos = (to_points @ lights.axis[index]) / dist
    return point.irradiance(lights, index, to_points, dist) * falloff_array(cos, *lights.cone[index])[:, None]


@njit
def sample(position, axis, cone, li, px, py, pz):
    """The point light's sample with the falloff toward p as its weight."""
    ux, uy, uz, dist, f = point.sample(position, axis, cone, li, px, py, pz)
    if f == 0.0:
        return ux, uy, uz, dist, f
    # the light leaves along -u
    f = falloff(-(ux * axis[li, 0] + uy * axis[li, 1] + uz * axis[li, 2]), cone[li, 0], cone[li, 1], cone[li, 2])
    return ux, uy, uz, dist, f


@njit
def has_cone(cos_start):
    """Whether an emitter point's emission has an angular profile (a spot's cone, an area light's Lambert lobe)
    from the cosine `cos_start` of its core (`Light.cos_start`, column 1 of `Lights.cone`, column 3 of a
    segment's cone row): a property of the row, not of the light's kind; NO_CONE's (isotropic) is below -1."""
    return cos_start > -1.0


@njit
def falloff(c, cos_end, cos_start, curve):
    """The spot falloff at cosine c to the axis: 1 from cos_start up, 0 from cos_end down (a hard
    edge if they are equal), and between, with t = (c - cos_end) / (cos_start - cos_end),
    SMOOTHSTEP: 3t^2 - 2t^3 (pbrt-v4's SpotLight, smoothstep(cos_end, cos_start, c));
    MITSUBA: (acos(cos_end) - acos(c)) / (acos(cos_end) - acos(cos_start)), linear in the angle
    (Mitsuba 3's spot emitter, src/emitters/spot.cpp `falloff_curve`);
    GLTF: t^2 (KHR_lights_punctual's recommended implementation);
    LAMBERT: t (with cos_end = 0, cos_start = 1: F = max(c, 0), an area light's emitter point)."""
    if c >= cos_start:
        return 1.0
    if c <= cos_end:
        return 0.0
    if curve == MITSUBA:
        cutoff = math.acos(cos_end)
        return (cutoff - math.acos(c)) / (cutoff - math.acos(cos_start))
    t = (c - cos_end) / (cos_start - cos_end)
    if curve == GLTF:
        return t * t
    if curve == LAMBERT:
        return t
    return t * t * (3.0 - 2.0 * t)


@njit
def falloff_array(c, cos_end, cos_start, curve):
    out = np.empty(c.shape[0])
    for i in range(c.shape[0]):
        out[i] = falloff(c[i], cos_end, cos_start, curve)
    return out


@njit
def polynomial_band(curve):
    """Whether the curve's band is a polynomial in the cosine (`band_trig` writes it in phi)."""
    return curve != MITSUBA


@njit
def band_slope(cos_end, cos_start, curve):
    """(cos_start - cos_end) times the largest slope dF/dc of the curve over its band: 1.5
    (smoothstep), 2 (gltf), 1 (lambert), (cos_start - cos_end) / ((acos(cos_end) - acos(cos_start)) sin(acos(cos_start)))
    (mitsuba, dF/dc = 1 / ((cutoff - beam) sin(theta)) is largest at the core's edge; inf at a core
    of 0 degrees)."""
    if curve == SMOOTHSTEP:
        return 1.5
    if curve == GLTF:
        return 2.0
    if curve == LAMBERT:
        return 1.0
    s = math.sqrt(max(0.0, 1.0 - cos_start * cos_start))
    den = (math.acos(cos_end) - math.acos(cos_start)) * s
    return (cos_start - cos_end) / den if den > 0.0 else math.inf


@njit
def cosine_at(A, B, v):
    """c at v = tan(phi/2) in [0, inf]: (2 A v - B (1 - v^2)) / (1 + v^2), B at v = inf."""
    if v == math.inf:
        return B
    return (2.0 * A * v - B * (1.0 - v * v)) / (1.0 + v * v)


@njit
def cone_breaks(A, B, C):
    """(count, v1, v2): the v in (0, inf) where c = A sin(phi) - B cos(phi) equals C, ascending (0, 1
    or 2 of them; unused slots inf). c = C is (B - C) v^2 + 2 A v - (B + C) = 0 (c = 2Av/(1+v^2) -
    B (1-v^2)/(1+v^2)); both roots without cancellation (q = -(A + sign(A) sqrt(disc)))."""
    disc = A * A + B * B - C * C
    if not disc > 0.0:
        return 0, math.inf, math.inf
    a2 = B - C
    q = -(A + math.copysign(math.sqrt(disc), A))
    r1 = q / a2 if a2 != 0.0 else math.inf
    r2 = -(B + C) / q if q != 0.0 else math.inf
    good1 = 0.0 < r1 < math.inf
    good2 = 0.0 < r2 < math.inf
    if good1 and good2:
        return 2, min(r1, r2), max(r1, r2)
    if good1:
        return 1, r1, math.inf
    if good2:
        return 1, r2, math.inf
    return 0, math.inf, math.inf


@njit
def _kind(A, B, cos_end, cos_start, v):
    c = cosine_at(A, B, v)
    return 1.0 if c >= cos_start else (0.0 if c <= cos_end else 2.0)


@njit
def segment_cone(A, B, cos_end, cos_start, va, vb, out):
    """The pieces of [va, vb] (v = tan(phi/2)) between the cone's crossings: out[i] = (v_lo, v_hi,
    kind) with kind 0 (dark), 1 (full intensity), 2 (the falloff's band); returns the count (<= 5 rows
    of `out`, no allocation). A light without a cone (cos_start <= -1) is one full piece."""
    if not has_cone(cos_start):
        out[0, 0], out[0, 1], out[0, 2] = va, vb, 1.0
        return 1
    m = 0
    for C in (cos_end, cos_start):
        k, r1, r2 = cone_breaks(A, B, C)
        for i in range(k):
            r = r1 if i == 0 else r2
            # crossings within rounding of the ends (a segment cut at the cone, segments.py) are the ends
            if va * (1.0 + CUT_TOL) < r < vb * (1.0 - CUT_TOL):
                j = m  # insertion sort into the scratch column out[:, 2]
                while j > 0 and out[j - 1, 2] > r:
                    out[j, 2] = out[j - 1, 2]
                    j -= 1
                out[j, 2] = r
                m += 1
        if cos_start == cos_end:
            break
    for i in range(m):
        out[i + 1, 0] = out[i, 2]  # piece i + 1 starts at cut i
    out[0, 0] = va
    n = 0
    for i in range(m + 1):
        lo = out[i, 0]
        hi = out[i + 1, 0] if i < m else vb
        if hi > lo:
            # classify by the cosine at two inside points; two, so that a level the cosine only
            # touches (a double root, no crossing) at one of them cannot decide: either in the band
            # makes it a band, else the darker wins
            if hi == math.inf:
                x1, x2 = (1.0 + lo) * 3.2, (1.0 + lo) * 4.8
            else:
                x1, x2 = lo + 0.3 * (hi - lo), lo + 0.7 * (hi - lo)
            k1, k2 = _kind(A, B, cos_end, cos_start, x1), _kind(A, B, cos_end, cos_start, x2)
            out[n, 0], out[n, 1], out[n, 2] = lo, hi, 2.0 if max(k1, k2) == 2.0 else min(k1, k2)
            n += 1
    return n


@njit
def lambert_trig(A, B, cos_end, cos_start, a, b):
    """`band_trig` of the LAMBERT curve, F = t = u / d alone: a_0 = u0 / d, a_1 = 2 Re(alpha) / d,
    b_1 = -2 Im(alpha) / d, the rest 0 (real arithmetic only: what an area light's emitter points compile)."""
    d = cos_start - cos_end
    a[0], b[0], a[1], b[1] = -cos_end / d, 0.0, 2.0 * (-0.5 * B) / d, -2.0 * (-0.5 * A) / d
    a[2] = b[2] = a[3] = b[3] = 0.0


@njit
def band_trig(A, B, cos_end, cos_start, curve, a, b):
    """A polynomial curve's band (`polynomial_band`) as a trigonometric polynomial in phi:
    F = sum_{m=0}^{3} a_m cos(m phi) + b_m sin(m phi) (a, b of length 4), for
    t = (c - cos_end) / (cos_start - cos_end) and F = 3 t^2 - 2 t^3 (SMOOTHSTEP), t^2 (GLTF:
    a_3 = b_3 = 0) or t (LAMBERT: a_2 = b_2 = a_3 = b_3 = 0). With z = e^{i phi},
    c - cos_end = alpha z + u0 + conj(alpha) / z,
    alpha = -(B + iA) / 2, u0 = -cos_end; its square and cube are Laurent polynomials whose
    coefficient P_m of z^m gives a_m = 2 Re P_m, b_m = -2 Im P_m (a_0 = P_0)."""
    if curve == LAMBERT:
        lambert_trig(A, B, cos_end, cos_start, a, b)
        return
    d = cos_start - cos_end
    al = complex(-0.5 * B, -0.5 * A)
    u0 = -cos_end
    s0 = u0 * u0 + 2.0 * (al.real * al.real + al.imag * al.imag)  # u^2 coefficients: z^0, z^1, z^2
    s1 = 2.0 * u0 * al
    s2 = al * al
    c0 = s0 * u0 + 2.0 * (s1 * al.conjugate()).real  # u^3: z^0 .. z^3
    c1 = s0 * al + s1 * u0 + s2 * al.conjugate()
    c2 = s1 * al + s2 * u0
    c3 = s2 * al
    p2, p3 = 3.0 / (d * d), 2.0 / (d * d * d)
    if curve == GLTF:
        p2, p3 = 1.0 / (d * d), 0.0
    a[0] = p2 * s0 - p3 * c0
    b[0] = 0.0
    for m, (sq, cu) in enumerate(((s1, c1), (s2, c2), (complex(0.0, 0.0), c3))):
        P = p2 * sq - p3 * cu
        a[m + 1] = 2.0 * P.real
        b[m + 1] = -2.0 * P.imag
