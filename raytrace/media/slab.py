"""Single scattering inside a bounded medium lit through its planar boundary (after the analytic note
on single scattering in homogeneous slabs, "the note" below).

Geometry of a segment (the note's Fig. 1, in the project's segment terms, methods/geometry.py): a
ray enters the medium at its start o with unit direction w and runs inside for x in [0, ell]; the
boundary is the plane through the entry point with outward unit normal n. The depth of the point
o + x w below the plane is z0 + a x with a = -w·n > 0 (the note's omega_e·n_e, its omega = -w). A
point or spot light at p lies outside, at the height H_L = (p - o)·n > 0 above the plane; x_h and h
are its projection coordinate and distance to the ray line, d(x) = sqrt(h^2 + (x - x_h)^2).

* Distant light (the note's eq. 5): the light's refracted direction inside is constant; the path from
  depth z to the boundary has length k = c x with c = a / b, b the cosine of the refracted light
  direction to the normal (the note's sin(beta) / sin(alpha)), so the in-scattered radiance is
      L = ks Phi E_in ∫_0^ell exp(-kt (1 + c) x) dx = ks Phi E_in (1 - exp(-kt (1 + c) ell)) / (kt (1 + c)),
  with E_in the irradiance of the refracted beam (`beam_irradiance`: E T cos1 / cos2, T the
  Fresnel transmittance; E when the boundary is index-matched).
* Point light, index-matched boundary (the note's eq. 6-7): the straight path from o + x w to the light
  crosses the plane after k(x) = d(x) (z0 + a x) / (z0 + a x + H_L) inside, so
      L = I ks ∫_0^ell Phi(cos) exp(-kt (x + k(x)) - kt_out (d(x) - k(x))) / d(x)^2 dx,
  kt_out the extinction outside (0 in the note), cos = -(x - x_h) / d the scattering cosine. It has
  no closed form; `point_exact` integrates it with the project's adaptive Gauss-Legendre rule
  (media/adaptive.py) in the angle theta = atan((x - x_h) / h) seen from the light
  (dx / d^2 = dtheta / h: a bounded, smooth integrand). With the light in the plane (H_L = 0),
  k = d and this is the air-light of eq. 4 (the note's eq. 8).
* Point or spot light in a convex refractive shape (`faces_point`): Fermat's path (`refracted_at`) through
  each face whose plane the light is outside of, the segment's start at depth z0 below that plane,
  counted where the refraction point lies on the face; `faces_quadrature` starts its adaptive rule
  where a refraction point crosses a face's edge (`edge_breaks`) and at a spot's cone crossings.
* The note's separable approximation (its sec. 4.2, for thin media): the exponential part replaced
  by its average under the distant-light limit, c taken at the entry point,
      L_approx = I ks Phi(cos_a) (1 - exp(-kt (1 + c) ell)) / (kt (1 + c) ell) ∫_0^ell d(x)^-2 dx,
  with ∫ d^-2 dx = (theta_b - theta_a) / h in closed form (`inverse_square_integral`).

Refraction uses Snell's law in vector form and the unpolarised Fresnel reflectance of a smooth
dielectric (`refract`, `fresnel`); eta = n_inside / n_outside.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..jit import njit
from ..lights import NO_CONE, SMOOTHSTEP, band_slope, cone_breaks, falloff, has_cone
from .adaptive import INTERVALS, bounded_piecewise, piecewise
from ..geometry.sorting import sort_few
from .fermat_rounding import (SQ3, cosine_error, fermat_pace, fermat_speed, leaving_slope, leg_errors, point_error,
                              refraction_newton, term_rounding)
from .convex_chords import PLANES, SPHERE, section_kinks, sphere_exit
from .convex_directional import envelope
from .inside_rule import QUAD, cut_length, march_or_sample
from .integrand import integrand_of
from .gauss import N10, N20, W10, W20
from .phase import ISOTROPIC, phase_value

STREAM = 1 << 40  # random-number dimensions of inside segments start here (a ray's air-light uses the low ones)
# the spot terms (w_h·A, L_h·A, n·A, cos_end, cos_start, curve) of `refracted_point` for a light without a cone
NO_SPOT = (0.0, 0.0, 0.0, NO_CONE[0], NO_CONE[1], float(SMOOTHSTEP))
# geo rows of `inside_radiance`: entry point, direction w, the light's position (or minus a directional
# light's direction of travel), the spot's axis, its (cos_end, cos_start), the entry face's outward normal,
# the spot's falloff curve (lights.py)
GEO_COLUMNS = 18


@njit
def fresnel(cos_i, eta):
    """Unpolarised Fresnel reflectance of a smooth dielectric boundary for a ray arriving at cosine
    cos_i (> 0) to the normal from the side of index 1, the other side of index eta (relative);
    1 beyond the critical angle."""
    if eta == 1.0:
        return 0.0
    sin2_t = (1.0 - cos_i * cos_i) / (eta * eta)
    if sin2_t >= 1.0:
        return 1.0
    cos_t = math.sqrt(1.0 - sin2_t)
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return 0.5 * (rs * rs + rp * rp)


@njit
def refract(dx, dy, dz, nx, ny, nz, eta):
    """The direction of the unit ray d refracted through a boundary with unit normal n facing it
    (n·d < 0) into a medium of relative index eta: (tx, ty, tz, cos_t), cos_t = -t·n > 0; cos_t = 0
    and t = d on total internal reflection."""
    cos_i = -(dx * nx + dy * ny + dz * nz)
    r = 1.0 / eta
    sin2_t = r * r * (1.0 - cos_i * cos_i)
    if sin2_t >= 1.0:
        return dx, dy, dz, 0.0
    cos_t = math.sqrt(1.0 - sin2_t)
    f = r * cos_i - cos_t
    return r * dx + f * nx, r * dy + f * ny, r * dz + f * nz, cos_t


@njit
def beam_irradiance(cos_i, eta):
    """Irradiance of a collimated beam inside a dielectric boundary, per unit irradiance outside on
    a surface facing the beam, the beam arriving at cosine cos_i: T cos_i / cos_t (the beam's
    cross-section widens from cos_i to cos_t per unit boundary area); 1 when index-matched."""
    if eta == 1.0:
        return 1.0
    sin2_t = (1.0 - cos_i * cos_i) / (eta * eta)
    if sin2_t >= 1.0 or cos_i <= 0.0:
        return 0.0
    return (1.0 - fresnel(cos_i, eta)) * cos_i / math.sqrt(1.0 - sin2_t)


@njit
def slab_distant(kt, ks, phase, c, ell):
    """The note's eq. 5 per unit beam irradiance: ks Phi ∫_0^ell exp(-kt (1 + c) x) dx, c >= 0, ell <= inf."""
    q = kt * (1.0 + c)
    if q * ell < 1e-300 or q == 0.0:
        return ks * phase * ell
    if ell == math.inf:
        return ks * phase / q
    return ks * phase * (-math.expm1(-q * ell)) / q


@njit
def light_path_inside(x, d, z0, a, hl):
    """k(x): length inside of the straight path from depth z0 + a x to a light at height hl above
    the plane, at distance d (the note's eq. 6); d when the light lies in the plane."""
    z = z0 + a * x
    if z <= 0.0:
        return 0.0
    return d * z / (z + hl)


@njit
def refraction_point(rho, z, hl, eta):
    """The horizontal distance r, from the foot of a point at depth z > 0, of the point where the
    path to a light at height hl > 0 and horizontal distance rho refracts (Snell: sin1 = eta sin2,
    sin1 = (rho - r) / o, sin2 = r / k): f(r) = (rho - r) / o - eta r / k falls from f(0) >= 0 to
    f(rho) <= 0, its root found by bisection to the resolution of doubles."""
    lo, hi = 0.0, rho
    for _ in range(80):
        r = 0.5 * (lo + hi)
        if not lo < r < hi:
            break
        f = (rho - r) / math.sqrt((rho - r) * (rho - r) + hl * hl) - eta * r / math.sqrt(r * r + z * z)
        if f > 0.0:
            lo = r
        else:
            hi = r
    return 0.5 * (lo + hi)


@njit
def fermat(x, z0, wl, ll, a, hl, eta):
    """(rho, r) of `refracted_at` at x: the horizontal distance between the light and the point, and
    the refraction point's distance from the point's foot."""
    rho = _rho(x, wl, ll, a)
    return rho, refraction_point(rho, z0 + a * x, hl, eta)


@njit
def _leaving_cosine(x, rho, r, o, hl, wa, la, na):
    """The cosine to the spot's axis of the direction in which the light leaves toward the
    refraction point (`refracted_point`); rho > 0."""
    return ((rho - r) * (x * wa - la) / rho - hl * na) / o


@njit
def refracted_cosine(x, z0, wl, ll, a, hl, eta, wa, la, na):
    """`_leaving_cosine` at x, depth z0 + a x > 0 (-na straight below the light)."""
    rho, r = fermat(x, z0, wl, ll, a, hl, eta)
    if not rho > 1e-12 * (hl + z0 + a * x):
        return -na
    return _leaving_cosine(x, rho, r, math.sqrt((rho - r) * (rho - r) + hl * hl), hl, wa, la, na)


SCAN = 64  # samples of the leaving cosine over a refracted segment, to bracket the cone's crossings
MAX_CUTS = 8


@njit
def refracted_cuts(z0, wl, ll, a, hl, eta, wa, la, na, cos_end, cos_start, end, out):
    """The depths in (0, end) where the cosine of the refracted path's leaving direction crosses the
    cone's levels (kinks of the falloff, its jumps for a hard edge), bracketed on SCAN samples and
    bisected to the resolution of doubles, then those the samples missed (two in one cell, or in
    the half cells at the ends; for eta != 1) isolated with a bound on the cosine's derivative
    (`_cone_crossings`), ascending in out; returns their count (<= MAX_CUTS)."""
    if not has_cone(cos_start):
        return 0
    m = 0
    prev = refracted_cosine(end * 0.5 / SCAN, z0, wl, ll, a, hl, eta, wa, la, na)
    for i in range(1, SCAN):
        x1 = end * (i + 0.5) / SCAN
        c1 = refracted_cosine(x1, z0, wl, ll, a, hl, eta, wa, la, na)
        for level in (cos_end, cos_start):
            if (prev - level) * (c1 - level) < 0.0 and m < MAX_CUTS:
                out[m] = _bisect_cosine(end * (i - 0.5) / SCAN, x1, prev - level, z0, wl, ll, a, hl, eta, wa, la, na,
                                        level)
                m += 1
            if cos_start == cos_end:
                break
        prev = c1
    for level in (cos_end, cos_start):
        if eta == 1.0:  # no speed bound (fermat_speed)
            break
        m = _cone_crossings(z0, wl, ll, a, hl, eta, wa, la, na, level, end, out, m)
        if cos_start == cos_end:
            break
    sort_few(out, 0, m)
    return m


@njit
def _bisect_cosine(lo, hi, s_lo, z0, wl, ll, a, hl, eta, wa, la, na, level):
    """The crossing of `refracted_cosine` with level in [lo, hi] (s_lo: its sign at lo, the other at
    hi) to the resolution of doubles."""
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:
            break
        if (refracted_cosine(mid, z0, wl, ll, a, hl, eta, wa, la, na) - level) * s_lo > 0.0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@njit
def _cone_crossings(z0, wl, ll, a, hl, eta, wa, la, na, level, end, out, m):
    """`refracted_cuts`' crossings of one level that out[:m] lacks, appended (up to MAX_CUTS); returns
    the new count. c(x) - level with the refraction point by Newton's method (media/fermat_rounding.py
    `refraction_newton`), whose derivative is at most K_R / o_min (K_R `_speed`, the refraction
    point's speed; the leaving direction's turn is at most |R'| / o, o >= sqrt(s^2 + hl^2) with
    s >= rho hl / (hl + z) for eta > 1: tan t1 >= tan t2; s >= 0 for eta < 1): an interval [lo, hi] with
    |c(lo) - level| + |c(hi) - level| > K (hi - lo) + 2e-13 holds no crossing, nor one whose ends' values share
    a sign and exceed `cone_bend`'s M (hi - lo)^2 / 8 + 2e-13 (`_off_band`; M from `fermat_bend`, the refraction
    point's acceleration, and K_R); the others are halved down to 1e-13 of the segment's scale (at most
    MAX_ISOLATE evaluations). Where `refracted_cosine` - level changes sign there, or is 0 at one end only
    (`_isolate` counts a 0 as a change: at a crossing whose slope is below an ulp of the cosine over that
    width, the ends of the smallest intervals often lie on the level exactly), with no cut in it: that end
    (where the run of 0s begins or ends), or the sign change bisected to the resolution of doubles."""
    scale = end + math.sqrt(ll) + hl + z0
    width = 1e-13 * scale
    bend = 1e-9 * scale  # fermat_bend's widening: the rounding of the row's numbers
    stack = np.empty((128, 4))
    stack[0, 0], stack[0, 1] = 0.0, end
    stack[0, 2] = _cone_psi(0.0, z0, wl, ll, a, hl, eta, wa, la, na) - level
    stack[0, 3] = _cone_psi(end, z0, wl, ll, a, hl, eta, wa, la, na) - level
    top, evals = 1, 2
    while top > 0 and m < MAX_CUTS:
        top -= 1
        lo, hi, vlo, vhi = stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3]
        rmin, rmax = rho_range(lo, hi, wl, ll, a)
        zlo, zhi = min(z0 + a * lo, z0 + a * hi), max(z0 + a * lo, z0 + a * hi)
        smin = rmin * hl / (hl + zhi) if eta > 1.0 else 0.0
        o_min = math.sqrt(smin * smin + hl * hl)
        if eta > 1.0:
            k = fermat_speed(rmin, rmax, max(zlo, 0.0), a, eta) / o_min
        else:
            k = fermat_pace(hi - lo, rmin, rmax, max(zlo, 0.0), max(zhi, 0.0), a, hl, eta) / (hi - lo) * (
                1.0 + 1e-12) / o_min
        if abs(vlo) + abs(vhi) > k * (hi - lo) + 2e-13:
            continue
        if min(vlo, vhi) > 2e-13 or max(vlo, vhi) < -2e-13:
            curve = cone_bend(fermat_bend(rmin, rmax, zlo, zhi, a, hl, eta, bend), k * o_min, o_min)
            if _off_band(vlo, vhi, 2e-13, 2e-13, curve, hi - lo):
                continue
        if hi - lo <= width or evals >= MAX_ISOLATE or top + 2 > stack.shape[0]:
            c_lo = refracted_cosine(lo, z0, wl, ll, a, hl, eta, wa, la, na) - level
            c_hi = refracted_cosine(hi, z0, wl, ll, a, hl, eta, wa, la, na) - level
            if (c_lo * c_hi < 0.0 or (c_lo == 0.0) != (c_hi == 0.0)) and not _near(out[:m], lo, hi, 0.0):
                out[m] = lo if c_lo == 0.0 else hi
                if c_lo * c_hi < 0.0:
                    out[m] = _bisect_cosine(lo, hi, c_lo, z0, wl, ll, a, hl, eta, wa, la, na, level)
                m += 1
            continue
        mid = 0.5 * (lo + hi)
        vm = _cone_psi(mid, z0, wl, ll, a, hl, eta, wa, la, na) - level
        evals += 1
        stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3] = mid, hi, vm, vhi
        stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2], stack[top + 1, 3] = lo, mid, vlo, vm
        top += 2
    return m


@njit
def _cone_psi(x, z0, wl, ll, a, hl, eta, wa, la, na):
    """`refracted_cosine` with the refraction point by Newton's method (`refraction_newton`)."""
    rho = _rho(x, wl, ll, a)
    z = z0 + a * x
    if not rho > 1e-12 * (hl + z):
        return -na
    r = refraction_newton(rho, z, hl, eta)
    return _leaving_cosine(x, rho, r, math.sqrt((rho - r) * (rho - r) + hl * hl), hl, wa, la, na)


@njit
def rho_range(lo, hi, wl, ll, a):
    """The least and largest horizontal distance `_rho` over [lo, hi] (a convex function of x)."""
    r0, r1 = _rho(lo, wl, ll, a), _rho(hi, wl, ll, a)
    rmin = min(r0, r1)
    if a * a < 1.0 and lo < wl / (1.0 - a * a) < hi:
        rmin = _rho(wl / (1.0 - a * a), wl, ll, a)
    return rmin, max(r0, r1)


@njit
def refracted_point(x, wl, ll, a, hl, eta, kt, ks, code, g, kt_out, wa, la, na, cos_end, cos_start, curve):
    """`refracted_at` through the plane of the segment's start (z0 = 0)."""
    if not a * x > 0.0:
        return 0.0
    rho, r = fermat(x, 0.0, wl, ll, a, hl, eta)
    return refracted_at(x, 0.0, rho, r, wl, a, hl, eta, kt, ks, code, g, kt_out, wa, la, na, cos_end, cos_start,
                        curve)


