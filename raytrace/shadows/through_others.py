"""The light of a point, spot or directional light inside a convex index-matched shape (and of the
sun's refracted beams inside a convex refractive one), attenuated by the other index-matched
interiors its straight path crosses on the way out.

Inside shape A the single-scattering integrand of media/slab.py `convex_integrand` carries the
outside's extinction kt_out over the light's path outside A. Where that path crosses another
index-matched convex shape B_j (chord c_j, media/convex_chords.py `chord`), the light is attenuated
by B_j's extinction instead over c_j: the integrand times exp(-sum_j (kt_j - kt_out) c_j) (A and the
B_j do not overlap, so c_j is B_j's chord of the whole path from the point to the light). The
chords change slope where the path toward the light passes a vertex of the polygon the plane through
the segment and the light cuts from B_j (`section_kinks`), so `quadrature` starts its adaptive rule
from those points as well as A's own kinks and a spot's cone crossings; `raymarch` and `montecarlo`
evaluate the same integrand with their own rules (media/inside_rule.py `march_or_sample`).

A directional light (geo's light columns: the unit direction u toward it) takes the path X + s u,
s >= 0, and the integrand ks Phi(w·u) exp(-kt (x + k)) (the outside medium does not attenuate it:
media/slab.py) times exp(-sum_j kt_j c_j) (dk[j] = kt_j: the light crosses B_j instead of nothing).
All its paths lie in the plane through the segment along u, and c_j changes slope where the path
passes a vertex of the polygon that plane cuts from B_j (`section_kinks(..., directional=True)`),
A's own path where it passes one of A's.

Inside a convex refractive shape A, the directional light's beam refracted through face f (`only`,
geo[6:9] minus its direction inside, `sun` the unit direction toward the sun outside) reaches X
where X's path back leaves through f, at the entry point P = X + k toward; outside, the light runs
from P along the sun's direction, so the chords are those of P + s sun. Where the path leaves
through f, P runs along a line of f's plane as X runs along the segment (k is linear in x), so the
chords' kinks are `section_kinks(..., directional=True)` of that line (`_beam_kinks`).

QUAD bounds its integrals (docs/error_bounds.md): its rule's bound plus the integrand's relative
rounding over its sums, as media/slab.py `convex_bounded`, that rounding media/slab.py
`directional_rounding` or `point_rounding` of A's path plus sum_j |dk_j| (dc_j + 16u C_j) + 4u
(`chord_rounding` along the sun, from a beam's entry point with its error dP added to the planes'
offsets, `_entry_line`; `point_chord_rounding` toward a point or spot light: c_j off by dc_j, at
most C_j; the exponent's sum and exp). MARCH and SAMPLE are not bounded (inf).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..jit import njit
from ..media.convex_chords import PLANES, chord, section_kinks
from ..media.integrand import integrand_of
from ..media.phase import phase_value
from ..media.adaptive import INTERVALS, bounded_piecewise
from ..media.convex_directional import envelope
from .fermat_legs import _OUT_EDGE, RESOLUTION, ROUNDING, _cross, _norm, _push, _refraction, _roots
from ..media.fermat_rounding import point_error
from ..media.gauss import N10, N20, W10, W20
from ..media.inside_rule import QUAD, cut_length, march_or_sample
from ..media.slab import (EDGE_CUTS, FACE_COLUMNS, MAX_CUTS, U, FacesPoint, break_errors,
                          convex_exit_face, convex_integrand, coordinate_size, directional_rounding, edge_breaks,
                          fermat, light_norms, light_span, on_face, only_face, phase_condition,
                          point_rounding, reachable_faces, refracted_at, refracted_cuts, refracting_faces, rho_range,
                          spot_terms, straight_cuts, term_error)


class AttenuatedConvex(NamedTuple):
    """`convex_integrand` of a point or spot light, or a `directional` one (geo row, the shape's
    planes, one channel; `only` >= 0: the beam refracted through that face, the chords from its
    entry point along `sun`) times exp(-sum_j dk[j] chord_j), chord_j through the planes
    others[first[j]:stop[j]]."""
    directional: bool
    geo: np.ndarray
    planes: np.ndarray
    kt: float
    ks: float
    code: int
    g: float
    kt_out: float
    others: np.ndarray
    first: np.ndarray
    stop: np.ndarray
    dk: np.ndarray
    rtol: float
    only: int
    sun: np.ndarray


@integrand_of(AttenuatedConvex)
@njit
def _attenuated(x, r):
    geo = r.geo
    phase = phase_value(r.code, r.g, geo[3] * geo[6] + geo[4] * geo[7] + geo[5] * geo[8]) if r.directional else 0.0
    v = convex_integrand(x, geo, PLANES, r.planes, r.directional, r.kt, r.ks, r.code, r.g, r.kt_out, phase, r.only)
    if v == 0.0:
        return 0.0
    px, py, pz = geo[0] + x * geo[3], geo[1] + x * geo[4], geo[2] + x * geo[5]
    if r.only >= 0:  # a refracted beam: from its entry point on face `only`, toward the sun
        k = convex_exit_face(px, py, pz, geo[6], geo[7], geo[8], r.planes)[0]
        px, py, pz = px + k * geo[6], py + k * geo[7], pz + k * geo[8]
        ux, uy, uz, dist = r.sun[0], r.sun[1], r.sun[2], math.inf
    elif r.directional:
        ux, uy, uz, dist = geo[6], geo[7], geo[8], math.inf
    else:
        ux, uy, uz = geo[6] - px, geo[7] - py, geo[8] - pz
        dist = math.sqrt(ux * ux + uy * uy + uz * uz)
        if not dist > 0.0:
            return v
        ux, uy, uz = ux / dist, uy / dist, uz / dist
    tau = 0.0
    for j in range(r.first.shape[0]):
        if r.dk[j] != 0.0:
            tau += r.dk[j] * chord(r.others, r.first[j], r.stop[j], px, py, pz, ux, uy, uz, dist)
    return v * math.exp(-tau)


@njit
def chord_rounding(planes, first, stop, u, r, dplanes):
    """(dc, C): a bound dc on the rounding of `chord` along the unit u from any point X with |X| <= r
    through the planes planes[first:stop] (themselves dplanes = (dn, dc) off the shape's faces), and
    C >= the chord. Each end is 0 or s_f = (c_f - n_f·X) / q_f (q_f = n_f·u), |s_f| <= S = max_f
    (|c_f| + r) / |q_f|, off by (16u (|c_f| + r) + dc + dn (r + S)) / |q_f| as media/slab.py
    `directional_rounding`'s exit; the chord, max(hi - lo, 0), by twice the largest of those, and
    C = S. inf where a face is within its own error of parallel to u (the clip's side undecided)."""
    smax = 0.0
    for f in range(first, stop):
        q = abs(planes[f, 0] * u[0] + planes[f, 1] * u[1] + planes[f, 2] * u[2])
        if not q > 16.0 * U + dplanes[0]:
            return math.inf, math.inf
        smax = max(smax, (abs(planes[f, 3]) + r) / q)
    ds = 0.0
    for f in range(first, stop):
        q = abs(planes[f, 0] * u[0] + planes[f, 1] * u[1] + planes[f, 2] * u[2])
        ds = max(ds, (16.0 * U * (abs(planes[f, 3]) + r) + dplanes[1] + dplanes[0] * (r + smax)) / q)
    return 2.0 * ds, smax


@njit
def point_chord_rounding(planes, first, stop, light, sphere, r, dmax, dmin, dplanes):
    """(dc, C): a bound dc on the rounding of `chord` toward the point light L = `light` from any point
    X with |X| <= r (L at distances in [dmin, dmax] from X) through the convex shape of the planes
    planes[first:stop] (themselves dplanes = (dn, dc) off its faces; inside the ball `sphere` =
    (centre, radius)), and C = dmax >= the chord; inf where dmin is 0.

    Face f's end s_f = num_f / q_f (num_f = c_f - n_f·X, q_f = n_f·u, u = (L - X) / d) is computed
    as the exact end of a plane displaced, at the crossing Y = X + s_f u, by at most
    e_f = dn |Y| + dc + D (du + 4u) + 16u (|c_f| + r) (|Y| <= |centre| + radius: only crossings at
    the shape move the chord; du = 64u (|L| + r) / dmin + 4u bounds u's rounding), and q_f by dq = du
    + dn + 4u. On the plane, n_f·(L - Y) = h_f (the light's height over it), so |q_f| = |h_f| / |L - Y|
    >= |h_f| / G, G = min(D, |L - centre| + radius): s_f is off by at most e_f / (|h_f| / G - dq) <=
    4 e_f G / (3 |h_f|) where |h_f| > 4 (e_f + G dq), and a crossing farther from the light than G,
    exact or rounded, lies off the shape and leaves the chord as it is. The chord, max(min(hi, d) -
    lo, 0), is then off by the sum of the two largest ends' errors (lo's face enters, hi's leaves: two
    faces) plus d's own rounding 32u (|L| + r) + 4u D.
    inf where the light lies within that margin of a face's plane (a path could graze the face)."""
    if not dmin > 0.0:
        return math.inf, math.inf  # the light on the segment
    p = math.sqrt(light[0] * light[0] + light[1] * light[1] + light[2] * light[2])
    cx, cy, cz = light[0] - sphere[0], light[1] - sphere[1], light[2] - sphere[2]
    far = min(dmax, math.sqrt(cx * cx + cy * cy + cz * cz) + sphere[3])
    at = math.sqrt(sphere[0] * sphere[0] + sphere[1] * sphere[1] + sphere[2] * sphere[2]) + sphere[3]
    du = 64.0 * U * (p + r) / dmin + 4.0 * U
    dq = du + dplanes[0] + 4.0 * U
    ds, ds2 = 0.0, 0.0  # the two largest ends' errors
    for f in range(first, stop):
        c = planes[f, 3]
        e = dplanes[0] * at + dplanes[1] + dmax * (du + 4.0 * U) + 16.0 * U * (abs(c) + r)
        h = abs(planes[f, 0] * light[0] + planes[f, 1] * light[1] + planes[f, 2] * light[2] - c)
        h -= 16.0 * U * (abs(c) + p) + dplanes[1] + dplanes[0] * p  # the height's own rounding
        if not h > 4.0 * (e + far * dq):
            return math.inf, math.inf
        e = 4.0 * e * far / (3.0 * h)
        ds, ds2 = max(ds, e), max(ds2, min(ds, e))
    return ds + ds2 + 32.0 * U * (p + r) + 4.0 * U * dmax, dmax


@njit
def _entry_line(rec, end, r, dplanes):
    """(o', w', kmax, dP) of a refracted beam through face f = rec.only: where a point X(x) = o + x w
    leaves through f along `toward` (geo[6:9]), its entry point P = X + k toward with k = (c_f -
    n_f·X) / q_f (q_f = n_f·toward > 0) runs along the line o' + x w', k at most kmax (k is linear
    in x), and P is off by dP = dk + 16u (r + kmax), dk = (16u (|c_f| + r) + dc + dn (r + kmax)) / q_f
    as media/slab.py `directional_rounding`'s exit (r >= |X|)."""
    geo, f = rec.geo, rec.only
    n, c = rec.planes[f, :3], rec.planes[f, 3]
    q = n[0] * geo[6] + n[1] * geo[7] + n[2] * geo[8]
    k0 = (c - (n[0] * geo[0] + n[1] * geo[1] + n[2] * geo[2])) / q
    dkdx = -(n[0] * geo[3] + n[1] * geo[4] + n[2] * geo[5]) / q
    kmax = max(k0, k0 + dkdx * end, 0.0)
    dk = (16.0 * U * (abs(c) + r) + dplanes[1] + dplanes[0] * (r + kmax)) / q
    return geo[0:3] + k0 * geo[6:9], geo[3:6] + dkdx * geo[6:9], kmax, dk + 16.0 * U * (r + kmax)


@njit
def _beam_kinks(rec, end, out):
    """The kinks in (0, end) of the chords along the sun through every B_j from a refracted beam's
    entry point (`_entry_line`): `section_kinks(..., directional=True)` of the line o' + x w' (in its
    arc length, mapped back to x); none where the entry point stands still. Returns their count."""
    o, w, _, _ = _entry_line(rec, end, 0.0, NO_ERROR)
    speed = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    if not speed > 0.0:
        return 0
    w = w / speed
    m = 0
    for j in range(rec.first.shape[0]):
        n = section_kinks(rec.others, rec.first[j], rec.stop[j], o, w, rec.sun, end * speed, out[m:], True)
        out[m:m + n] /= speed
        m += n
    return m


NO_ERROR = np.zeros(2)


@njit
def _bounded(rec, planes, end, dplanes, dothers, spheres, stats):
    """(value, bound) of an `AttenuatedConvex` over [0, end] by QUAD (`bounded_piecewise` between the
    kinks of A's and every B_j's chords, and a spot's cone crossings), the bound as the module's
    docstring says."""
    geo, others, first, stop = rec.geo, rec.others, rec.first, rec.stop
    o, w, toward = geo[0:3], geo[3:6], geo[6:9]
    nf = planes.shape[0]
    br = np.empty(nf + others.shape[0] + 4 * first.shape[0] + 10)
    br[0] = 0.0
    if rec.directional:
        cuts, lines, alpha, beta = np.empty(nf + 1), np.empty(nf, dtype=np.int64), np.empty(nf), np.empty(nf)
        n_env = envelope(planes[:, :3], planes[:, 3], o, w, toward, end, alpha, beta, cuts, lines)
        if n_env == 0:
            return 0.0, 0.0  # no face toward the light: an infinite path inside (kt > 0)
        m = 0
    else:
        m = straight_cuts(geo, end, br[1:])
    m += section_kinks(planes, 0, nf, o, w, toward, end, br[1 + m:], rec.directional)
    if rec.only >= 0:
        m += _beam_kinks(rec, end, br[1 + m:])
    else:
        for j in range(first.shape[0]):
            m += section_kinks(others, first[j], stop[j], o, w, toward, end, br[1 + m:], rec.directional)
    br[1:m + 1].sort()
    br[m + 1] = end
    before = stats[INTERVALS]
    value, rule = bounded_piecewise(rec, br, m + 2, rec.rtol, N10, W10, N20, W20, stats)
    r = coordinate_size(geo, planes, end)[0]
    dshift = np.zeros(2)
    if rec.only >= 0:  # the chords start at the entry point P = X + k toward, off by dP (`_entry_line`)
        _, _, kmax, dp = _entry_line(rec, end, r, dplanes)
        r += kmax
        dshift[1] = dp
    if rec.directional:
        eps = directional_rounding(geo, planes, end, rec.kt, rec.code, rec.g, cuts, lines, alpha, beta, n_env,
                                   dplanes)
    else:
        eps = point_rounding(geo, planes, end, rec.kt, rec.kt_out, rec.code, rec.g, dplanes)
        _, dmax, dmin = light_span(geo, end)
    for j in range(first.shape[0]):
        if rec.dk[j] != 0.0:
            if rec.directional:
                dc, cmax = chord_rounding(others, first[j], stop[j], rec.sun, r, dothers[j] + dshift)
            else:
                dc, cmax = point_chord_rounding(others, first[j], stop[j], toward, spheres[j], r, dmax, dmin,
                                                dothers[j])
            eps += abs(rec.dk[j]) * (dc + 16.0 * U * cmax)
    eps += 4.0 * U
    return value, rule + (3.0 * eps + (stats[INTERVALS] - before) * U) * (value + rule)


@njit
def attenuated_radiance(directional, geo, planes, ell, kt, ks, code, g, kt_out, others, first, stop, dk, rule, keys,
                        dim0, seed, dplanes, dothers, spheres, only, sun, out, var, err, stats):
    """out, var, err (N,) = the attenuated single scattering (`AttenuatedConvex`) of each segment (geo
    rows, unit light, one channel) over [0, ell], its variance and a bound on its error, by the inside
    `rule` (media/inside_rule.py): QUAD adaptive
    between the kinks of A's and every B_j's chords and a spot's cone crossings, bounded (`_bounded`;
    dplanes, dothers[j]: the planes' (dn, dc) of A and B_j, spheres[j]: a ball (centre, radius)
    holding B_j; only, sun: a refracted beam's face and the direction toward the sun, only -1
    otherwise); MARCH, SAMPLE as media/inside_rule.py's `march_or_sample` (keys, dim0, seed: SAMPLE's
    random streams), err inf."""
    for s in range(geo.shape[0]):
        out[s], var[s], err[s] = 0.0, 0.0, 0.0
        if ks == 0.0 or not ell[s] > 0.0:
            continue
        rec = AttenuatedConvex(directional, geo[s], planes, kt, ks, code, g, kt_out, others, first, stop, dk,
                               rule.rtol, only, sun)
        if rule.kind == QUAD:
            out[s], err[s] = _bounded(rec, planes, min(ell[s], 745.0 / kt), dplanes, dothers, spheres, stats)
        else:
            out[s], var[s] = march_or_sample(rec, rule, cut_length(rule, ell[s], kt), kt, keys[s], dim0, seed)
            err[s] = math.inf


class RefractedAttenuated(NamedTuple):
    """A point or spot light's refracted path through one face of a convex refractive shape A (`row`, a
    media/slab.py `refracting_faces` row; `spot` its (cos_end, cos_start, curve)): `refracted_at` where
    the refraction point R lies on the face, times exp(-sum_j dk[j] chord_j) of the outside leg from R
    to the light, chord_j through the planes others[first[j]:stop[j]]. With a track (QUAD), each
    evaluation's rounding, the face's term's (media/slab.py `term_error`, `faces` the row alone)
    times the attenuation, is kept as `FacesPoint` keeps it. The shape's planes, eta, the medium's
    and the spot's terms are those of `faces`."""
    row: np.ndarray
    light: np.ndarray
    others: np.ndarray
    first: np.ndarray
    stop: np.ndarray
    dk: np.ndarray
    faces: FacesPoint


@njit
def _leg(x, row, eta):
    """(rho, r, R) of face row's Fermat path at x (media/slab.py `fermat`): R = p_f + x w_h +
    (r / rho)(L_h - x w_h), the refraction point on the face's plane (as `_edge_distance`)."""
    rho, r = fermat(x, max(row[0], 0.0), row[3], row[4], row[1], row[2], eta)
    t = r / rho if rho > 0.0 else 0.0
    return rho, r, (row[8] + x * row[11] + t * (row[14] - x * row[11]), row[9] + x * row[12] + t * (row[15] - x * row[12]),
                    row[10] + x * row[13] + t * (row[16] - x * row[13]))


@njit(inline="always")
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(inline="always")
def _minus(a, b):
    return a[0] - b[0], a[1] - b[1], a[2] - b[2]


@integrand_of(RefractedAttenuated)
@njit
def _refracted_attenuated(x, r):
    row, f = r.row, r.faces
    z0, a = row[0], row[1]
    if not z0 + a * x > 0.0:
        return 0.0
    rho, rr, p = _leg(x, row, f.eta)
    if not on_face(x, row, rr, rho, f.planes):
        return 0.0
    sp = f.spot
    v = refracted_at(x, z0, rho, rr, row[3], a, row[2], f.eta, f.kt, f.ks, f.code, f.g, f.kt_out, row[5], row[6],
                     row[7], sp[0], sp[1], sp[2])
    track = f.track
    err = term_error(x, row, v, rho, rr, f) if track.shape[0] > 0 else 0.0
    if v == 0.0 and err == 0.0:
        return 0.0
    u = _minus(r.light, p)
    dist = math.sqrt(_dot(u, u))
    tau = 0.0
    if dist > 0.0:
        for j in range(r.first.shape[0]):
            if r.dk[j] != 0.0:
                tau += r.dk[j] * chord(r.others, r.first[j], r.stop[j], p[0], p[1], p[2], u[0] / dist, u[1] / dist,
                                       u[2] / dist, dist)
    if track.shape[0] > 0 and err * math.exp(-tau) > track[0]:
        track[0] = err * math.exp(-tau)
    if not dist > 0.0:
        return v
    return v * math.exp(-tau)


@njit
def leg_kinks(row, n, p, w, eta, light, others, first, stop, end, out):
    """The x in (0, end) where the outside leg from face row's refraction point R(x) to the light
    crosses an edge of a shape B_j (planes others[first[j]:stop[j]]): the kinks of its chord. Each
    pair of B_j's planes meets on a line (through q, along e); the leg meets it where R(x) crosses
    the plane through the light and that line, the roots of g = (e x (L - q))·(R - q), isolated
    with shadows/fermat_legs.py's Lipschitz bound on R (`_roots`: none missed, no grid) and kept
    where the crossing lies on B_j (every other plane, to 1e-9 of its size) between R and the light.
    n: the face's outward normal, p + x w the segment. Returns (out, count)."""
    z0, a, hl = row[0], row[1], row[2]
    lf = light - hl * n
    scale = max(np.abs(light).max(), np.abs(p).max(), np.abs(p + end * w).max())
    tol, width = ROUNDING * scale, RESOLUTION * scale
    roots = np.empty(16)
    m = 0
    for j in range(first.shape[0]):
        for g in range(first[j], stop[j]):
            for h in range(g + 1, stop[j]):
                e = _cross(others[g, :3], others[h, :3])
                ee = e @ e
                if not ee > 1e-24:
                    continue
                q = (others[g, 3] * _cross(others[h, :3], e) + others[h, 3] * _cross(e, others[g, :3])) / ee
                vec = _cross(e, light - q)
                size = _norm(vec)
                if not size > 0.0:
                    continue
                roots, k = _roots(_OUT_EDGE, q, vec, p, w, row[8:11], row[11:14], z0, a, lf, hl, eta, end,
                                  tol * size, width, roots, 0)
                for i in range(k):
                    d = _refraction(roots[i], row[8:11], row[11:14], z0, a, lf, hl, eta)[0] - light
                    c1 = _cross(d, e)
                    cc = c1 @ c1
                    if not cc > 0.0:
                        continue
                    s = (_cross(q - light, e) @ c1) / cc  # the leg's line L + s d meets the edge line
                    y = light + s * d
                    slack = 1e-9 * (np.abs(y).max() + abs(others[g, 3]))
                    on = 0.0 < s < 1.0
                    for f in range(first[j], stop[j]):
                        if f != g and f != h and others[f, :3] @ y - others[f, 3] > slack:
                            on = False
                    if on:
                        out = _push(out, m, roots[i])
                        m += 1
    return out, m


@njit
def refracted_attenuated(geo, planes, near, ell, kt, ks, code, g, kt_out, eta, only, others, first, stop, dk, rule,
                         keys, dim0, seed, dplanes, dothers, spheres, out, var, err, stats):
    """out, var, err (N,) = a unit point or spot light's single scattering over each segment (geo rows
    with zero entry normals: every face's terms from `planes`) of a convex refractive shape through
    face `only` (`RefractedAttenuated`), the outside leg attenuated by the B_j, its variance and a
    bound on its error, by the inside `rule`: QUAD adaptive between A's edge breaks and cone crossings (media/slab.py
    `faces_quadrature`'s) and the leg's chord kinks (`leg_kinks`), bounded (`_refracted_bound`;
    dplanes, dothers[j]: the planes' (dn, dc) of A and B_j, spheres[j] a ball holding B_j); MARCH,
    SAMPLE as media/inside_rule.py's `march_or_sample`, err inf. `near` (interiors/crossing.py
    `plane_neighbours`; given for a shape of more than KERNEL_PLANES planes): the face's path over the
    planes it needs alone (media/slab.py `reachable_faces`, as `faces_quadrature`'s each face: its
    face test, breaks and bound those with every plane; 0, exactly, where its refraction point
    never lies on the face); empty: over every plane."""
    nf = planes.shape[0]
    faces = np.empty((max(nf, 1), FACE_COLUMNS))
    br = np.empty(EDGE_CUTS * nf + MAX_CUTS + 1)
    ph = phase_condition(code, g)
    one = np.empty(1, np.int64)
    for s in range(geo.shape[0]):
        out[s], var[s], err[s] = 0.0, 0.0, 0.0
        if ks == 0.0 or not ell[s] > 0.0:
            continue
        spot = spot_terms(geo[s], 0.0, 0.0)
        m = only_face(faces, refracting_faces(geo[s], planes, 0.0, 0.0, 0.0, 0.0, spot, faces), only)
        end = min(ell[s], 745.0 / kt)
        local = planes
        if m == 1 and near.shape[0] > 0:
            m, local = reachable_faces(faces, m, planes, near, eta, end, one)
        if m == 0:
            continue
        row = faces[0]
        r, cmax = coordinate_size(geo[s], planes, end)
        pn, ln, lp = light_norms(geo[s])
        tracked = FacesPoint(faces[:1].copy(), local, eta, kt, ks, code, g, kt_out, spot[3:], ph, dplanes[0],
                               dplanes[1], (pn, ln, lp, r + ln + cmax), -1, np.zeros(1 if rule.kind == QUAD else 0))
        rec = RefractedAttenuated(row.copy(), geo[s, 6:9].copy(), others, first, stop, dk, tracked)
        if rule.kind != QUAD:
            out[s], var[s] = march_or_sample(rec, rule, cut_length(rule, ell[s], kt), kt, keys[s], dim0, seed)
            err[s] = math.inf
            continue
        br[0] = 0.0
        k = 1 + refracted_cuts(row[0], row[3], row[4], row[1], row[2], eta, row[5], row[6], row[7], spot[3], spot[4],
                               end, br[1:])
        k += edge_breaks(row, local, eta, end, br[k:])
        legs, n_legs = leg_kinks(row, planes[only, :3].copy(), geo[s, 0:3].copy(), geo[s, 3:6].copy(), eta, rec.light,
                                 others, first, stop, end, np.empty(16))
        cuts = np.concatenate((br[:k], legs[:n_legs], np.array([end])))
        cuts[1:-1].sort()
        out[s], err[s] = _refracted_bound(rec, cuts, end, rule.rtol, dothers, spheres, stats)


@njit
def _refracted_bound(rec, cuts, end, rtol, dothers, spheres, stats):
    """(value, bound) of a `RefractedAttenuated` over the pieces between `cuts` (0 and end included):
    the rule's bound (`bounded_piecewise`) + 3 times the evaluations' largest rounding (the face's
    term's, kept in the track) times the width + 3 times the chords' relative rounding eps times
    (value + rule) + the breaks' location error of A's face (media/slab.py `break_errors`, times the
    largest attenuation exp(sum_j max(-dk_j, 0) o_max)) + u per interval. eps = sum_j |dk_j| (dc_j +
    16u C_j) + 4u, dc_j, C_j of B_j's `point_chord_rounding` toward the light from the refraction
    point R, whose own error dR (media/fermat_rounding.py `point_error`) moves a crossing of the leg
    at most as much (the leg turns about the light), so it adds to B_j's offset error; |R| <= R_max
    (R lies between the feet of X and of the light on the face's plane), the leg between the
    light's height hl and o_max = sqrt(rho_max^2 + hl^2). The leg's chord kinks are continuous (no
    location error) and none is missed (`leg_kinks`). inf where the face's bound is (media/slab.py
    `faces_quadrature`)."""
    tracked = rec.faces
    row = rec.row
    before = stats[INTERVALS]
    tracked.track[0] = 0.0
    value, rule = bounded_piecewise(rec, cuts, cuts.shape[0], rtol, N10, W10, N20, W20, stats)
    if not tracked.eta > 1.0:
        return value, math.inf
    z0, a, hl, wl, ll = row[0], row[1], row[2], row[3], row[4]
    rho_min, rho_max = rho_range(0.0, end, wl, ll, a)
    if not (rho_min > 0.0 and hl > 0.0):
        return value, math.inf
    z_max = max(z0, z0 + a * end)
    pn, ln = tracked.mags[0], tracked.mags[1]
    dr = point_error(end, math.sqrt(rho_max * rho_max + z_max * z_max), rho_max, hl, ll, rho_min, tracked.eta,
                     tracked.dn, tracked.dc, tracked.mags, False)
    o_max = math.sqrt(rho_max * rho_max + hl * hl)
    r_max = max(pn + end + z_max, ln + hl)
    eps, grow = 4.0 * U, 0.0
    for j in range(rec.first.shape[0]):
        if rec.dk[j] != 0.0:
            dc, cmax = point_chord_rounding(rec.others, rec.first[j], rec.stop[j], rec.light, spheres[j], r_max,
                                            o_max, hl, dothers[j] + np.array([0.0, dr]))
            eps += abs(rec.dk[j]) * (dc + 16.0 * U * cmax)
            grow += max(-rec.dk[j], 0.0) * o_max
    located = break_errors(tracked, end, cuts[1:-1]) * math.exp(grow)
    rounding = 3.0 * tracked.track[0] * (cuts[-1] - cuts[0])
    return value, rule + rounding + located + (3.0 * eps + (stats[INTERVALS] - before) * U) * (value + rule)