@njit
def refracted_at(x, z0, rho, r, wl, a, hl, eta, kt, ks, code, g, kt_out, wa, la, na, cos_end, cos_start, curve):
    """The single-scattering integrand at x along an inside segment, at depth z = z0 + a x > 0 below a
    refractive plane, for a unit point or spot light at height hl above it (eta = n_inside / n_outside):
    ks Phi(mu) E exp(-kt (x + k) - kt_out o), k and o the path's lengths inside and outside (Fermat's
    path: rho, r of `fermat`) and E the irradiance across the refracted beam of a point source
    through a plane,
        E = T(cos1) sin1 / (rho cos2 (hl / cos1^2 + z cos1 / (eta cos2^3))),
    (the ray tube: sagittal width rho dphi, meridional d(rho) cos2 with rho = hl tan1 + z tan2 and
    d2 / d1 = cos1 / (eta cos2); its limit I T / (hl + z / eta)^2 below the light, and I / d^2 for
    eta = 1). The segment's horizontal direction w_h = w + a n and the light's horizontal offset L_h
    from the foot of the segment's start enter as wl = w_h·L_h and ll = |L_h|^2 (|w_h|^2 = 1 - a^2). A
    spot light (axis A, cone cos_end, cos_start, its curve; NO_SPOT for a point light) emits toward the
    refraction point R: the light leaves along ((rho - r) u - hl n) / o, whose cosine to A is
    ((rho - r)(x wa - la) / rho - hl na) / o with wa = w_h·A, la = L_h·A, na = n·A."""
    z = z0 + a * x
    k = math.sqrt(r * r + z * z)
    o = math.sqrt((rho - r) * (rho - r) + hl * hl)
    cos1, cos2 = hl / o, z / k
    sin2 = r / k
    if rho > 1e-12 * (hl + z):
        e = (1.0 - fresnel(cos1, eta)) * ((rho - r) / o) / (rho * cos2 * (hl / (cos1 * cos1)
                                                                        + z * cos1 / (eta * cos2 * cos2 * cos2)))
        # the light travels along sin2 u - cos2 n, u = (X_h - L_h) / rho; mu = its cosine to -w
        mu = -(sin2 * (x * (1.0 - a * a) - wl) / rho + a * cos2)
        c = _leaving_cosine(x, rho, r, o, hl, wa, la, na)
    else:
        q = hl + z / eta
        e = (1.0 - fresnel(1.0, eta)) / (q * q)
        mu = -a
        c = -na
    f = falloff(c, cos_end, cos_start, curve)
    if f == 0.0:
        return 0.0
    return ks * phase_value(code, g, mu) * e * f * math.exp(-kt * (x + k) - kt_out * o)


# rows of `refracting_faces`: z0, a, hl, wl, ll, wa, la, na of `refracted_at` for one face, the foot of the
# segment's start on its plane (3), w_h (3), L_h (3), the face's row in `planes`
FACE_COLUMNS = 18
EDGE_TOL = 1e-12  # relative tolerance of the test that a refraction point lies on its face
EDGE_CUTS = 4  # room for a face's crossings of each other plane's line in `edge_breaks`
MAX_ISOLATE = 20000  # evaluations of one function in `_sign_changes` and `_isolate`


@njit
def entry_face(geo, planes):
    """The row of `planes` whose normal is the geo row's entry normal geo[14:17] (-1: none)."""
    entry, best = -1, 1.0 - 1e-9
    for f in range(planes.shape[0]):
        dot = planes[f, 0] * geo[14] + planes[f, 1] * geo[15] + planes[f, 2] * geo[16]
        if dot > best:
            entry, best = f, dot
    return entry


@njit
def refracting_faces(geo, planes, a, hl, wl, ll, spot, out, floor=0.0):
    """The faces of the convex refractive shape {q : n_f·q <= c_f} (`planes`) that the point or spot light of
    the geo row (media/slab.py GEO_COLUMNS) is outside of (n_f·L > c_f; with `floor` < 0, above c_f +
    floor), one row of FACE_COLUMNS each in out; returns their count. Face f's plane is the refractive plane
    of `refracted_at` with z0 = c_f - n_f·p, a = -w·n_f, hl = n_f·L - c_f, L_h = (L - p) - (hl + z0) n_f.
    The row's entry face (the plane whose normal is the row's entry normal geo[14:17]) takes z0 = 0 and the
    entry plane's a, hl, wl, ll and spot terms (wa, la, na: spot[:3]) as given (those of `refracted_point`).
    With no planes (a shape that is not convex), the entry plane alone, face -1 (the note's planar
    boundary)."""
    nf = planes.shape[0]
    entry = entry_face(geo, planes)
    m = 0
    for f in range(nf) if nf > 0 else range(-1, 0):
        if f == entry:
            n0, n1, n2 = geo[14], geo[15], geo[16]
            z0, af, hf, wlf, llf = 0.0, a, hl, wl, ll
        else:
            n0, n1, n2 = planes[f, 0], planes[f, 1], planes[f, 2]
            z0 = max(planes[f, 3] - (n0 * geo[0] + n1 * geo[1] + n2 * geo[2]), 0.0)
            af = -(n0 * geo[3] + n1 * geo[4] + n2 * geo[5])
            hf = n0 * geo[6] + n1 * geo[7] + n2 * geo[8] - planes[f, 3]
        if not hf > floor:
            continue
        row = out[m]
        rel0, rel1, rel2 = geo[6] - geo[0], geo[7] - geo[1], geo[8] - geo[2]
        up = hf + z0  # (L - p)·n
        row[8], row[9], row[10] = geo[0] + z0 * n0, geo[1] + z0 * n1, geo[2] + z0 * n2
        row[11], row[12], row[13] = geo[3] + af * n0, geo[4] + af * n1, geo[5] + af * n2
        row[14], row[15], row[16] = rel0 - up * n0, rel1 - up * n1, rel2 - up * n2
        if f != entry:
            wlf = row[11] * row[14] + row[12] * row[15] + row[13] * row[16]
            llf = row[14] * row[14] + row[15] * row[15] + row[16] * row[16]
        row[0], row[1], row[2], row[3], row[4] = z0, af, hf, wlf, llf
        row[5], row[6], row[7] = spot[0], spot[1], spot[2]
        if f != entry and has_cone(geo[13]):  # the spot's terms, as refracted_point's
            na = n0 * geo[9] + n1 * geo[10] + n2 * geo[11]
            row[5] = geo[3] * geo[9] + geo[4] * geo[10] + geo[5] * geo[11] + af * na
            row[6] = rel0 * geo[9] + rel1 * geo[10] + rel2 * geo[11] - up * na
            row[7] = na
        row[17] = f
        m += 1
    return m


@njit
def _edge_distance(x, row, r, rho, planes, g):
    """n_g·R - c_g for the refraction point R = p_f + x w_h + (r / rho)(L_h - x w_h) on face row's plane
    (`refracting_faces`), with the relative tolerance EDGE_TOL subtracted (`_edge_parts`)."""
    dist, slack = _edge_parts(x, row, r, rho, planes, g)
    return dist - slack


@njit
def _edge_parts(x, row, r, rho, planes, g):
    """`_edge_distance`'s n_g·R - c_g and the tolerance it subtracts."""
    t = r / rho if rho > 0.0 else 0.0
    q0 = row[8] + x * row[11] + t * (row[14] - x * row[11])
    q1 = row[9] + x * row[12] + t * (row[15] - x * row[12])
    q2 = row[10] + x * row[13] + t * (row[16] - x * row[13])
    dist = planes[g, 0] * q0 + planes[g, 1] * q1 + planes[g, 2] * q2 - planes[g, 3]
    return dist, EDGE_TOL * (abs(planes[g, 3]) + abs(q0) + abs(q1) + abs(q2))


@njit
def on_face(x, row, r, rho, planes):
    """Whether the refraction point through face row's plane lies on that face (every other plane
    g: n_g·R <= c_g, to EDGE_TOL)."""
    f = int(row[17])
    for g in range(planes.shape[0]):
        if g != f and _edge_distance(x, row, r, rho, planes, g) > 0.0:
            return False
    return True


@njit
def faces_point(x, faces, planes, eta, kt, ks, code, g, kt_out, cos_end, cos_start, curve):
    """The single-scattering integrand at x along an inside segment of a convex refractive shape for a
    unit point or spot light: `refracted_at` through each face of `faces` (rows of `refracting_faces`)
    whose refraction point lies on that face, summed."""
    total = 0.0
    for j in range(faces.shape[0]):
        total += _face_term(x, faces[j], planes, eta, kt, ks, code, g, kt_out, cos_end, cos_start, curve)[0]
    return total


@njit
def _face_term(x, row, planes, eta, kt, ks, code, g, kt_out, cos_end, cos_start, curve):
    """(term, rho, r, on) of face row at x in `faces_point`: `refracted_at` where the refraction point
    lies on the face (`on_face`: on), else 0; rho, r of `fermat` (0 where X is above the face's plane)."""
    z0, a = row[0], row[1]
    if not z0 + a * x > 0.0:
        return 0.0, 0.0, 0.0, False
    rho, r = fermat(x, z0, row[3], row[4], a, row[2], eta)
    if not on_face(x, row, r, rho, planes):
        return 0.0, rho, r, False
    return (refracted_at(x, z0, rho, r, row[3], a, row[2], eta, kt, ks, code, g, kt_out, row[5], row[6], row[7],
                         cos_end, cos_start, curve), rho, r, True)


@njit
def _edge_value(x, row, planes, g, eta):
    """`_edge_distance` at x, the refraction point found by `fermat`."""
    z0, a = row[0], row[1]
    rho, r = fermat(x, max(z0, 0.0), row[3], row[4], a, row[2], eta)
    return _edge_distance(x, row, r, rho, planes, g)


@njit
def edge_breaks(row, planes, eta, end, out):
    """The x in (0, end) where face row's refraction point R(x) (`refracting_faces`) crosses the line of
    another face plane g in its plane (n_g·R = c_g: where the face's term of `faces_point` switches on or
    off): every sign change of `_edge_value`, isolated with a bound K on its derivative (K_R of
    media/fermat_rounding.py `fermat_speed`, the refraction point's speed, times `edge_tilt`, the part of
    n_g along the face's plane, in which R moves: an interval [lo, hi] with |phi(lo)| + |phi(hi)| > K (hi -
    lo) + 2e-14 S holds none, S the scene's size about the segment; the others are halved down to 1e-13 S,
    at most MAX_ISOLATE evaluations: none missed, no grid) and bisected to the resolution of doubles. The
    isolation reads phi with the refraction point by Newton's method (`_edge_newton`, far cheaper than the
    bisection of `fermat`; within 1e-15 S of phi: its test takes 2e-14 S more), the sign changes and their
    bisection phi itself; one sign change between the segment's ends is bisected from them (for eta = 1,
    which has no such bound, only that one; for eta < 1 K bounds the mean speed over each interval,
    `_speed`). Into out, returns their count (at most out's length)."""
    f = int(row[17])
    m = 0
    scale = math.sqrt(row[8] ** 2 + row[9] ** 2 + row[10] ** 2) + end + math.sqrt(row[4])
    for g in range(planes.shape[0]):
        if g == f or m == out.shape[0]:
            continue
        size = scale + abs(planes[g, 3])
        ends = _edge_value(0.0, row, planes, g, eta) * _edge_value(end, row, planes, g, eta) < 0.0
        if eta != 1.0:
            found = _sign_changes(row, planes, g, eta, end, 2e-14 * size, 1e-14 * size, 1e-13 * size, out, m)
        else:  # no speed bound (fermat_speed): the crossing between the ends only
            found = m + 1 if ends else m
        if found == m + 1 and ends:
            out[m] = _bisect(row, planes, g, eta, 0.0, end)  # the one crossing, bisected from the ends
        m = found
    return m


@njit
def edge_tilt(row, planes, g):
    """A bound on |n_g·v| / |v| for v along face row's plane, in which its refraction point R moves:
    |d(n_g·R)/dx| <= it times |R'|. |n_g x n_f| (n_f the normal of plane row[17]) plus 1e-9 (the
    normals are unit, and the row's vectors in the plane, to a few roundings: w_h's and L_h's normal
    parts, at most 8u S with S = |L_h| + z0 + hl, move R off the plane by at most (K + 1) 8u S / rho,
    below 1e-9 K where rho >= 1e-4 S), at most 1; 1 where z0 = 0, as for the entry face's row (its
    plane the entry point's normal's, within 1e-9 of the plane's in cosine: `entry_face`), and where
    the segment's line passes within 1e-4 S of straight below the light (rho < 1e-4 S)."""
    a, wl, ll = row[1], row[3], row[4]
    rho2 = ll - wl * wl / (1.0 - a * a) if 1.0 - a * a > 0.0 else ll
    if not row[0] > 0.0 or not rho2 >= (1e-4 * (math.sqrt(ll) + row[0] + row[2])) ** 2:
        return 1.0
    f = int(row[17])
    c0 = planes[g, 1] * planes[f, 2] - planes[g, 2] * planes[f, 1]
    c1 = planes[g, 2] * planes[f, 0] - planes[g, 0] * planes[f, 2]
    c2 = planes[g, 0] * planes[f, 1] - planes[g, 1] * planes[f, 0]
    return min(math.sqrt(c0 * c0 + c1 * c1 + c2 * c2) * (1.0 + 1e-11) + 1e-9, 1.0)


@njit
def fermat_bend(rmin, rmax, zlo, zhi, a, hl, eta, d):
    """A bound on the refraction point's acceleration |R''(x)| on the face's plane over a piece of a
    segment where the horizontal distance to the light lies in [rmin, rmax], the depth in [zlo, zhi]
    and the light's height is hl, each range widened by d (the exact geometry's distance from the
    computed one), a = -w.n and W by 1e-9; inf unless eta > 1 and rmin, zlo, hl > 0 after widening
    (z > 0: the refraction point is a smooth function of x, R'' exists). In
    shadows/fermat_legs.py's terms (R = L_f + s u, rho = s + z T(s), T = tan t2, W = |w_h| =
    sqrt(1 - a^2)): R'' = s'' u + 2 s' u' + s u'', with u' = w_perp / rho (w_perp the part of w_h across
    u: |u'| <= W / rho), u'' = -(rho'' u + 2 rho' u') / rho, rho'' = |w_perp|^2 / rho (so |u''| <=
    (q^2 + 2 p q) / rho^2 <= 1.6181 W^2 / rho^2 with p = |rho'|, q = |w_perp|, p^2 + q^2 = W^2), and,
    differentiating rho = s + z T(s) twice (z' = a), s' = (rho' - a T) / (1 + z T'),
    s'' = (rho'' - 2 a T' s' - z T'' s'^2) / (1 + z T'), the denominators >= 1 (z, T' >= 0). In
    sigma = sin t2 = s / (eta o), o = sqrt(s^2 + hl^2): sigma' = hl^2 / (eta o^3), sigma'' =
    -3 s hl^2 / (eta o^5), T' = sigma' / (1 - sigma^2)^(3/2) and T'' = 3 sigma sigma'^2 / (1 -
    sigma^2)^(5/2) + sigma'' / (1 - sigma^2)^(3/2), two terms of opposite signs (|T''| is at most the
    larger). Over the piece s <= rho <= rmax, s >= rmin - zhi / sqrt(eta^2 - 1) (r = z T <= z / sqrt(eta^2
    - 1)), sigma <= rmax / (eta sqrt(rmax^2 + hl^2)) (increasing in s), T <= min(1 / sqrt(eta^2 - 1),
    rmax / zlo) and s / o = eta sigma; each factor is bounded by its value at the end of its range that
    makes it largest. Returned times 1 + 1e-9 (this arithmetic's rounding)."""
    rmin, rmax, zlo, zhi, h_lo, hl = rmin - d, rmax + d, zlo - d, zhi + d, hl - d, hl + d
    if not (eta > 1.0 and rmin > 0.0 and zlo > 0.0 and h_lo > 0.0):
        return math.inf
    w = min(math.sqrt(max(1.0 - a * a, 0.0)) + 1e-9, 1.0)
    aa = abs(a) + 1e-9
    tmax = 1.0 / math.sqrt(eta * eta - 1.0)
    t_hi = min(tmax, rmax / zlo)
    smin = max(rmin - zhi * tmax, 0.0)
    o2 = smin * smin + h_lo * h_lo
    o_min = math.sqrt(o2)
    sig = rmax / (eta * math.sqrt(rmax * rmax + h_lo * h_lo))
    c2 = 1.0 - sig * sig
    dsig = hl * hl / (eta * o2 * o_min)
    t1 = dsig / (c2 * math.sqrt(c2))
    t2 = max(3.0 * sig * dsig * dsig / (c2 * c2 * math.sqrt(c2)), 3.0 * sig * hl * hl / (o2 * o2 * c2 * math.sqrt(c2)))
    s1 = w + aa * t_hi
    s2 = w * w / rmin + 2.0 * aa * t1 * s1 + zhi * t2 * s1 * s1
    return (s2 + 2.0 * s1 * w / rmin + 1.6181 * w * w / rmin) * (1.0 + 1e-9)


@njit
def _interval_bend(lo, hi, z0, a, wl, ll, hl, eta, d):
    """`fermat_bend` over [lo, hi] of a face row's segment (depth z0 + a x, horizontal distance `_rho`)."""
    rmin, rmax = rho_range(lo, hi, wl, ll, a)
    z_lo, z_hi = z0 + a * lo, z0 + a * hi
    return fermat_bend(rmin, rmax, min(z_lo, z_hi), max(z_lo, z_hi), a, hl, eta, d)


@njit
def cone_bend(bend, speed, o_min):
    """A bound on |c''| for the leaving cosine c = A·(R - L) / o, o = |R - L| >= o_min, of a refraction point R
    with |R'| <= speed and |R''| <= bend: with d = (R - L) / o and P = I - d d^T, d' = P R' / o and d'' =
    P R'' / o - (2 d' (d·R') + d (d'·R')) / o, whose second part (d' across d, |d'·R'| <= |d'| |P R'|) is at
    most 2 |d'| |R'| / o, so |c''| <= |d''| <= bend / o_min + 2 (speed / o_min)^2."""
    return (bend / o_min + 2.0 * (speed / o_min) ** 2) * (1.0 + 1e-12)


@njit
def _off_band(vlo, vhi, above, below, curve, h):
    """Whether psi, with |psi''| <= curve on an interval of width h and values vlo, vhi at its ends, stays
    above `above` or below -`below` on it: psi lies above its chord less curve (x - lo)(hi - x) / 2 >=
    curve h^2 / 8, so above min(vlo, vhi) - curve h^2 / 8 (and below max(vlo, vhi) + curve h^2 / 8)."""
    bow = curve * h * h * 0.125 * (1.0 + 1e-12)
    return min(vlo, vhi) > bow + above or max(vlo, vhi) < -(bow + below)


@njit
def _bisect(row, planes, g, eta, lo, hi):
    """The sign change of `_edge_value` in [lo, hi] (signs differ at its ends) to the resolution of doubles."""
    s_lo = _edge_value(lo, row, planes, g, eta)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:
            break
        if _edge_value(mid, row, planes, g, eta) * s_lo > 0.0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@njit
def _edge_newton(x, row, planes, g, eta):
    """`_edge_value` with the refraction point by Newton's method (media/fermat_rounding.py
    `refraction_newton`: within 4e-16 rho of where the computed f changes sign, as the bisection of
    `fermat`, which stops within an ulp of it), so within 1e-15 rho of `_edge_value` (R moves by
    the difference in r, n_g is unit)."""
    rho = _rho(x, row[3], row[4], row[1])
    return _edge_distance(x, row, refraction_newton(rho, max(row[0], 0.0) + row[1] * x, row[2], eta), rho, planes, g)


@njit
def _speed(lo, hi, z0, a, wl, ll, hl, eta):
    """K_R over [lo, hi] of a face row's segment: `fermat_speed` for eta > 1; for eta < 1 `fermat_pace`'s
    displacement over hi - lo (a bound on the mean speed, which is what the isolation's tests need)."""
    if eta < 1.0:
        return fermat_pace(hi - lo, _rho(lo, wl, ll, a), _rho(hi, wl, ll, a), max(z0 + a * lo, 0.0),
                           max(z0 + a * hi, 0.0), a, hl, eta) / (hi - lo) * (1.0 + 1e-12)
    return fermat_speed(_rho(lo, wl, ll, a), _rho(hi, wl, ll, a), max(min(z0 + a * lo, z0 + a * hi), 0.0), a, eta)


@njit
def _sign_changes(row, planes, g, eta, end, tol, newton, width, out, m):
    """`edge_breaks`' isolation of plane g's sign changes, appended to out from m; returns the new count.
    newton: a bound on `_edge_newton`'s difference from `_edge_value` (a smallest interval whose Newton
    values at its ends have one sign and exceed it there has `_edge_value`'s sign there too). Where the
    first-order test fails, `_isolate`'s second-order one: n_g·R - c_g has |psi''| <= M = tilt times
    `fermat_bend` (R'' along the face's plane), and the face test's tolerance that `_edge_distance`
    subtracts (EDGE_TOL (|c_g| + |R|_1), not smooth) lies within EDGE_TOL sqrt(3) K_R (hi - lo) of its
    chord (its slope is at most EDGE_TOL sqrt(3) |R'|), so an interval whose ends' values share a sign
    and exceed M (hi - lo)^2 / 8 + 2 (tol + newton) + that holds no sign change. A smallest interval
    where `_edge_value` changes sign: bisected; where it is 0 at one end only (a crossing whose value
    lies on 0 exactly at a shared end of two smallest intervals, which neither sees as a strict change):
    that end, where the run of 0s begins or ends, unless a cut of plane g lies in the interval."""
    z0, a, wl, ll = row[0], row[1], row[3], row[4]
    tilt = edge_tilt(row, planes, g) * (1.0 + 1e-11)
    reach = math.sqrt(row[8] * row[8] + row[9] * row[9] + row[10] * row[10]) + end + math.sqrt(ll)
    bend = 1e-9 * (reach + abs(z0) + row[2])  # fermat_bend's widening: the rounding of the row's numbers
    stack = np.empty((128, 4))
    stack[0, 0], stack[0, 1] = 0.0, end
    stack[0, 2], stack[0, 3] = _edge_newton(0.0, row, planes, g, eta), _edge_newton(end, row, planes, g, eta)
    top, evals, first = 1, 2, m
    while top > 0 and m < out.shape[0]:
        top -= 1
        lo, hi, vlo, vhi = stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3]
        k = _speed(lo, hi, z0, a, wl, ll, row[2], eta)
        if abs(vlo) + abs(vhi) > k * tilt * (hi - lo) + 2.0 * (tol + newton):
            continue
        margin = 2.0 * (tol + newton) + EDGE_TOL * SQ3 * (1.0 + 1e-12) * k * (hi - lo)
        if (min(vlo, vhi) > margin or max(vlo, vhi) < -margin) and _off_band(
                vlo, vhi, margin, margin, tilt * _interval_bend(lo, hi, z0, a, wl, ll, row[2], eta, bend), hi - lo):
            continue
        if hi - lo <= width or evals >= MAX_ISOLATE or top + 2 > stack.shape[0]:
            if vlo * vhi > 0.0 and min(abs(vlo), abs(vhi)) > newton:  # `_edge_value`'s signs the same
                continue
            c_lo, c_hi = _edge_value(lo, row, planes, g, eta), _edge_value(hi, row, planes, g, eta)
            if c_lo * c_hi < 0.0:
                out[m] = _bisect(row, planes, g, eta, lo, hi)
                m += 1
            elif (c_lo == 0.0) != (c_hi == 0.0) and not _near(out[first:m], lo, hi, 0.0):
                out[m] = lo if c_lo == 0.0 else hi  # where a run of 0s begins or ends
                m += 1
            continue
        mid = 0.5 * (lo + hi)
        vm = _edge_newton(mid, row, planes, g, eta)
        evals += 1
        stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3] = mid, hi, vm, vhi
        stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2], stack[top + 1, 3] = lo, mid, vlo, vm
        top += 2
    return m




class PlanarTheta(NamedTuple):
    """Eq. 7's integrand for a unit point light through an index-matched plane (module docstring), in
    the angle theta = atan((x - x_h) / h) seen from the light (dx / d^2 = dtheta / h): ks Phi
    exp(-(...)), the 1/h outside."""
    xh: float
    h: float
    kt: float
    ks: float
    code: int
    g: float
    z0: float
    a: float
    hl: float
    kt_out: float


class PlanarBehind(PlanarTheta):
    """The same in u = 1 / (x - x_h), for a light behind the segment's start within 45 degrees of its
    line (dx / d^2 = du / (1 + h^2 u^2)): ks Phi exp(-(...)) / (1 + h^2 u^2)."""


class ExponentialPart(NamedTuple):
    """Eq. 7's exponential part alone in x, exp(-kt (x + k(x))) (the note's Figs. 2-3)."""
    xh: float
    h: float
    kt: float
    z0: float
    a: float
    hl: float


class DistantSlab(NamedTuple):
    """Eq. 5's integrand in x, ks Phi exp(-kt (x + a x / b)) per unit beam irradiance (`phase` the
    phase function's value, b the cosine of the refracted light to the normal)."""
    kt: float
    ks: float
    phase: float
    a: float
    b: float


class FacesPoint(NamedTuple):
    """`faces_point` in x (`spot`: the light's (cos_end, cos_start, curve)). With a track (QUAD), its
    evaluations keep in track[0] the largest bound on their rounding (the sum over the faces of
    `term_error`): ph the phase's `phase_condition`, dn, dc the planes' errors, mags and entry as
    `faces_quadrature`'s (else an empty track)."""
    faces: np.ndarray
    planes: np.ndarray
    eta: float
    kt: float
    ks: float
    code: int
    g: float
    kt_out: float
    spot: tuple
    ph: float
    dn: float
    dc: float
    mags: tuple
    entry: int
    track: np.ndarray


@integrand_of(FacesPoint)
@njit
def _faces_value(x, r):
    sp = r.spot
    if r.track.shape[0] == 0:
        return faces_point(x, r.faces, r.planes, r.eta, r.kt, r.ks, r.code, r.g, r.kt_out, sp[0], sp[1], sp[2])
    total, err = 0.0, 0.0
    for j in range(r.faces.shape[0]):
        row = r.faces[j]
        term, rho, rr, on = _face_term(x, row, r.planes, r.eta, r.kt, r.ks, r.code, r.g, r.kt_out, sp[0], sp[1], sp[2])
        total += term
        if on:
            err += term_error(x, row, term, rho, rr, r)
    if err > r.track[0]:
        r.track[0] = err
    return total


@integrand_of(PlanarTheta)
@njit
def _planar_theta(v, r):
    h = r.h
    st = math.sin(v)
    ct = math.cos(v)
    if ct <= 0.0:
        return 0.0
    x = r.xh + h * st / ct
    d = h / ct
    k = light_path_inside(x, d, r.z0, r.a, r.hl)
    path = r.kt * (x + k) + (r.kt_out * (d - k) if r.kt_out > 0.0 else 0.0)
    return r.ks * phase_value(r.code, r.g, -st) * math.exp(-path)


@integrand_of(PlanarBehind)
@njit
def _planar_behind(v, r):
    if v <= 0.0:
        return 0.0
    h = r.h
    q = math.sqrt(1.0 + h * h * v * v)
    x = r.xh + 1.0 / v
    d = q / v
    k = light_path_inside(x, d, r.z0, r.a, r.hl)
    path = r.kt * (x + k) + (r.kt_out * (d - k) if r.kt_out > 0.0 else 0.0)
    return r.ks * phase_value(r.code, r.g, -1.0 / q) * math.exp(-path) / (q * q)


@integrand_of(ExponentialPart)
@njit
def _exponential_part(x, r):
    d = math.sqrt(r.h * r.h + (x - r.xh) * (x - r.xh))
    return math.exp(-r.kt * (x + light_path_inside(x, d, r.z0, r.a, r.hl)))


@integrand_of(DistantSlab)
@njit
def _distant_slab(x, r):
    return r.ks * r.phase * math.exp(-r.kt * (x + r.a * x / r.b))


@njit
def _one_piece(rec, lo, hi, rtol, stats):
    """The adaptive rule (adaptive.piecewise) over [lo, hi]: tails below rtol/10 of a first 20-point
    estimate per unit of the variable are not refined."""
    return piecewise(rec, (lo, hi), 2, rtol, N10, W10, N20, W20, stats)


@njit
def faces_quadrature(faces, planes, ell, end, kt, ks, code, g, kt_out, eta, spot, rtol, dplanes, mags, entry, stats,
                     value, bound):
    """(∫_0^ell `faces_point` dx, a bound on its error) for a unit point or spot light (`spot`: (cos_end,
    cos_start, curve)) in a convex refractive shape, per channel (kt, ks, kt_out: one each, every one's
    integral ending at `end` = min(ell, 745 / kt), where exp(-kt x) underflows) into value and bound,
    adaptive (`_one_piece`'s rule) on the pieces between the breaks of the integrand: where a face's
    refraction point crosses one of its edges (`edge_breaks`) and where a spot's cone levels are
    crossed on a face's refracted path (`refracted_cuts`). With no planes (`refracting_faces`' entry
    plane alone), the pieces between the cone's crossings. The breaks and their isolation in the
    bound read no channel's coefficients: found once for all the channels. The bound
    (docs/error_bounds.md, "Point and spot light in refractive shapes") is the rule's (inf where a
    panel was accepted at a cap), plus 3 times each piece's largest rounding of an evaluation
    (`FacesPoint`'s track) times its width (the positive weights' sum, over the rule's 20-point sums and
    the 10-point sums of its test), plus the breaks' location error (`break_errors`), plus u per
    interval; inf with no planes, eta = 1, or for eta < 1 without the scene's size (mags[3] = 0:
    `out_of_faces` without the planes' errors). dplanes: the planes' errors (interiors/rows.py
    `plane_errors`); mags: (|p|, |L|, |L - p|, |p| + ell + |L| + the largest |c_f|) (media/fermat_rounding.py
    `leg_errors`); entry: the entry face's row in planes."""
    value[:] = 0.0
    bound[:] = 0.0
    if not ell > 0.0:
        return
    nf = faces.shape[0]
    cuts = np.empty(nf * (EDGE_CUTS * planes.shape[0] + MAX_CUTS))
    m = 0
    for j in range(nf):
        row = faces[j]
        m += refracted_cuts(row[0], row[3], row[4], row[1], row[2], eta, row[5], row[6], row[7], spot[0], spot[1],
                            end, cuts[m:])
        m += edge_breaks(row, planes, eta, end, cuts[m:m + EDGE_CUTS * planes.shape[0]])
    cuts[:m].sort()
    bounded = planes.shape[0] > 0 and (eta > 1.0 or (eta < 1.0 and mags[3] > 0.0))  # eta < 1: given mags
    graze = bounded and nf == 1 and not faces[0, 2] > GRAZING * mags[3]  # bounded whole (`grazing_bound`)
    located = np.zeros(kt.shape[0])
    track = np.zeros(1)
    for c in range(kt.shape[0]):
        rec = FacesPoint(faces, planes, eta, kt[c], ks[c], code, g, kt_out[c], spot, phase_condition(code, g),
                         dplanes[0], dplanes[1], mags, entry, track)
        if bounded and not graze and c == 0:  # the breaks' location errors of every channel
            channel_break_errors(rec, end, cuts[:m], kt, ks, kt_out, located)
        if ks[c] == 0.0:
            continue
        before = stats[INTERVALS]
        total, rule, rounding, lo = 0.0, 0.0, 0.0, 0.0
        for i in range(m + 1):
            hi = cuts[i] if i < m else end
            if hi > lo:
                track[0] = 0.0
                v, e = bounded_piecewise(rec, (lo, hi), 2, rtol, N10, W10, N20, W20, stats)
                total += v
                rule += e
                rounding += 3.0 * track[0] * (hi - lo)
            lo = hi
        value[c] = total
        if graze:  # both the value and the exact integral lie in [0, total + the bound on the exact]
            row = faces[0]
            bound[c] = total + grazing_bound(row[0], row[1], row[2], row[3], row[4], end, ks[c], code, g, eta, dplanes,
                                             mags)
        else:
            bound[c] = (rule + rounding + located[c] + (stats[INTERVALS] - before) * U * (total + rule) if bounded
                        else math.inf)


GRAZING = 1e-9  # a light within this of the scene's size of a face's plane: the face bounded whole (`grazing_bound`)


@njit
def grazing_bound(z0, a, hl, wl, ll, end, ks, code, g, eta, dplanes, mags):
    """A bound on ∫_0^end of a face's exact term of `faces_point` for a unit light, on the face or not
    (z0, a, hl, wl, ll of its row, `refracting_faces`), for a light near the face's plane: its exact
    height hl_e <= max(hl, 0) + dc + sqrt(3) dn |L| + 32u S (hl computed, dn, dc the planes' errors,
    S = mags[3] >= |p|, |L|, |c_f|); no term where hl_e <= 0; else the tube's irradiance (`refracted_at`)
    E <= T sin1 cos1^2 / (rho cos2 hl_e) (its denominator without the second term) = T sin1 hl_e /
    (rho cos2 o^2) <= hl_e / (rho cos2 o^2), with cos2 >= sqrt(1 - 1 / eta^2) (sin2 = sin1 / eta) and
    o >= rho - r >= rho - z / sqrt(eta^2 - 1) (r = z tan2); the falloff, T and the attenuation are at
    most 1, Phi at most its value at mu = 1 or -1 (isotropic, Rayleigh, HG). rho's least value over
    [0, end] (`rho_range`) less 1e-6 S and the depth's largest (z0 + a x at an end) plus 1e-6 S (the
    exact ones differ by the rounding and the planes' errors, far less). inf where the bound on o or
    rho is not positive, or for eta <= 1."""
    if not eta > 1.0:
        return math.inf
    size = mags[3]
    rho = rho_range(0.0, end, wl, ll, a)[0] - 1e-6 * size
    o = rho - (max(z0, z0 + a * end, 0.0) + 1e-6 * size) / math.sqrt(eta * eta - 1.0)
    if not (rho > 0.0 and o > 0.0):
        return math.inf
    h = max(hl, 0.0) + dplanes[1] + SQ3 * dplanes[0] * mags[1] + 32.0 * U * size
    phi = max(phase_value(code, g, 1.0), phase_value(code, g, -1.0))
    return end * ks * phi * h / (rho * math.sqrt(1.0 - 1.0 / (eta * eta)) * o * o) * (1.0 + 1e-9)


@njit
def term_error(x, row, term, rho, r, rec):
    """A bound on the rounding of face row's term `term` at x (lit through the face): its relative
    rounding (media/fermat_rounding.py `term_rounding`) times it, and where the spot's cosine c lies
    within its error dcos of the falloff's band, the falloff's slope times dcos times the term without
    the falloff (a hard edge's jump is a break, `break_errors`). For eta < 1 where the relative rounding exceeds
    1/4 (near the critical circle: first order no longer bounds it), the term plus `leaving_envelope`."""
    sp = rec.spot
    z0, a, hl = row[0], row[1], row[2]
    eps, dcos = term_rounding(x, z0, a, hl, row[4], rho, r, rec.eta, rec.kt, rec.kt_out, rec.ph, rec.dn, rec.dc,
                              rec.mags, row[17] == rec.entry)
    err = eps * term
    if rec.eta < 1.0 and not eps <= 0.25:  # beyond first order: the term and the exact one's bound
        err = term + leaving_envelope(x, row, 0.0, rec.ks, rec.code, rec.g, rec.eta, rec.dn, rec.dc, rec.mags,
                                      row[17] == rec.entry)
    if has_cone(sp[1]) and sp[1] > sp[0]:
        z = z0 + a * x
        c = -row[7]
        if rho > 1e-12 * (hl + z):
            c = _leaving_cosine(x, rho, r, math.sqrt((rho - r) * (rho - r) + hl * hl), hl, row[5], row[6], row[7])
        if sp[0] - dcos < c < sp[1] + dcos:
            bare = refracted_at(x, z0, rho, r, row[3], a, hl, rec.eta, rec.kt, rec.ks, rec.code, rec.g, rec.kt_out,
                                row[5], row[6], row[7], NO_CONE[0], NO_CONE[1], SMOOTHSTEP)
            err += band_slope(sp[0], sp[1], int(sp[2])) / (sp[1] - sp[0]) * dcos * bare * (1.0 + eps)
    return err


@njit
def leaving_envelope(x, row, spread, ks, code, g, eta, dn, dc, mags, entry):
    """For eta < 1, a bound on face row's exact term of `faces_point` for a unit light within `spread` of x along
    the segment (media/fermat_rounding.py's module docstring, "Light leaving the denser side"): with the exact
    depth z <= |z0 + a x| + |a| spread + dz, rho >= rho(x) - spread - drho and hl_e = hl - dh (`leg_errors`'),
    ks Phi_max times the least of 2 (eta + 1 / eta) / hl_e^2 and, beyond the critical circle (k >= r >= rho -
    s_c, s_c = eta (hl + dh) / sqrt(1 - eta^2): s <= hl tan t_c), 2 (1 + eta^2) z^2 / (hl_e (1 - eta^2) k^3)
    (from Q >= B: E <= T sin1 eta cos2^2 / (rho z cos1), T <= 2 (eta + 1 / eta) cos2 / cos1, sin1 / rho <= 1 /
    hl, cos1^2 >= 1 - eta^2, cos2^3 / z = z^2 / k^3); inf where hl_e is not positive. Times 1 + 1e-9."""
    z0, a, hl, wl, ll = row[0], row[1], row[2], row[3], row[4]
    rho = _rho(x, wl, ll, a)
    dz, dh, drho, _, _ = leg_errors(x + spread, 1.0, 0.0, hl, ll, max(rho, 1e-300), eta, dn, dc, mags, entry, 0.0)
    h = hl - dh
    if not h > 0.0:
        return math.inf
    e = 2.0 * (eta + 1.0 / eta) / (h * h)
    k = rho - spread - drho - eta * (hl + dh) / math.sqrt(1.0 - eta * eta)
    if k > 0.0:
        z = abs(z0 + a * x) + abs(a) * spread + dz
        e = min(e, 2.0 * (1.0 + eta * eta) * z * z / (h * (1.0 - eta * eta) * k * k * k))
    phi = max(phase_value(code, g, 1.0), phase_value(code, g, -1.0))
    return ks * phi * e * (1.0 + 1e-9)


_EDGE, _CONE = 0, 1


@njit
def break_errors(rec, end, cuts):
    """The breaks' location error of `faces_quadrature` over [0, end] (cuts: the breaks it took) for
    rec's channel (`channel_break_errors`)."""
    out = np.zeros(1)
    channel_break_errors(rec, end, cuts, np.array([rec.kt]), np.array([rec.ks]), np.array([rec.kt_out]), out)
    return out[0]


@njit
def channel_break_errors(rec, end, cuts, kt, ks, kt_out, out):
    """out[c] = the breaks' location error of `faces_quadrature` over [0, end] (cuts: the breaks it
    took) for each channel (kt, ks, kt_out: one each; the rest of rec's integrand is theirs): for
    every face row f and every other plane g, the roots of n_g·R(x) - c_g (R(x) face f's refraction
    point, whose computed value is within E of the exact one, E the refraction point's error
    `point_error` at the segment's worst (largest x, k, s, least rho) plus the planes' errors; the
    face test's tolerance EDGE_TOL apart) and, for a spot, of its cosine minus each cone level (within
    the cosine's error `cosine_error`) are isolated by `_isolate` (which reads no channel's
    coefficients); inf where one may lie away from every cut (the rule would have met an unfound jump
    or kink), else the sum over the undecided intervals of their width times twice the face's term at
    their ends (the jumps: an edge's, a hard cone edge's). For eta < 1 the refraction point's and the
    cosine's errors are `_isolate`'s per interval (`_leaving_tol`): no bound on dr/dz holds over a whole
    piece that starts on the face's plane inside the critical circle and leaves it."""
    faces, planes, eta, sp = rec.faces, rec.planes, rec.eta, rec.spot
    out[:] = 0.0
    if eta == 1.0:
        out[:] = math.inf
        return
    width = 1e-13 * rec.mags[3]
    part = np.empty(kt.shape[0])
    for j in range(faces.shape[0]):
        row = faces[j]
        z0, a, hl, wl, ll = row[0], row[1], row[2], row[3], row[4]
        rho_min, rho_max = rho_range(0.0, end, wl, ll, a)
        if not hl > GRAZING * rec.mags[3] or not rho_min > 0.0:  # a light within a few roundings of the face's plane
            out[:] = math.inf
            return
        z_max = max(z0, z0 + a * end)
        k_max = math.sqrt(rho_max * rho_max + z_max * z_max)
        entry = row[17] == rec.entry
        args = (end, k_max, rho_max, hl, ll, rho_min, eta, rec.dn, rec.dc, rec.mags, entry)
        e_point = point_error(*args) if eta > 1.0 else 0.0  # for eta < 1 per interval, `_isolate`
        q = SQ3 * max(rec.mags[0] + end + z_max, rec.mags[1] + hl)  # |R|_1, R between the feet of X and L
        for g in range(planes.shape[0]):
            if g == int(row[17]):
                continue
            tol = e_point + 8.0 * U * rho_max + rec.dc + SQ3 * rec.dn * q + 16.0 * U * (abs(planes[g, 3]) + q)
            if not _isolate(_EDGE, rec, row, g, 0.0, end, tol, EDGE_TOL * (abs(planes[g, 3]) + q), cuts, width, hl,
                            kt, ks, kt_out, part):
                out[:] = math.inf
                return
            out += part
        if has_cone(sp[1]):
            tol = (cosine_error(*args) if eta > 1.0 else 0.0) + 8.0 * U * rho_max / hl
            s_min = rho_min * hl / (hl + z_max) if eta > 1.0 else 0.0  # s / rho >= hl / (hl + z): tan t1 >= tan t2
            for level in (sp[0], sp[1]):
                if not _isolate(_CONE, rec, row, -1, level, end, tol, 0.0, cuts, width, math.hypot(s_min, hl), kt,
                                ks, kt_out, part):
                    out[:] = math.inf
                    return
                out += part
                if sp[1] == sp[0]:
                    break


@njit
def _rho(x, wl, ll, a):
    """The horizontal distance between the light and the point at x (`fermat`'s rho)."""
    return math.sqrt(max(x * x * (1.0 - a * a) - 2.0 * x * wl + ll, 0.0))


@njit
def _psi(kind, x, rec, row, g, level):
    """_EDGE: n_g·R - c_g of plane g; _CONE: the leaving cosine minus level; with the refraction point
    by Newton's method (media/fermat_rounding.py `refraction_newton`: within 4e-16 rho of the
    bisection's resolution, covered by `break_errors`' tolerance)."""
    z0, a, hl = row[0], row[1], row[2]
    rho = _rho(x, row[3], row[4], a)
    z = max(z0, 0.0) + a * x
    r = refraction_newton(rho, z, hl, rec.eta)
    if kind == _EDGE:
        return _edge_parts(x, row, r, rho, rec.planes, g)[0]
    if not rho > 1e-12 * (hl + z):
        return -row[7] - level
    return _leaving_cosine(x, rho, r, math.sqrt((rho - r) * (rho - r) + hl * hl), hl, row[5], row[6], row[7]) - level


@njit
def _phi(kind, x, rec, row, g, level):
    """What the integrand's switches take: _EDGE `_edge_value` of plane g (its tolerance subtracted),
    _CONE `refracted_cosine` minus level."""
    if kind == _EDGE:
        return _edge_value(x, row, rec.planes, g, rec.eta)
    return refracted_cosine(x, row[0], row[3], row[4], row[1], row[2], rec.eta, row[5], row[6], row[7]) - level


@njit
def _jump(kind, x, rec, row, kt, ks, kt_out, out):
    """out[c] = the face's term at x without its face test (_EDGE) or without the falloff (_CONE) for
    each channel (kt, ks, kt_out: one each): at least its jump there."""
    out[:] = 0.0
    z0, a, hl = row[0], row[1], row[2]
    if not z0 + a * x > 0.0:
        return
    rho, r = fermat(x, z0, row[3], row[4], a, hl, rec.eta)
    cone = rec.spot if kind == _EDGE else (NO_CONE[0], NO_CONE[1], float(SMOOTHSTEP))
    for c in range(kt.shape[0]):
        out[c] = refracted_at(x, z0, rho, r, row[3], a, hl, rec.eta, kt[c], ks[c], rec.code, rec.g, kt_out[c],
                              row[5], row[6], row[7], cone[0], cone[1], cone[2])


@njit
def _isolate(kind, rec, row, g, level, end, tol, slack, cuts, width, o_min, kt, ks, kt_out, err):
    """err[c] = the location error of one break over [0, end] for each channel (kt, ks, kt_out: one each; the
    rest of rec's integrand is theirs); False where it is inf (err then unset): the exact switch is a root
    of psi_exact, the computed one a sign change of phi (`_phi`: psi - t, 0 <= t <= slack, the face test's
    tolerance), and the computed psi (`_psi`) is within tol of psi_exact, so the two may differ only where
    psi lies in the band [-tol, slack + tol]. With K a bound on |psi'| (fermat_rounding.py `fermat_speed`
    K_R times `edge_tilt` and 1 + 1e-11 for an edge plane; over the outside leg's least length o_min for a
    cosine, whose unit direction turns at most |R'| / o), an interval [lo, hi] with psi(lo) + psi(hi) > K
    (hi - lo) + 4 tol + 2 slack or -(psi(lo) + psi(hi)) > K (hi - lo) + 4 tol lies outside the band. Where
    that fails, a second-order test: psi_exact is twice differentiable on the interval (the point below the
    face's plane, away from straight below the light) with |psi''| <= M, for an edge plane tilt times
    `fermat_bend`'s bound on |R''| over the interval (R'' lies along the face's plane, as R' does), for a
    cosine `cone_bend`'s, so it lies above its chord less M (x - lo)(hi - x) / 2 >= M (hi - lo)^2 / 8, and
    above min(psi(lo), psi(hi)) - tol - M (hi - lo)^2 / 8: an interval with min(psi(lo), psi(hi)) > M (hi -
    lo)^2 / 8 + 2 tol + slack (or max(...) < -(M (hi - lo)^2 / 8 + 2 tol)) lies outside the band too
    (`_off_band`). This closes a refraction point that slides along an edge's line (a cosine that stays
    near a level), close to it over a long stretch: there the first-order test, whose K is the speed of R
    and not of its distance from the line, excludes only intervals below psi / K; the second-order one
    those below sqrt(8 psi / M). The others are halved until shorter than `width`, or than 1e4 `width`
    with both ends in twice the band:
    these undecided intervals come out from left to right, and runs of adjacent ones form clusters. A
    cluster where phi changes sign with no cut within `width` of it (a jump or kink the rule did not break
    at): inf; else, for an edge or a hard cone edge, the sum of each undecided interval's width times twice
    the larger `_jump` at its ends (the term varies by far less than that over 1e4 `width` = 1e-9 of the
    scene's size: its log-derivative is at most a few over the light's height, which is above 1e-9 of it).
    inf after MAX_ISOLATE evaluations. The isolation reads no channel's coefficients. For eta < 1 (`_speed`: K
    the mean speed over the interval, which is what the first-order test needs; `fermat_bend` is inf) tol
    is the interval's own plus `_leaving_tol`, and an undecided interval where the depth is below 10 times
    its width is inf (the term's log-derivative grows like 2 / z near the plane, E ~ z^2, so twice the
    larger end holds only away from it)."""
    z0, a, wl, ll = row[0], row[1], row[3], row[4]
    eta = rec.eta
    hard = kind == _EDGE or rec.spot[0] == rec.spot[1]
    tilt = edge_tilt(row, rec.planes, g) * (1.0 + 1e-11) if kind == _EDGE else 1.0
    bend = 1e-9 * rec.mags[3] + 2.0 * (rec.dc + SQ3 * rec.dn * rec.mags[3])  # fermat_bend's widening
    stack = np.empty((128, 4))
    stack[0, 0], stack[0, 1] = 0.0, end
    stack[0, 2], stack[0, 3] = _psi(kind, 0.0, rec, row, g, level), _psi(kind, end, rec, row, g, level)
    top, evals = 1, 2
    err[:] = 0.0
    j_lo, j_hi = np.empty(kt.shape[0]), np.empty(kt.shape[0])
    run_lo, run_hi, change = -1.0, -1.0, False
    while top > 0:
        top -= 1
        lo, hi, vlo, vhi = stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3]
        k = _speed(lo, hi, z0, a, wl, ll, row[2], eta)
        k = k * tilt if kind == _EDGE else k / o_min
        t = tol if eta > 1.0 else tol + _leaving_tol(kind, rec, row, lo, hi)
        if vlo + vhi > k * (hi - lo) + 4.0 * t + 2.0 * slack or -(vlo + vhi) > k * (hi - lo) + 4.0 * t:
            continue
        if min(vlo, vhi) > 2.0 * t + slack or max(vlo, vhi) < -2.0 * t:
            curve = _interval_bend(lo, hi, z0, a, wl, ll, row[2], eta, bend)
            curve = tilt * curve if kind == _EDGE else cone_bend(curve, k * o_min, o_min)
            if _off_band(vlo, vhi, 2.0 * t + slack, 2.0 * t, curve, hi - lo):
                continue
        inside = -2.0 * t <= vlo <= slack + 2.0 * t and -2.0 * t <= vhi <= slack + 2.0 * t
        if hi - lo <= width or (inside and hi - lo <= 1e4 * width):
            if eta < 1.0 and not min(z0 + a * lo, z0 + a * hi) >= 10.0 * (hi - lo):
                return False
            if lo != run_hi:  # a new cluster: close the last
                if change and not _near(cuts, run_lo, run_hi, width):
                    return False
                run_lo, change = lo, False
            run_hi = hi
            change = change or _phi(kind, lo, rec, row, g, level) * _phi(kind, hi, rec, row, g, level) <= 0.0
            evals += 2
            if hard:
                _jump(kind, lo, rec, row, kt, ks, kt_out, j_lo)
                _jump(kind, hi, rec, row, kt, ks, kt_out, j_hi)
                for c in range(kt.shape[0]):
                    err[c] += 2.0 * max(j_lo[c], j_hi[c]) * (hi - lo)
            continue
        if evals >= MAX_ISOLATE or top + 2 > stack.shape[0]:
            return False
        mid = 0.5 * (lo + hi)
        vm = _psi(kind, mid, rec, row, g, level)
        evals += 1
        stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3] = mid, hi, vm, vhi
        stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2], stack[top + 1, 3] = lo, mid, vlo, vm
        top += 2
    return not (change and not _near(cuts, run_lo, run_hi, width))


@njit
def _leaving_tol(kind, rec, row, lo, hi):
    """For eta < 1, over [lo, hi] of face row's segment: the refraction point's error (_EDGE, media/fermat_rounding.py
    `point_error`) or the leaving cosine's (_CONE, `cosine_error`) at the interval's worst (x = hi, the largest
    k and s, the least rho) with `leaving_slope`'s bound on dr/dz there; inf where rho may vanish."""
    z0, a, hl, wl, ll = row[0], row[1], row[2], row[3], row[4]
    rmin, rmax = rho_range(lo, hi, wl, ll, a)
    if not (rmin > 0.0 and hl > 0.0):
        return math.inf
    z_lo, z_hi = max(min(z0 + a * lo, z0 + a * hi), 0.0), max(z0 + a * lo, z0 + a * hi, 0.0)
    slope = leaving_slope(rmin, rmax, z_lo, hl, rec.eta)
    args = (hi, math.sqrt(rmax * rmax + z_hi * z_hi), rmax, hl, ll, rmin, rec.eta, rec.dn, rec.dc, rec.mags,
            row[17] == rec.entry, slope)
    return point_error(*args) if kind == _EDGE else cosine_error(*args)


@njit
def _near(cuts, lo, hi, width):
    """Whether a cut lies within width of [lo, hi]."""
    for c in cuts:
        if lo - width <= c <= hi + width:
            return True
    return False


@njit
def point_exact(xh, h, ell, kt, ks, code, g, z0, a, hl, kt_out, rtol, stats):
    """The note's eq. 7 for a unit-intensity point light (module docstring), adaptive to `rtol`: the
    in-scattered radiance at the segment's start."""
    if ks == 0.0 or not ell > 0.0:
        return 0.0
    if xh < 0.0 and h < -xh:  # behind the start, within 45 degrees of the line: u = 1 / (x - x_h)
        lo = 0.0 if ell == math.inf else 1.0 / (ell - xh)
        return _one_piece(PlanarBehind(xh, h, kt, ks, code, g, z0, a, hl, kt_out), lo, -1.0 / xh, rtol, stats)
    lo = math.atan2(-xh, h)
    hi = 0.5 * math.pi if ell == math.inf else math.atan2(ell - xh, h)
    return _one_piece(PlanarTheta(xh, h, kt, ks, code, g, z0, a, hl, kt_out), lo, hi, rtol, stats) / h


@njit
def exponential_part(xh, h, ell, kt, z0, a, hl, rtol, stats):
    """∫_0^ell exp(-kt (x + k(x))) dx: eq. 7 without the falloff and the phase function, as the note
    plots it (Figs. 2-3, 6-8)."""
    if not ell > 0.0:
        return 0.0
    return _one_piece(ExponentialPart(xh, h, kt, z0, a, hl), 0.0, ell, rtol, stats)


@njit
def inverse_square_integral(xh, h, ell):
    """∫_0^ell dx / (h^2 + (x - x_h)^2) = (atan((ell - x_h)/h) - atan(-x_h/h)) / h, as one atan2 (no
    cancellation when the light is near the ray line, h -> 0: the note's s / (l (s + l)))."""
    b = ell - xh
    if h == 0.0:  # on the line, outside the segment (xh < 0 or xh > ell)
        return -1.0 / xh if ell == math.inf else ell / (-xh * b)
    if ell == math.inf:
        return (0.5 * math.pi - math.atan2(-xh, h)) / h
    return math.atan2(ell * h, h * h - xh * b) / h


@njit
def point_approx(xh, h, ell, kt, ks, code, g, a, b):
    """The note's separable approximation of eq. 7 (sec. 4.2) for a unit-intensity light: the
    distant-light average (eq. 5 / ell, c = a / b at the entry point) times ∫ d^-2 dx; the phase
    function at the entry point's scattering angle. 0 for a light in the boundary plane (b = 0,
    c = inf), as eq. 5."""
    if ks == 0.0 or not ell > 0.0 or b <= 0.0 or ell == math.inf:
        return 0.0
    c = a / b
    da = math.sqrt(h * h + xh * xh)
    mean = slab_distant(kt, ks, phase_value(code, g, xh / da), c, ell) / ell
    return mean * inverse_square_integral(xh, h, ell)


@njit
def distant_quadrature(kt, ks, phase, a, b, ell, rtol, stats):
    """Eq. 5's integral by the adaptive rule (the reference for `slab_distant`), per unit beam
    irradiance; an infinite segment is cut where the integrand falls below e^-745 of its start."""
    if ks == 0.0 or not ell > 0.0:
        return 0.0
    end = min(ell, 745.0 / (kt * (1.0 + a / b))) if kt > 0.0 else ell
    return _one_piece(DistantSlab(kt, ks, phase, a, b), 0.0, end, rtol, stats)


@njit
def convex_exit_face(px, py, pz, ux, uy, uz, planes):
    """(distance, face) from the inside point p along the unit direction u to the boundary of the
    convex polyhedron {q : n_i·q <= c_i} (rows n_x, n_y, n_z, c of `planes`, n outward): the
    nearest plane ahead, the first of equals (face -1 and inf when none is ahead)."""
    best, face = math.inf, -1
    for i in range(planes.shape[0]):
        den = planes[i, 0] * ux + planes[i, 1] * uy + planes[i, 2] * uz
        if den > 0.0:
            t = max((planes[i, 3] - planes[i, 0] * px - planes[i, 1] * py - planes[i, 2] * pz) / den, 0.0)
            if t < best:
                best, face = t, i
    return best, face


class ConvexIntegrand(NamedTuple):
    """`convex_integrand` in x along an inside segment of a convex index-matched shape."""
    geo: np.ndarray
    kind: int
    planes: np.ndarray
    directional: bool
    kt: float
    ks: float
    code: int
    g: float
    kt_out: float
    phase: float
    only: int


@njit(inline="always")
def exit_face(kind, planes, px, py, pz, ux, uy, uz):
    """`convex_exit_face` of the face planes (PLANES), or (convex_chords.sphere_exit, -1) of the exact
    sphere planes[0] = (centre, radius) (SPHERE)."""
    if kind == SPHERE:
        return sphere_exit(planes[0], px, py, pz, ux, uy, uz), -1
    return convex_exit_face(px, py, pz, ux, uy, uz, planes)


@njit
def convex_integrand(x, geo, kind, planes, directional, kt, ks, code, g, kt_out, phase, only):
    """The single-scattering integrand at x along an inside segment of a convex index-matched shape
    (its boundary of `kind`: face planes, or an exact sphere, convex_chords.py), with the light's
    straight path inside measured exactly to the shape's boundary: geo = (entry
    point, segment direction w, the light's position or, for a directional light, minus its
    direction of travel); a directional light's value per unit irradiance (`phase` its phase
    value), a point light's per unit intensity. only >= 0 (a directional light's beam refracted
    through face `only` of a refractive shape, geo holding minus its direction inside): 0 where the
    path back toward the light leaves through another face."""
    X0, X1, X2 = geo[0] + x * geo[3], geo[1] + x * geo[4], geo[2] + x * geo[5]
    if directional:
        k, face = exit_face(kind, planes, X0, X1, X2, geo[6], geo[7], geo[8])
        if only >= 0 and face != only:
            return 0.0
        return ks * phase * math.exp(-kt * (x + k))
    r0, r1, r2 = geo[6] - X0, geo[7] - X1, geo[8] - X2
    d2 = max(r0 * r0 + r1 * r1 + r2 * r2, 1e-250)
    d = math.sqrt(d2)
    f = falloff(-(r0 * geo[9] + r1 * geo[10] + r2 * geo[11]) / d, geo[12], geo[13], geo[17])  # leaving the light along -r
    if f == 0.0:
        return 0.0
    k = min(exit_face(kind, planes, X0, X1, X2, r0 / d, r1 / d, r2 / d)[0], d)
    mu = (r0 * geo[3] + r1 * geo[4] + r2 * geo[5]) / d  # the light travels along -r; the eye is along -w
    return ks * phase_value(code, g, mu) * f * math.exp(-kt * (x + k) - kt_out * (d - k)) / d2


@integrand_of(ConvexIntegrand)
@njit
def _convex_value(x, r):
    return convex_integrand(x, r.geo, r.kind, r.planes, r.directional, r.kt, r.ks, r.code, r.g, r.kt_out, r.phase,
                            r.only)


@njit
def straight_cuts(geo, end, out):
    """The distances in (0, end) along a segment (a `geo` row) where the straight line from a spot
    light crosses its cone's levels (lights.cone_breaks in v = tan(phi / 2), x = x_h + h (v - 1/v) / 2;
    A from h A = (r x w)·(w x a) as segment_light_table), ascending in out (>= 4); returns the count.
    0 for a point light or a light on the segment's line."""
    if not has_cone(geo[13]):
        return 0
    r0, r1, r2 = geo[6] - geo[0], geo[7] - geo[1], geo[8] - geo[2]
    w0, w1, w2 = geo[3], geo[4], geo[5]
    a0, a1, a2 = geo[9], geo[10], geo[11]
    xh = r0 * w0 + r1 * w1 + r2 * w2
    c0, c1, c2 = r1 * w2 - r2 * w1, r2 * w0 - r0 * w2, r0 * w1 - r1 * w0
    h = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
    if not h > 1e-12 * math.sqrt(r0 * r0 + r1 * r1 + r2 * r2):
        return 0
    u0, u1, u2 = w1 * a2 - w2 * a1, w2 * a0 - w0 * a2, w0 * a1 - w1 * a0
    A = (c0 * u0 + c1 * u1 + c2 * u2) / h
    B = w0 * a0 + w1 * a1 + w2 * a2
    m = 0
    for level in (geo[12], geo[13]):
        k, v1, v2 = cone_breaks(A, B, level)
        for i in range(k):
            v = v1 if i == 0 else v2
            x = xh + 0.5 * h * (v - 1.0 / v)
            if 0.0 < x < end:
                out[m] = x
                m += 1
        if geo[12] == geo[13]:
            break
    sort_few(out, 0, m)
    return m


@njit
def convex_quadrature(geo, planes, directional, ell, kt, ks, code, g, kt_out, phase, only, rtol, stats):
    """The value of `convex_bounded`."""
    return convex_bounded(geo, PLANES, planes, directional, ell, kt, ks, code, g, kt_out, phase, only, rtol,
                          NO_PLANE_ERROR, stats)[0]


NO_PLANE_ERROR = np.zeros(2)


@njit
def convex_bounded(geo, kind, planes, directional, ell, kt, ks, code, g, kt_out, phase, only, rtol, dplanes, stats):
    """(∫_0^ell `convex_integrand` dx, a bound on its error): adaptive (adaptive.bounded_piecewise) on
    the pieces between the kinks of the light's path inside, where the face it leaves through changes:
    a directional light's (convex_directional.envelope; with `only`, the pieces on other faces are 0),
    a point or spot light's (convex_chords.section_kinks), and a spot's cone crossings (`straight_cuts`).
    A kink inside a panel can fool the rules' agreement: one 1e-3 of the segment from its end was
    accepted 2e-7 off at any rtol, and a point light's kinks inside a 32-face sphere left 3e-9 at rtol
    1e-10. Inside an exact sphere (kind SPHERE, planes[0] its centre and radius) the path is smooth:
    only a spot's cone crossings cut it. The bound is the rule's (inf where a panel was accepted at a
    cap) plus the integrand's rounding (`directional_rounding`, `point_rounding`, with `dplanes` = (dn,
    dc) the planes' own errors against the shape's faces, on the normals and the offsets;
    `sphere_rounding`: eps relative at every node, so eps (value + rule) over each of the rule's
    20-point sums and the 10-point sums of its test; the integrand is positive), and the sum over the
    rule's intervals (u per interval)."""
    if ks == 0.0 or not ell > 0.0:
        return 0.0, 0.0
    rec = ConvexIntegrand(geo, kind, planes, directional, kt, ks, code, g, kt_out, phase, only)
    end = min(ell, 745.0 / kt)
    before = stats[INTERVALS]
    if kind == SPHERE:
        value, rule, eps = _sphere_rule(rec, end, rtol, stats)
    elif directional:
        value, rule, eps = _distant_rule(rec, end, rtol, dplanes, stats)
    else:
        value, rule, eps = _point_rule(rec, end, rtol, dplanes, stats)
    return _bounded(value, rule, eps, before, stats)


@njit
def _bounded(value, rule, eps, before, stats):
    """`convex_bounded`'s (value, bound) from the rule's bound, the integrand's relative rounding eps
    and the count of the rule's intervals since `before`."""
    return value, rule + (3.0 * eps + (stats[INTERVALS] - before) * U) * (value + rule)


@njit
def _sphere_rule(r, end, rtol, stats):
    """(value, the rule's bound, the integrand's rounding) of `convex_bounded` in an exact sphere."""
    br = np.empty(6)
    br[0] = 0.0
    m = 0 if r.directional else straight_cuts(r.geo, end, br[1:])
    br[m + 1] = end
    value, rule = bounded_piecewise(r, br, m + 2, rtol, N10, W10, N20, W20, stats)
    return value, rule, sphere_rounding(r.geo, r.planes[0], r.directional, end, r.kt, r.kt_out, r.code, r.g)


@njit
def _distant_rule(r, end, rtol, dplanes, stats):
    """The same for a directional light in a convex polyhedron."""
    geo, planes = r.geo, r.planes
    nf = planes.shape[0]
    cuts, lines, alpha, beta = np.empty(nf + 1), np.empty(nf, dtype=np.int64), np.empty(nf), np.empty(nf)
    m = envelope(planes[:, :3], planes[:, 3], geo[0:3], geo[3:6], geo[6:9], end, alpha, beta, cuts, lines)
    if m == 0:
        return 0.0, 0.0, 0.0  # no face toward the light: an infinite path inside (kt > 0)
    value, rule = bounded_piecewise(r, cuts, m + 1, rtol, N10, W10, N20, W20, stats)
    return value, rule, directional_rounding(geo, planes, end, r.kt, r.code, r.g, cuts, lines, alpha, beta, m, dplanes)


@njit
def _point_rule(r, end, rtol, dplanes, stats):
    """The same for a point or spot light in a convex polyhedron."""
    geo, planes = r.geo, r.planes
    br = np.empty(planes.shape[0] + 10)
    br[0] = 0.0
    m = straight_cuts(geo, end, br[1:])
    m += section_kinks(planes, 0, planes.shape[0], geo[0:3], geo[3:6], geo[6:9], end, br[1 + m:])
    sort_few(br, 1, m + 1)
    br[m + 1] = end
    value, rule = bounded_piecewise(r, br, m + 2, rtol, N10, W10, N20, W20, stats)
    return value, rule, point_rounding(geo, planes, end, r.kt, r.kt_out, r.code, r.g, dplanes)


@njit
def _straight(kind, planes, geo, directional, ell, kt, ks, code, g, kt_out, ph, only, dplanes, rule, key, dim0, seed,
              stats):
    """(value, variance, bound) of one inside segment of a convex index-matched shape (its boundary of
    `kind`) by the inside `rule` (media/inside_rule.py): QUAD `convex_bounded`, MARCH or SAMPLE
    `march_or_sample` of `convex_integrand` (bound inf)."""
    if rule.kind == QUAD:
        value, bound = convex_bounded(geo, kind, planes, directional, ell, kt, ks, code, g, kt_out, ph, only,
                                      rule.rtol, dplanes, stats)
        return value, 0.0, bound
    value, var = _straight_sampled(kind, planes, geo, directional, ell, kt, ks, code, g, kt_out, ph, only, rule, key,
                                   dim0, seed)
    return value, var, math.inf


@njit
def _straight_sampled(kind, planes, geo, directional, ell, kt, ks, code, g, kt_out, ph, only, rule, key, dim0, seed):
    """(value, variance) of `_straight`'s MARCH or SAMPLE."""
    rec = ConvexIntegrand(geo, kind, planes, directional, kt, ks, code, g, kt_out, ph, only)
    return march_or_sample(rec, rule, cut_length(rule, ell, kt), kt, key, dim0, seed)


@njit
def sphere_radiance(sphere, geo, directional, ell, kt, ks, code, g, kt_out, rule, keys, dim0, seed, out, var, err,
                    stats):
    """`inside_radiance` inside an index-matched exact sphere (centre, radius) for one light and
    channel (the inside `rule`: `_straight`): out, var and err per segment (geo: GEO_COLUMNS rows;
    a directional light's phase at the cosine between w and the direction toward it, geo[6:9])."""
    rows = sphere.reshape(1, 4)
    for s in range(ell.shape[0]):
        out[s], var[s], err[s] = 0.0, 0.0, 0.0
        if ks == 0.0 or not ell[s] > 0.0:
            continue
        ph = phase_value(code, g, geo[s, 3] * geo[s, 6] + geo[s, 4] * geo[s, 7] + geo[s, 5] * geo[s, 8])
        out[s], var[s], err[s] = _straight(SPHERE, rows, geo[s], directional, ell[s], kt, ks, code, g, kt_out, ph, -1,
                                           NO_PLANE_ERROR, rule, keys[s], dim0, seed, stats)


U = 2.0 ** -53  # unit roundoff of doubles


@njit
def phase_condition(code, g):
    """1 + max |d log Phi / d mu|: 1 + 3|g| / (1 - |g|)^2 bounds Henyey-Greenstein's, 2 the others
    (Rayleigh's 2|mu| / (1 + mu^2) <= 1)."""
    return 1.0 + (3.0 * abs(g) / (1.0 - abs(g)) ** 2 if g != 0.0 else 1.0)


@njit
def coordinate_size(geo, planes, end):
    """The size R of the coordinates along a segment (|o| + end) and the largest |c_f| of the planes."""
    r = math.sqrt(geo[0] * geo[0] + geo[1] * geo[1] + geo[2] * geo[2]) + end
    cmax = 0.0
    for f in range(planes.shape[0]):
        cmax = max(cmax, abs(planes[f, 3]))
    return r, cmax


@njit
def directional_rounding(geo, planes, end, kt, code, g, cuts, lines, alpha, beta, m, dplanes):
    """A bound on the relative rounding of `convex_integrand` for a directional light at every node of
    [0, end] (first order in u = 2^-53, doubled and more for the second-order terms), R = |o| + end:
    the light's path inside, k = (c_f - n_f·X) / q_f on the exit face f, off by 16u (|c_f| + R) / q_f (q_f
    its cosine to the face's normal, over the faces of the envelope's m pieces: cuts, lines, alpha, beta
    of convex_directional.envelope), and by (dc + dn (R + k)) / q_f where the planes themselves are
    dn, dc off the faces (`dplanes`), times kt; the exponent kt (x + k) rounded to 32u of its size and
    moved by the node's own rounding (16u R); the phase value (its cosine is fixed per segment) 8u times
    its condition."""
    r, _ = coordinate_size(geo, planes, end)
    dk, kmax = 0.0, 0.0
    for i in range(m):
        f = lines[i]
        q = planes[f, 0] * geo[6] + planes[f, 1] * geo[7] + planes[f, 2] * geo[8]
        kmax = max(kmax, alpha[f] + beta[f] * cuts[i], alpha[f] + beta[f] * cuts[i + 1])
        dk = max(dk, (16.0 * U * (abs(planes[f, 3]) + r) + dplanes[1] + dplanes[0] * (r + kmax)) / q)
    return _directional_eps(r, end, kmax, dk, kt, code, g)


@njit
def _directional_eps(r, end, kmax, dk, kt, code, g):
    """`directional_rounding` from the light path's largest length kmax and its error dk."""
    return 32.0 * U * (1.0 + kt * (end + kmax)) + kt * (dk + 16.0 * U * r) + 8.0 * U * phase_condition(code, g)


@njit
def point_rounding(geo, planes, end, kt, kt_out, code, g, dplanes):
    """`directional_rounding` for a point or spot light at p: the exit k = (c_f - n_f·X) / q_f with
    q_f = (h_f + s_f) / d >= h_f / D (h_f = n_f·p - c_f > 0 the light's height above the plane of a face
    it is outside of, s_f >= 0 the point's depth below it, D the light's largest distance from the
    segment) is off by 16u ((|c_f| + |p| + 2R) D / h_f + D) (the cosine's own rounding included), and by
    (dc + dn (R + D)) D / h_f where the planes are dn, dc off the faces (`dplanes`); the
    exponent kt (x + k) + kt_out (d - k) by 32u of its size and kt dk + kt_out (dk + dd) + kt 16u R; d
    by dd = 8u (|p| + R), which moves 1 / d^2 and the scattering cosine r·w / d relatively by dd / d_min
    times 2 + the phase's condition (d_min the light's least distance from the segment). A light inside
    every face plane, at depth g_f = c_f - n_f·p >= g below each: the exit along u = (p - X) / d is
    k_f = (c_f - n_f·X) / q_f = d + g_f / q_f >= d + g_f (q_f = n_f·u <= 1), so the computed exit, off by
    at most s / q_f with s = 16u (|c_f| + |p| + 2R + D) + dc + dn (R + D) (numerator and q_f's rounding,
    the planes' errors), stays beyond d where 4 s < g: then k = min(exit, d) = d itself (dk = dd); inf
    otherwise, and where the light lies on the segment."""
    r, cmax = coordinate_size(geo, planes, end)
    p, dmax, dmin = light_span(geo, end)
    hmin, depth = math.inf, math.inf
    for f in range(planes.shape[0]):
        hf = planes[f, 0] * geo[6] + planes[f, 1] * geo[7] + planes[f, 2] * geo[8] - planes[f, 3]
        if hf > 0.0:
            hmin = min(hmin, hf)
        else:
            depth = min(depth, -hf)
    if not dmin > 0.0:
        return math.inf
    if hmin == math.inf:  # the light inside
        slack = 16.0 * U * (cmax + p + 2.0 * r + dmax) + dplanes[1] + dplanes[0] * (r + dmax)
        if not 4.0 * slack < depth:
            return math.inf
        return _point_eps(r, p, dmax, dmin, 8.0 * U * (p + r), end, kt, kt_out, code, g)
    dk = 16.0 * U * ((cmax + p + 2.0 * r) * dmax / hmin + dmax) + (dplanes[1] + dplanes[0] * (r + dmax)) * dmax / hmin
    return _point_eps(r, p, dmax, dmin, dk, end, kt, kt_out, code, g)


@njit
def light_span(geo, end):
    """(|p|, D, d_min) of a point light p: its norm and its largest and least distance from the segment."""
    px, py, pz = geo[6], geo[7], geo[8]
    p = math.sqrt(px * px + py * py + pz * pz)
    d0x, d0y, d0z = px - geo[0], py - geo[1], pz - geo[2]
    d0 = math.sqrt(d0x * d0x + d0y * d0y + d0z * d0z)
    d1x, d1y, d1z = d0x - end * geo[3], d0y - end * geo[4], d0z - end * geo[5]
    d1 = math.sqrt(d1x * d1x + d1y * d1y + d1z * d1z)
    xh = d0x * geo[3] + d0y * geo[4] + d0z * geo[5]
    dmax, dmin = max(d0, d1), min(d0, d1)
    if 0.0 < xh < end:
        dmin = math.sqrt(max(d0 * d0 - xh * xh, 0.0))
    return p, dmax, dmin


@njit
def _point_eps(r, p, dmax, dmin, dk, end, kt, kt_out, code, g):
    """`point_rounding` from the light's span (`light_span`) and the error dk of the path inside."""
    dd = 8.0 * U * (p + r)
    return (32.0 * U * (1.0 + kt * (end + dmax) + kt_out * dmax) + kt * (dk + 16.0 * U * r) + kt_out * (dk + dd)
            + (2.0 + phase_condition(code, g)) * dd / dmin)


@njit
def _offset(cx, cy, cz, ox, oy, oz, ux, uy, uz):
    """|(o - c) x u| / |u|: the distance from c of the line through o along u."""
    fx, fy, fz = ox - cx, oy - cy, oz - cz
    ax, ay, az = fy * uz - fz * uy, fz * ux - fx * uz, fx * uy - fy * ux
    return math.sqrt(ax * ax + ay * ay + az * az) / math.sqrt(ux * ux + uy * uy + uz * uz)


@njit
def sphere_rounding(geo, sphere, directional, end, kt, kt_out, code, g):
    """`directional_rounding` and `point_rounding` inside the exact sphere (centre c, radius rho):
    the light's path inside is the far root k = -b + sqrt(b^2 + rho^2 - |f|^2) of sphere_roots from
    X = o + x w (f = X - c, b = f·u), whose inputs f, b and the line's offset h from c are off by
    delta = 16u (R + |c| + rho) (R = |o| + end) and whose discriminant (rho - h)(rho + h) and
    (|f| - rho)(|f| + rho) by e = 4 rho delta + 4 delta^2; the square root sqrt(rho^2 - h^2) (half
    the line's chord) then moves by e / s for s >= sqrt(e), and by at most sqrt(e) (where the line
    grazes the sphere, k <= 2 s), so k is off by dk = min(4 e / s_min, 10 sqrt(e)) + 4 delta + 32u rho,
    s_min^2 = rho^2 - h_max^2 - 2e with h_max the largest offset over the segment's light lines: a
    directional light's are parallel, |(f0 + x w) x l| convex in x, largest at an end; a point light
    L's pass through L, h = |c - L| sin(theta) with theta the angle at L between c and X, whose cosine
    (A + B x) / sqrt(C + 2 D x + x^2) (A = e·(o - L), B = e·w for the unit e toward c, C = |o - L|^2,
    D = (o - L)·w) is stationary only at x* = (A D - B C) / (B D - A): the largest at an end or x*.
    A light inside, at depth g = rho - |c - L|: the exit along u = (L - X) / d lies at least g beyond L,
    so where 4 dk < g the computed exit stays beyond it and k = min(exit, d) = d itself (dk = dd, as
    `point_rounding`'s light inside every face). inf otherwise, for a light on the sphere or on the segment."""
    cx, cy, cz, rho = sphere[0], sphere[1], sphere[2], sphere[3]
    r = math.sqrt(geo[0] * geo[0] + geo[1] * geo[1] + geo[2] * geo[2]) + end
    delta = 16.0 * U * (r + math.sqrt(cx * cx + cy * cy + cz * cz) + rho)
    e = 4.0 * rho * delta + 4.0 * delta * delta
    ends = (0.0, end, -1.0)
    lx, ly, lz = geo[6], geo[7], geo[8]
    dist = math.inf
    if not directional:
        ex, ey, ez = cx - geo[6], cy - geo[7], cz - geo[8]
        dist = math.sqrt(ex * ex + ey * ey + ez * ez)
        if not (dist > rho or dist < rho):
            return math.inf
        vx, vy, vz = geo[0] - geo[6], geo[1] - geo[7], geo[2] - geo[8]
        a = (ex * vx + ey * vy + ez * vz) / dist
        b = (ex * geo[3] + ey * geo[4] + ez * geo[5]) / dist
        c = vx * vx + vy * vy + vz * vz
        d = vx * geo[3] + vy * geo[4] + vz * geo[5]
        if b * d - a != 0.0:
            ends = (0.0, end, (a * d - b * c) / (b * d - a))
    hmax = 0.0
    for x in ends:
        if not 0.0 <= x <= end:
            continue
        px, py, pz = geo[0] + x * geo[3], geo[1] + x * geo[4], geo[2] + x * geo[5]
        if not directional:
            lx, ly, lz = px - geo[6], py - geo[7], pz - geo[8]
        hmax = max(hmax, _offset(cx, cy, cz, px, py, pz, lx, ly, lz))
    s2 = (rho - hmax) * (rho + hmax) - 2.0 * e
    dk = min(4.0 * e / math.sqrt(s2) if s2 > 0.0 else math.inf, 10.0 * math.sqrt(e)) + 4.0 * delta + 32.0 * U * rho
    if directional:
        return _directional_eps(r, end, 2.0 * rho, dk, kt, code, g)
    p, dmax, dmin = light_span(geo, end)
    if not dmin > 0.0:
        return math.inf
    if dist < rho:  # the light inside
        if not 4.0 * dk < rho - dist:
            return math.inf
        dk = 8.0 * U * (p + r)
    return _point_eps(r, p, dmax, dmin, dk, end, kt, kt_out, code, g)


@njit
def inside_integrand(directional, x, xh, h, hl, a, b, phase, kt, ks, code, g, kt_out, wl, ll, eta, spot):
    """The inside single-scattering integrand at depth x along the segment (module docstring): a
    directional light's ks Phi exp(-kt (x + a x / b)) per unit beam irradiance (`phase` its phase
    value), or a point light's eq. 7 integrand per unit intensity (`refracted_point` when eta != 1,
    with a spot's terms `spot`; the index-matched planar branch is for point lights only: spot lights
    in index-matched shapes take `convex_integrand` or interiors/paths.py)."""
    if directional:
        return ks * phase * math.exp(-kt * (x + a * x / b))
    if eta != 1.0:
        return refracted_point(x, wl, ll, a, hl, eta, kt, ks, code, g, kt_out, spot[0], spot[1], spot[2], spot[3],
                               spot[4], spot[5])
    dx = x - xh
    d2 = max(h * h + dx * dx, 1e-250)
    d = math.sqrt(d2)
    k = light_path_inside(x, d, 0.0, a, hl)
    return ks * phase_value(code, g, -dx / d) * math.exp(-kt * (x + k) - kt_out * (d - k)) / d2


class InsideIntegrand(NamedTuple):
    """`inside_integrand` in x (its arguments but x)."""
    directional: bool
    xh: float
    h: float
    hl: float
    a: float
    b: float
    phase: float
    kt: float
    ks: float
    code: int
    g: float
    kt_out: float
    wl: float
    ll: float
    eta: float
    spot: tuple


@integrand_of(InsideIntegrand)
@njit
def _inside_value(x, r):
    return inside_integrand(r.directional, x, r.xh, r.h, r.hl, r.a, r.b, r.phase, r.kt, r.ks, r.code, r.g, r.kt_out,
                            r.wl, r.ll, r.eta, r.spot)


def inside_radiance(directional, xh, h, hl, a, b, mu, ell, kt, ks, code, g, kt_out, wl, ll, eta, geo, planes, near,
                    dplanes, only, rule, keys, dim0, seed, out, var, err, stats):
    """Single scattering over inside segments (module docstring), one light each, unit light, per
    channel (kt, ks, kt_out: one each; out, var, err: (N, C)) by the method's inside `rule`
    (media/inside_rule.py): for a directional light (`directional`)
    per unit beam irradiance inside, with b the cosine of its refracted direction to the normal and mu
    the scattering cosine; for a point or spot light at height hl above the entry plane, kt_out the
    extinction outside (through a refractive plane, eta != 1: wl, ll of `refracted_point`). A light below
    the entry plane (hl <= 0, b <= 0) gives 0 (it does not enter through that plane).
    rule: QUAD (adaptive, the reference), MARCH (`steps` midpoints over the segment, cut where its
    optical depth reaches tau_max), SAMPLE (`steps` free-path samples x = -ln(1 - u (1 - e^{-kt ell})) / kt,
    u from the ray's key at dimensions dim0 + j; var gets the variance of the mean). geo: GEO_COLUMNS per
    segment (a spot's axis and cone there; NO_CONE for other lights). With `planes` (a convex shape, rows
    of `convex_exit_face`; else an empty array) the rule integrates `convex_integrand` (geo: its per-segment rows)
    instead: the exact straight path to every light outside, or with only >= 0 a directional light's
    beam refracted through that face (`convex_integrand`); a point or spot light in a refractive one
    (eta != 1): `faces_point`, its refracted paths through every face (`faces_quadrature` for QUAD,
    every channel at once: the faces' cull and breaks are the channels'), with only >= 0 through that
    face alone; `near` (int64): the planes' neighbours of interiors/shapes.py `plane_neighbours`
    there (`reachable_faces`; empty: every plane is tested). The closed forms through the entry plane
    are `plane_closed`'s.
    err: a bound on each value's error, known for QUAD in convex index-matched shapes (`convex_bounded`,
    `dplanes` the planes' own errors against the shape's faces), for QUAD's point and spot lights in
    convex refractive ones (`faces_quadrature`) and where the value is exactly 0 (no light, nothing to
    scatter); inf elsewhere.
    Each kind of segment has its own kernel below, compiled on first use: a scene compiles the
    integrands of the kinds it meets only."""
    _unlit(ell, ks, out, var, err)
    directional = np.asarray(directional, dtype=np.bool_)
    faces = eta != 1.0 and rule.kind == QUAD
    if faces and np.any((ell > 0.0) & ~directional):
        _faces_quad(np.flatnonzero((ell > 0.0) & ~directional), geo, planes, near, a, hl, wl, ll, only, ell, kt, ks,
                    code, g, kt_out, eta, rule.rtol, dplanes, out, err, stats)
    for c in range(kt.shape[0]):
        column = out[:, c].copy(), var[:, c].copy(), err[:, c].copy()
        live = _live(ell, ks[c])
        _channel_radiance(live & directional if faces else live, directional, xh, h, hl, a, b, mu, ell, float(kt[c]),
                          float(ks[c]), code, g, float(kt_out[c]), wl, ll, eta, geo, planes, near, dplanes, only,
                          rule, keys, dim0, seed, *column, stats)
        out[:, c], var[:, c], err[:, c] = column


def plane_closed(directional, xh, h, hl, a, b, mu, ell, kt, ks, code, g, kt_out, approximate, out, var, err):
    """`inside_radiance` by the analytic note's closed forms through the entry plane, for the methods that
    declare them (methods/ `Interiors`): a directional light's eq. 5 (`slab_distant`, exact for the planar
    boundary) and, with `approximate`, a point light's separable approximation (`point_approx`, the outside
    attenuation at the entry point; without it, 0); var 0, err inf where anything scatters."""
    _unlit(ell, ks, out, var, err)
    directional = np.asarray(directional, dtype=np.bool_)
    for c in range(kt.shape[0]):
        column = out[:, c].copy()
        live = _live(ell, ks[c]) & np.where(directional, ~(b <= 0.0), ~(hl <= 0.0))  # below the entry plane: 0
        kt_c, ks_c = float(kt[c]), float(ks[c])
        _each(_distant_closed, live & directional, mu, a, b, ell, kt_c, ks_c, code, g, column)
        if approximate:
            _each(_point_approx, live & ~directional, xh, h, hl, a, ell, kt_c, ks_c, code, g, float(kt_out[c]), column)
        out[:, c] = column


def _unlit(ell, ks, out, var, err):
    """out, var = 0; err inf where a segment has length and its channel scatters, else 0 (exact)."""
    out[:], var[:] = 0.0, 0.0
    err[:] = np.where((ell[:, None] > 0.0) & (ks[None, :] != 0.0), math.inf, 0.0)


def _live(ell, ks):
    """The segments that scatter in a channel of scattering coefficient ks."""
    return ell > 0.0 if ks != 0.0 else np.zeros(ell.shape, dtype=np.bool_)


def _each(kernel, which, *args):
    """`kernel` over the segments `which` selects, where there are any."""
    if np.any(which):
        kernel(np.flatnonzero(which), *args)


def _channel_radiance(live, directional, xh, h, hl, a, b, mu, ell, kt, ks, code, g, kt_out, wl, ll, eta, geo, planes,
                      near, dplanes, only, rule, keys, dim0, seed, out, var, err, stats):
    """`inside_radiance` of one channel over the segments `live` (out, var, err: (N,))."""
    convex, quad = planes.shape[0] > 0, rule.kind == QUAD
    if eta != 1.0 and convex and not quad:
        # a point or spot light through every face of a convex refractive shape
        _each(_faces_sampled, live & ~directional, geo, planes, near, a, hl, wl, ll, only, ell, kt, ks, code, g, kt_out,
              eta, rule, keys, dim0, seed, out, var)
        live &= directional
    if convex:
        if quad:
            for kernel, which in ((_convex_quad, live & ~directional), (_convex_distant_quad, live & directional)):
                _each(kernel, which, directional, mu, ell, kt, ks, code, g, kt_out, eta, geo, planes, dplanes, only,
                      rule.rtol, out, err, stats)
        else:
            _each(_convex_sampled, live, directional, mu, ell, kt, ks, code, g, kt_out, geo, planes, only, rule, keys,
                  dim0, seed, out, var)
        return
    live &= np.where(directional, ~(b <= 0.0), ~(hl <= 0.0))  # a light below the entry plane gives 0
    if quad:
        _each(_distant_quad, live & directional, mu, a, b, ell, kt, ks, code, g, rule.rtol, out, stats)
        _each(_point_quad, live & ~directional, xh, h, hl, a, ell, kt, ks, code, g, kt_out, rule.rtol, out, stats)
    else:
        _each(_plane_sampled, live, directional, xh, h, hl, a, b, mu, ell, kt, ks, code, g, kt_out, wl, ll, eta, geo,
              rule, keys, dim0, seed, out, var)


@njit
def spot_terms(geo, a, hl):
    """`refracted_point`'s spot terms of a segment's geo row (NO_SPOT for a light without a cone)."""
    if not has_cone(geo[13]):
        return NO_SPOT
    n0, n1, n2 = geo[14], geo[15], geo[16]
    na = n0 * geo[9] + n1 * geo[10] + n2 * geo[11]
    wa = geo[3] * geo[9] + geo[4] * geo[10] + geo[5] * geo[11] + a * na
    la = (geo[6] - geo[0]) * geo[9] + (geo[7] - geo[1]) * geo[10] + (geo[8] - geo[2]) * geo[11] - hl * na
    return (wa, la, na, geo[12], geo[13], geo[17])


@njit
def _faces(s, geo, planes, a, hl, wl, ll, only):
    """A point or spot light's `refracting_faces` rows for segment s (with only >= 0, that face's alone),
    their count and the spot's terms."""
    spot = spot_terms(geo[s], a[s], hl[s])
    faces = np.empty((max(planes.shape[0], 1), FACE_COLUMNS))
    m = refracting_faces(geo[s], planes, a[s], hl[s], wl[s], ll[s], spot, faces)
    if only >= 0:  # the path through face `only` alone
        m = only_face(faces, m, only)
    return faces, m, spot


@njit
def _reached(s, geo, planes, near, a, hl, wl, ll, only, eta, end):
    """`_faces` over [0, end] culled to the faces that can light segment s (`reachable_faces`): the
    rows, their count, the planes they refer to and the spot's terms."""
    faces, m, spot = _faces(s, geo, planes, a, hl, wl, ll, only)
    m, local = reachable_faces(faces, m, planes, near, eta, end, np.empty(m, np.int64))
    return faces, m, local, spot


EVERY = np.zeros(0, np.int64)  # `reachable_faces`' `near` that tests every plane (interiors/rows.py)
REACH_TOL = 1e-9  # relative margin of `reachable_faces`' plane tests (the face test's own is EDGE_TOL)
REACH_DEPTH = 7  # `reachable_faces` halves a segment down to 2^-7 of it


@njit
def _candidates(near, f, nf):
    """The planes `reachable_faces` tests for face f: its neighbours in `near` (interiors/crossing.py
    `plane_neighbours`), or every plane where `near` is empty."""
    if near.shape[0] == 0:
        return np.arange(nf)
    return near[near[f]:near[f + 1]]


@njit
def _beyond_span(row, planes, cand, f, eta, end):
    """Whether face row's refraction point lies beyond one of the planes `cand` for every x in [0, end]:
    R(x) = X_f + t (L_f - X_f) with X_f the foot of the point at x, L_f the light's and 0 <= t <=
    z / (z + eta hl) (sin t1 = eta sin t2 gives tan t1 >= eta tan t2, t1 the outside angle: (rho - r) / hl
    >= eta r / z), z <= z_max the point's depth: R lies in the quadrilateral of the feet of the segment's
    ends and their images at t = t_max, convex; beyond plane g by more than REACH_TOL of the scene's
    size at all four corners, it is beyond it everywhere."""
    z_max = max(row[0], row[0] + row[1] * end, 0.0)
    t = min(z_max / (z_max + eta * row[2]) * (1.0 + 1e-9), 1.0) if z_max > 0.0 else 0.0
    cx = np.empty((4, 3))
    for c in range(3):
        x0, x1 = row[8 + c], row[8 + c] + end * row[11 + c]
        cx[0, c], cx[1, c] = x0, x1
        cx[2, c], cx[3, c] = x0 + t * row[14 + c], x1 + t * (row[14 + c] - end * row[11 + c])
    size = 0.0
    for k in range(4):
        size = max(size, abs(cx[k, 0]) + abs(cx[k, 1]) + abs(cx[k, 2]))
    for g in cand:
        if g == f:
            continue
        margin = REACH_TOL * (abs(planes[g, 3]) + size)
        out = True
        for k in range(4):
            if planes[g, 0] * cx[k, 0] + planes[g, 1] * cx[k, 1] + planes[g, 2] * cx[k, 2] - planes[g, 3] <= margin:
                out = False
                break
        if out:
            return True
    return False


@njit
def reachable_faces(faces, m, planes, near, eta, end, ids):
    """The first m rows of `refracting_faces` culled, in place, to those whose refraction point can lie
    on their face for some x in [0, end], and the planes (`planes`' rows) they need; the rows' face
    numbers [17] renumbered into those planes: (count, planes). Face f's face is its plane's points
    inside the planes `near` lists for it (interiors/shapes.py `plane_neighbours`; every plane where
    `near` is empty): only these are read. A face whose refraction points all lie beyond one of them
    (`_beyond_span`) is dropped at once. Else over a piece [lo, hi] the refraction
    point R(x) stays within K (hi - lo) / 2 of R at the middle (K media/fermat_rounding.py
    `fermat_speed`, the bound on |R'| of `edge_breaks`): a piece whose disk lies beyond another plane g
    (n_g·R - c_g > that radius times `edge_tilt` + REACH_TOL of the scene's size at R, far beyond the face test's
    EDGE_TOL and R's rounding) is unlit through the face (g is kept, so that the face test reads it
    so), one whose disk lies inside every other plane
    is lit and needs none of them (no switch of `on_face`, no root in `edge_breaks` or `break_errors`);
    the others are halved, down to 2^-REACH_DEPTH of the segment, where the planes crossing their disk
    are needed. A face with every piece unlit is 0 over the segment and dropped; the kept faces'
    terms, breaks and bounds are those with every plane. For eta <= 1 (no speed bound) and without
    planes: as given. ids[:count]: the kept rows' faces in `planes`."""
    nf = planes.shape[0]
    for j in range(m):
        ids[j] = faces[j, 17]
    if nf == 0 or m == 0 or not end < math.inf or not eta > 1.0:
        return m, planes
    need = np.zeros(nf, np.bool_)
    stack = np.empty((REACH_DEPTH + 2, 3))
    kept = 0
    for j in range(m):
        row = faces[j]
        f = int(row[17])
        cand = _candidates(near, f, nf)
        if _beyond_span(row, planes, cand, f, eta, end):
            continue
        z0, a, hl, wl, ll = row[0], row[1], row[2], row[3], row[4]
        lit = False
        stack[0, 0], stack[0, 1], stack[0, 2] = 0.0, end, 0.0
        top = 1
        while top > 0:
            top -= 1
            lo, hi, depth = stack[top, 0], stack[top, 1], stack[top, 2]
            x = 0.5 * (lo + hi)
            rho, r = fermat(x, max(z0, 0.0), wl, ll, a, hl, eta)
            t = r / rho if rho > 0.0 else 0.0
            q0 = row[8] + x * row[11] + t * (row[14] - x * row[11])
            q1 = row[9] + x * row[12] + t * (row[15] - x * row[12])
            q2 = row[10] + x * row[13] + t * (row[16] - x * row[13])
            k = fermat_speed(_rho(lo, wl, ll, a), _rho(hi, wl, ll, a), max(min(z0 + a * lo, z0 + a * hi), 0.0), a,
                             eta)
            radius = 0.5 * k * (1.0 + 1e-9) * (hi - lo)
            size = abs(q0) + abs(q1) + abs(q2)
            beyond, crossing = False, False
            for g in cand:
                if g == f:
                    continue
                d = planes[g, 0] * q0 + planes[g, 1] * q1 + planes[g, 2] * q2 - planes[g, 3]
                margin = radius * edge_tilt(row, planes, g) + REACH_TOL * (abs(planes[g, 3]) + size)
                if d > margin:  # kept among the planes: the face test reads this piece unlit by it
                    beyond, need[g] = True, True
                    break
                crossing = crossing or d >= -margin
            if beyond:
                continue
            if crossing and depth < REACH_DEPTH:
                stack[top, 0], stack[top, 1], stack[top, 2] = x, hi, depth + 1
                stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2] = lo, x, depth + 1
                top += 2
                continue
            lit = True
            for g in cand if crossing else cand[:0]:  # an undecided piece: the planes crossing its disk
                d = planes[g, 0] * q0 + planes[g, 1] * q1 + planes[g, 2] * q2 - planes[g, 3]
                if g != f and abs(d) <= radius * edge_tilt(row, planes, g) + REACH_TOL * (abs(planes[g, 3]) + size):
                    need[g] = True
        if not lit:
            continue
        need[f] = True
        ids[kept] = f
        if kept != j:
            for c in range(FACE_COLUMNS):
                faces[kept, c] = faces[j, c]
        kept += 1
    index = np.cumsum(need) - 1
    local = np.empty((index[-1] + 1, 4))
    for g in range(nf):
        if need[g]:
            for c in range(4):
                local[index[g], c] = planes[g, c]
    for j in range(kept):
        faces[j, 17] = index[int(faces[j, 17])]
    return kept, local


@njit
def segment_reach(geo, planes, near, eta, ell, out):
    """out[s, f] = True where face f of a convex refractive shape may light segment s over [0, ell[s]]
    (geo rows of GEO_COLUMNS without an entry normal: every face's row from `planes`), its refraction
    point on the face (`reachable_faces`, `near` its planes' neighbours)."""
    faces = np.empty((max(planes.shape[0], 1), FACE_COLUMNS))
    ids = np.empty(planes.shape[0], np.int64)
    for s in range(geo.shape[0]):
        m = refracting_faces(geo[s], planes, 0.0, 0.0, 0.0, 0.0, NO_SPOT, faces)
        m, _ = reachable_faces(faces, m, planes, near, eta, ell[s], ids)
        for j in range(m):
            out[s, ids[j]] = True


@njit
def _faces_quad(sel, geo, planes, near, a, hl, wl, ll, only, ell, kt, ks, code, g, kt_out, eta, rtol, dplanes, out,
                err, stats):
    """`inside_radiance`'s point or spot light in a refractive shape, QUAD, every channel at once (kt, ks,
    kt_out: one each; out, err: (N, C)): `faces_quadrature`, its bound; with several faces (eta > 1),
    each face's integral over the planes it needs alone (`reachable_faces` of its row alone, the same
    decisions as with the others: the same face test, breaks and bound as with every plane), summed,
    their bounds summed with the sum's rounding (u per term). The channels whose integrals end at the
    same x (min(ell, 745 / kt)) share the faces, their cull and their breaks (none reads the channel's
    coefficients); those with ks = 0 are 0, exactly."""
    row, one = np.empty((1, FACE_COLUMNS)), np.empty(1, np.int64)
    nc = kt.shape[0]
    ends = np.empty(nc)
    for s in sel:
        for c in range(nc):
            ends[c] = min(ell[s], 745.0 / kt[c]) if ks[c] != 0.0 else -1.0
        for c0 in range(nc):
            end = ends[c0]
            if end < 0.0 or np.any(ends[:c0] == end):
                continue
            chans = np.flatnonzero(ends == end)
            kts, kss, kos = kt[chans], ks[chans], kt_out[chans]
            value, bound = np.empty(len(chans)), np.empty(len(chans))
            faces, m, spot = _faces(s, geo, planes, a, hl, wl, ll, only)
            ids = np.empty(m, np.int64)
            m, local = reachable_faces(faces, m, planes, near, eta, end, ids)
            r, cmax = coordinate_size(geo[s], planes, end)
            p, ln, lp = light_norms(geo[s])
            mags = (p, ln, lp, r + ln + cmax)
            left = _left_out(s, geo, planes, a, hl, wl, ll, only, end, kss, code, g, eta, dplanes, mags)
            for k, c in enumerate(chans):
                err[s, c] = left[k]
            if m == 0:
                continue
            if m == 1 or not eta > 1.0:
                faces_quadrature(faces[:m], local, ell[s], end, kts, kss, code, g, kos, eta, spot[3:], rtol, dplanes,
                                 mags, entry_face(geo[s], local), stats, value, bound)
                for k, c in enumerate(chans):
                    out[s, c], err[s, c] = value[k], bound[k] + left[k]
                continue
            total, bounds = np.zeros(len(chans)), np.zeros(len(chans))
            for j in range(m):  # each face over its own planes: their sum is the integral over all
                for c in range(FACE_COLUMNS):
                    row[0, c] = faces[j, c]
                row[0, 17] = ids[j]  # the same cull of this row alone: the planes it needs
                own = reachable_faces(row, 1, planes, near, eta, end, one)[1]
                faces_quadrature(row, own, ell[s], end, kts, kss, code, g, kos, eta, spot[3:], rtol, dplanes, mags,
                                 entry_face(geo[s], own), stats, value, bound)
                total += value
                bounds += bound
            for k, c in enumerate(chans):
                out[s, c], err[s, c] = total[k], bounds[k] + m * U * (total[k] + bounds[k]) + left[k]


@njit
def _left_out(s, geo, planes, a, hl, wl, ll, only, end, ks, code, g, eta, dplanes, mags):
    """Per channel (ks: one each), the sum of `grazing_bound` over the faces of segment s that
    `refracting_faces` leaves out (the light's computed height above the face's plane hl <= 0) while
    the exact height may be positive (hl > -(dc + sqrt(3) dn |L| + 32u S), `grazing_bound`'s error of
    hl); with only >= 0, face `only` alone. 0 without planes (the entry plane alone: the light's height
    above it is the row's own)."""
    out = np.zeros(ks.shape[0])
    floor = -(dplanes[1] + SQ3 * dplanes[0] * mags[1] + 32.0 * U * mags[3])
    near = floor < hl[s] <= 0.0  # the entry face's (the others' rows below)
    for f in range(planes.shape[0]):
        hf = planes[f, 0] * geo[s, 6] + planes[f, 1] * geo[s, 7] + planes[f, 2] * geo[s, 8] - planes[f, 3]
        near = near or floor < hf <= 0.0
    if planes.shape[0] == 0 or not near:
        return out
    spot = spot_terms(geo[s], a[s], hl[s])
    faces = np.empty((planes.shape[0], FACE_COLUMNS))
    m = refracting_faces(geo[s], planes, a[s], hl[s], wl[s], ll[s], spot, faces, floor)
    if only >= 0:
        m = only_face(faces, m, only)
    for j in range(m):
        row = faces[j]
        if not row[2] > 0.0:
            for c in range(ks.shape[0]):
                out[c] += grazing_bound(row[0], row[1], row[2], row[3], row[4], end, ks[c], code, g, eta, dplanes,
                                        mags)
    return out


@njit
def light_norms(geo):
    """|p|, |L| and |L - p| of a point or spot light's geo row."""
    p = math.sqrt(geo[0] * geo[0] + geo[1] * geo[1] + geo[2] * geo[2])
    ln = math.sqrt(geo[6] * geo[6] + geo[7] * geo[7] + geo[8] * geo[8])
    lp = math.sqrt((geo[6] - geo[0]) ** 2 + (geo[7] - geo[1]) ** 2 + (geo[8] - geo[2]) ** 2)
    return p, ln, lp


@njit
def _faces_sampled(sel, geo, planes, near, a, hl, wl, ll, only, ell, kt, ks, code, g, kt_out, eta, rule, keys, dim0,
                   seed, out, var):
    """The same, MARCH or SAMPLE: `march_or_sample` of `faces_point`."""
    for s in sel:
        length = cut_length(rule, ell[s], kt)
        faces, m, local, spot = _reached(s, geo, planes, near, a, hl, wl, ll, only, eta, length)
        if m > 0:
            rec = FacesPoint(faces[:m], local, eta, kt, ks, code, g, kt_out, spot[3:], 0.0, 0.0, 0.0,
                             (0.0, 0.0, 0.0, 0.0), -1, np.zeros(0))
            out[s], var[s] = march_or_sample(rec, rule, length, kt, keys[s], dim0, seed)


@njit
def _convex_quad(sel, directional, mu, ell, kt, ks, code, g, kt_out, eta, geo, planes, dplanes, only, rtol, out, err,
                 stats):
    """`inside_radiance` in a convex polyhedron along a point or spot light's exact straight path, QUAD:
    `convex_bounded` (its bound where the shape is index-matched)."""
    for s in sel:
        rec, end, before = _convex_start(s, directional, mu, ell, kt, ks, code, g, kt_out, geo, planes, only, stats)
        _convex_store(s, _point_rule(rec, end, rtol, dplanes, stats), eta, before, out, err, stats)


@njit
def _convex_distant_quad(sel, directional, mu, ell, kt, ks, code, g, kt_out, eta, geo, planes, dplanes, only, rtol, out,
                         err, stats):
    """The same for a directional light."""
    for s in sel:
        rec, end, before = _convex_start(s, directional, mu, ell, kt, ks, code, g, kt_out, geo, planes, only, stats)
        _convex_store(s, _distant_rule(rec, end, rtol, dplanes, stats), eta, before, out, err, stats)


@njit
def _convex_start(s, directional, mu, ell, kt, ks, code, g, kt_out, geo, planes, only, stats):
    """Segment s's `convex_bounded` record, the end of its integral and the rule's intervals so far."""
    ph = phase_value(code, g, mu[s]) if directional[s] else 0.0
    return (ConvexIntegrand(geo[s], PLANES, planes, directional[s], kt, ks, code, g, kt_out, ph, only),
            min(ell[s], 745.0 / kt), stats[INTERVALS])


@njit
def _convex_store(s, found, eta, before, out, err, stats):
    """Segment s's value and, in an index-matched shape, its bound from a rule's (value, bound, rounding)
    (a refracted beam's, err untouched: the irradiance's and the face test's rounding are not analysed
    here; interiors/rows.py bounds it against the beam's closed form)."""
    out[s], bound = _bounded(found[0], found[1], found[2], before, stats)
    if eta == 1.0:
        err[s] = bound


@njit
def _convex_sampled(sel, directional, mu, ell, kt, ks, code, g, kt_out, geo, planes, only, rule, keys, dim0, seed, out,
                    var):
    """The same, MARCH or SAMPLE: `march_or_sample` of `convex_integrand`."""
    for s in sel:
        ph = phase_value(code, g, mu[s]) if directional[s] else 0.0
        out[s], var[s] = _straight_sampled(PLANES, planes, geo[s], directional[s], ell[s], kt, ks, code, g, kt_out, ph,
                                           only, rule, keys[s], dim0, seed)


@njit
def _plane_sampled(sel, directional, xh, h, hl, a, b, mu, ell, kt, ks, code, g, kt_out, wl, ll, eta, geo, rule, keys,
                   dim0, seed, out, var):
    """`inside_radiance` through the entry plane, MARCH or SAMPLE: `march_or_sample` of `inside_integrand`."""
    for s in sel:
        ph = phase_value(code, g, mu[s]) if directional[s] else 0.0
        spot = spot_terms(geo[s], a[s], hl[s]) if eta != 1.0 and not directional[s] else NO_SPOT
        rec = InsideIntegrand(directional[s], xh[s], h[s], hl[s], a[s], b[s], ph, kt, ks, code, g, kt_out, wl[s],
                              ll[s], eta, spot)
        out[s], var[s] = march_or_sample(rec, rule, cut_length(rule, ell[s], kt), kt, keys[s], dim0, seed)


@njit
def _distant_quad(sel, mu, a, b, ell, kt, ks, code, g, rtol, out, stats):
    """`inside_radiance`'s directional light through the entry plane, QUAD: `distant_quadrature`."""
    for s in sel:
        out[s] = distant_quadrature(kt, ks, phase_value(code, g, mu[s]), a[s], b[s], ell[s], rtol, stats)


@njit
def _distant_closed(sel, mu, a, b, ell, kt, ks, code, g, out):
    """`plane_closed`'s directional light: eq. 5 (`slab_distant`)."""
    for s in sel:
        out[s] = slab_distant(kt, ks, phase_value(code, g, mu[s]), a[s] / b[s], ell[s])


@njit
def _point_quad(sel, xh, h, hl, a, ell, kt, ks, code, g, kt_out, rtol, out, stats):
    """`inside_radiance`'s point light through an index-matched entry plane, QUAD: `point_exact`."""
    for s in sel:
        out[s] = point_exact(xh[s], h[s], ell[s], kt, ks, code, g, 0.0, a[s], hl[s], kt_out, rtol, stats)


@njit
def _point_approx(sel, xh, h, hl, a, ell, kt, ks, code, g, kt_out, out):
    """`plane_closed`'s point light: the note's approximation (`point_approx`) with the outside attenuation at the
    entry point."""
    for s in sel:
        da = math.sqrt(h[s] * h[s] + xh[s] * xh[s])
        out[s] = point_approx(xh[s], h[s], ell[s], kt, ks, code, g, a[s], hl[s] / da) * math.exp(-kt_out * da)


@njit
def only_face(faces, m, f):
    """Keep the row of face f among the first m rows of `refracting_faces` (moved first); their count."""
    for j in range(m):
        if faces[j, 17] == f:
            for k in range(FACE_COLUMNS):  # by element: a row assignment compiles numba's shape-mismatch message (2 s)
                faces[0, k] = faces[j, k]
            return 1
    return 0


@njit
def refract_rays(d, n, eta, out, cos_t):
    """`refract` of every row of d (N, 3) through the facing normals n (N, 3): out (N, 3), cos_t (N,)."""
    for i in range(d.shape[0]):
        out[i, 0], out[i, 1], out[i, 2], cos_t[i] = refract(d[i, 0], d[i, 1], d[i, 2], n[i, 0], n[i, 1], n[i, 2], eta)


@njit
def transmittances(cos_i, eta, out):
    """1 - `fresnel` of every cosine."""
    for i in range(cos_i.shape[0]):
        out[i] = 1.0 - fresnel(cos_i[i], eta)


@njit
def surface_through_faces(q, planes, light, axis, cone, eta, value, toward, inside, outside):
    """A unit point or spot light (position `light`, `axis`, cone = cos_end, cos_start, curve) at the
    points q (M, 3) inside a convex refractive shape ({x : n_f·x <= c_f}, `planes` (F, 4)), through
    each face f it is outside of (`refracting_faces`; Fermat's path with its refraction point on the
    face, `on_face`): the irradiance across the refracted beam times the spot's falloff on the
    direction the light leaves in (`refracted_at` at x = 0 with its attenuation left out) in
    value[:, f], 0 where no such path; the unit direction from q toward the refraction point in
    toward[:, f], the path's lengths inside and outside in inside[:, f] and outside[:, f]."""
    _surface_faces(q, planes, planes, light, axis, cone, eta, False, value, toward, inside, outside)


@njit
def _piece_mags(p, length, planes):
    """`faces_quadrature`'s mags of a piece of a segment from p of that length lit from inside: (|p|, |L|,
    |L - p|, |p| + length + |L| + the largest |c_f|), L = p[6:9]."""
    pn = math.sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2])
    ln = math.sqrt(p[6] * p[6] + p[7] * p[7] + p[8] * p[8])
    lp = math.sqrt((p[6] - p[0]) ** 2 + (p[7] - p[1]) ** 2 + (p[8] - p[2]) ** 2)
    return pn, ln, lp, pn + length + ln + np.max(np.abs(planes[:, 3]))


@njit
def _end_moved(row, plane, x, dplanes):
    """How far an end x of `out_of_faces`' piece of the segment (geo row) beyond a face's plane, set by that plane
    (the crossing -depth / rate), may lie from the exact one's: depth off by dc + sqrt(3) dn |o| + 8u (|c| + |o|)
    and rate by sqrt(3) dn + 4u, so x by (that + x (sqrt(3) dn + 4u)) / |rate| + 4u x; doubled. The piece's value
    moves by at most this times the term's bound there (`leaving_envelope`), its transmittance exp(-kt lo) by kt
    times it."""
    on = math.sqrt(row[0] * row[0] + row[1] * row[1] + row[2] * row[2])
    rate = abs(plane[0] * row[3] + plane[1] * row[4] + plane[2] * row[5])
    dd = dplanes[1] + SQ3 * dplanes[0] * on + 8.0 * U * (abs(plane[3]) + on)
    if not rate > 0.0:
        return math.inf
    return 2.0 * ((dd + x * (SQ3 * dplanes[0] + 4.0 * U)) / rate + 4.0 * U * x)


@njit
def surface_out_of_faces(q, planes, light, axis, cone, eta, value, toward, inside, outside):
    """`surface_through_faces` reversed: a unit point or spot light inside the convex refractive shape
    (relative index eta inside) at the points q (M, 3) outside it, through each face f whose plane q is
    outside of: the same Fermat path (its refraction point on the face), now from the light's side of
    index eta to q's of index 1 (`refracted_at` with the plane's normal turned toward the light and
    relative index 1 / eta: Snell's sin1 = sin2 / eta, Fresnel's T the same on either side, and the ray
    tube's irradiance E = T sin1 / (rho cos2 (hl / cos1^2 + z eta cos1 / cos2^3)), hl the light's depth
    below the face's plane and z q's height above it; below the light T / (hl + eta z)^2; total internal
    reflection never lies on Fermat's path, whose leaving angle obeys sin1 = sin2 / eta <= 1 / eta). The
    path's lengths inside (the light's leg) in inside[:, f], outside (q's leg) in outside[:, f]."""
    _surface_faces(q, -planes, planes, light, axis, cone, 1.0 / eta, True, value, toward, outside, inside)


@njit
def _surface_faces(q, toward_light, planes, light, axis, cone, eta, beyond, value, toward, near, far):
    """`surface_through_faces` over the faces whose plane (rows of `toward_light`: `planes` with their
    normals toward the light's side) the light is outside of (`beyond`: and q is not), relative index
    eta on q's side: q's leg in near[:, f], the light's in far[:, f]."""
    geo = np.zeros(GEO_COLUMNS)
    geo[3] = 1.0  # a direction along which x = 0 is taken (the terms that depend on it drop out there)
    geo[6:9], geo[9:12], geo[12:14], geo[17] = light, axis, cone[:2], cone[2]
    faces = np.empty((max(planes.shape[0], 1), FACE_COLUMNS))
    value[:] = 0.0
    for i in range(q.shape[0]):
        geo[0:3] = q[i]
        for j in range(refracting_faces(geo, toward_light, 0.0, 0.0, 0.0, 0.0, NO_SPOT, faces)):
            row = faces[j]
            f = int(row[17])
            if beyond and toward_light[f, 0] * q[i, 0] + toward_light[f, 1] * q[i, 1] + toward_light[f, 2] * q[i, 2] \
                    > toward_light[f, 3]:
                continue  # q on the light's side of the face's plane
            rho, r = fermat(0.0, row[0], row[3], row[4], row[1], row[2], eta)
            if not on_face(0.0, row, r, rho, planes):
                continue
            t = r / rho if rho > 0.0 else 0.0
            k = 0.0
            for c in range(3):
                toward[i, f, c] = row[8 + c] + t * row[14 + c] - q[i, c]
                k += toward[i, f, c] * toward[i, f, c]
            k = math.sqrt(k)
            for c in range(3):  # on the face itself (k = 0): its normal toward the light's side
                toward[i, f, c] = toward[i, f, c] / k if k > 0.0 else toward_light[f, c]
            near[i, f] = k
            far[i, f] = math.sqrt((rho - r) * (rho - r) + row[2] * row[2])
            value[i, f] = 4.0 * math.pi * refracted_at(0.0, row[0], rho, r, row[3], row[1], row[2], eta, 0.0, 1.0,
                                                       ISOTROPIC, 0.0, 0.0, row[5], row[6], row[7], cone[0], cone[1],
                                                       cone[2])


@njit
def face_part(geo, plane, ell):
    """(lo, hi) of the part of the segment [0, ell] (geo row) beyond the plane (n·q > c); hi <= lo: none."""
    depth = plane[0] * geo[0] + plane[1] * geo[1] + plane[2] * geo[2] - plane[3]
    rate = plane[0] * geo[3] + plane[1] * geo[4] + plane[2] * geo[5]
    lo, hi = 0.0, ell
    if rate > 0.0:
        lo = max(lo, -depth / rate)
    elif rate < 0.0:
        hi = min(hi, depth / -rate)
    elif not depth > 0.0:
        hi = lo
    return lo, hi


@njit
def leaving_row(geo, x, toward, f, start, rows):
    """Face f's row (rows[0], `refracting_faces` of the planes `toward`: a convex shape's with their normals
    toward the light inside) along the segment of the geo row from its point at x (start: that row,
    GEO_COLUMNS); returns 1, or 0 where the light is not inside f's plane."""
    for c in range(GEO_COLUMNS):
        start[c] = geo[c]
    for c in range(3):
        start[c] = geo[c] + x * geo[3 + c]
    return only_face(rows, refracting_faces(start, toward, 0.0, 0.0, 0.0, 0.0, NO_SPOT, rows), f)


class LitFaces(NamedTuple):
    """`faces_point` in x (no track) on its segment's lit pieces only: 0 but where lit[i] > 0 on [ends[i],
    ends[i + 1]) (media/mesh_lamp_shadows.py `face_pieces`)."""
    faces: np.ndarray
    planes: np.ndarray
    eta: float
    kt: float
    ks: float
    code: int
    g: float
    kt_out: float
    spot: tuple
    ends: np.ndarray
    lit: np.ndarray


@integrand_of(LitFaces)
@njit
def _lit_faces_value(x, r):
    i = 1
    while i < r.ends.shape[0] - 1 and r.ends[i] <= x:
        i += 1
    if not r.lit[i - 1] > 0.0:
        return 0.0
    sp = r.spot
    return faces_point(x, r.faces, r.planes, r.eta, r.kt, r.ks, r.code, r.g, r.kt_out, sp[0], sp[1], sp[2])


@njit
def out_of_faces(geo, planes, ell, kt, ks, code, g, kt_out, eta, rule, keys, dim0, seed, out, var, err, stats,
                 dplanes=None, shadows=None):
    """The outside medium's single scattering (N, C) over segments outside a convex refractive shape ({q :
    n_f·q <= c_f}, `planes`) from a unit point or spot light inside it (geo rows of GEO_COLUMNS, no entry
    normal; kt, ks: the outside's, kt_out the inside's, one each per channel; eta = 1 / the shape's ior):
    `surface_out_of_faces`' path along each segment, each face f over the part [lo, hi] of [0, ell] beyond its
    plane (`face_part`), its row from the segment's point at lo (`leaving_row`), times exp(-kt lo). With
    `shadows` (start, ends, flags, proven of media/mesh_lamp_shadows.py `face_pieces`: the pieces of each face's
    part, relative to lo, that other shapes leave lit, LIT, DARK or UNDECIDED), only the lit pieces count.
    QUAD: `faces_quadrature` per face and lit piece, its row from the piece's start (its breaks: the refraction
    point's edge crossings and a spot's cone crossings, isolated with `_speed`'s eta < 1 bound; its bound with
    the planes' errors dplanes (interiors/shapes.py `measured_plane_errors`; None: inf), plus `_end_moved` where
    a piece ends on a face's plane, plus per undecided piece (counted dark) its length times twice the larger of
    its ends' unshadowed values, as media/sphere_refraction.py `out_of_sphere`; inf where a face's scan was not
    proven); MARCH, SAMPLE: `march_or_sample` per face and channel at dimensions dim0 + f STREAM (of `LitFaces`
    with shadows), their variances summed (independent streams)."""
    nf, nc = planes.shape[0], kt.shape[0]
    toward = -planes
    rows = np.empty((max(nf, 1), FACE_COLUMNS))
    start = np.empty(GEO_COLUMNS)
    value, bound = np.empty(nc), np.empty(nc)
    whole = np.ones(1)  # one lit piece (flags as media/globe_shadows.py's: > 0 lit, 0 dark, < 0 undecided)
    for s in range(geo.shape[0]):
        out[s, :], var[s, :], err[s, :] = 0.0, 0.0, 0.0
        for f in range(nf):
            lo, hi = face_part(geo[s], planes[f], ell[s])
            if not hi > lo or leaving_row(geo[s], lo, toward, f, start, rows) == 0:
                continue
            row = rows[:1].copy()
            spot = (start[12], start[13], start[17])
            ends, lit = np.array([0.0, hi - lo]), whole
            if shadows is not None:
                k = s * nf + f
                ends, lit = shadows[1][shadows[0][k]:shadows[0][k + 1]], shadows[2][shadows[0][k] - k:
                                                                                   shadows[0][k + 1] - k - 1]
            if rule.kind == QUAD:
                _faces_pieces(geo[s], planes, toward, f, lo, hi, ell[s], row, ends, lit, kt, ks, code, g, kt_out, eta,
                              spot, rule.rtol, dplanes, start, rows, out[s], err[s], stats, value, bound)
                if shadows is not None and not shadows[3][s * nf + f]:
                    err[s, :] = math.inf
                continue
            for c in range(nc):
                if ks[c] == 0.0:
                    continue
                rec = LitFaces(row, planes, eta, kt[c], ks[c], code, g, kt_out[c], spot, ends, lit)
                v, vv = march_or_sample(rec, rule, cut_length(rule, hi - lo, kt[c]), kt[c], keys[s],
                                        dim0 + np.uint64(f) * np.uint64(STREAM), seed)
                t = math.exp(-kt[c] * lo)
                out[s, c] += v * t
                var[s, c] += vv * t * t
                err[s, c] = math.inf


@njit
def _faces_pieces(geo, planes, toward, f, lo, hi, ell, row, ends, lit, kt, ks, code, g, kt_out, eta, spot, rtol,
                  dplanes, start, rows, out, err, stats, value, bound):
    """`out_of_faces`' QUAD over face f's part [lo, hi] of the segment (geo row; row: its face row from lo), on its
    pieces between ends (relative to lo) flagged lit: added into out and err (C,)."""
    errs = np.zeros(2) if dplanes is None else dplanes
    for i in range(lit.shape[0]):
        a, b = ends[i], ends[i + 1]
        if not b > a:
            continue
        if lit[i] < 0.0:  # undecided: dark, its length times twice its ends' larger value in the bound
            for c in range(kt.shape[0]):
                if ks[c] != 0.0:
                    most = max(faces_point(a, row, planes, eta, kt[c], ks[c], code, g, kt_out[c], spot[0], spot[1],
                                           spot[2]),
                               faces_point(b, row, planes, eta, kt[c], ks[c], code, g, kt_out[c], spot[0], spot[1],
                                           spot[2]))
                    err[c] += 2.0 * most * (b - a) * math.exp(-kt[c] * lo)
            continue
        if not lit[i] > 0.0:
            continue
        piece = row
        if a > 0.0:  # (a == 0: start is the row at lo, `out_of_faces`')
            if leaving_row(geo, lo + a, toward, f, start, rows) == 0:
                continue
            piece = rows[:1].copy()
        p_lo, p_hi = lo + a, (hi if b == hi - lo else lo + b)
        mags = (0.0, 0.0, 0.0, 0.0) if dplanes is None else _piece_mags(start, b - a, planes)
        for c in range(kt.shape[0]):
            if ks[c] == 0.0:
                continue
            faces_quadrature(piece, planes, b - a, min(b - a, 745.0 / kt[c]), kt[c:c + 1], ks[c:c + 1], code, g,
                             kt_out[c:c + 1], eta, spot, rtol, errs, mags, -1, stats, value[:1], bound[:1])
            t = math.exp(-kt[c] * p_lo)
            out[c] += value[0] * t
            if dplanes is None:
                err[c] = math.inf
                continue
            m_lo = _end_moved(geo, planes[f], p_lo, dplanes) if a == 0.0 and lo > 0.0 else 0.0
            m_hi = _end_moved(geo, planes[f], p_hi, dplanes) if b == hi - lo and hi < ell else 0.0
            err[c] += (bound[0] + value[0] * (kt[c] * m_lo + 8.0 * U * (1.0 + kt[c] * p_lo))) * t
            for x, moved in ((0.0, m_lo), (b - a, m_hi)):
                if moved > 0.0:
                    err[c] += moved * leaving_envelope(x, piece[0], moved, ks[c], code, g, eta, errs[0], errs[1], mags,
                                                       False)

