"""Other shapes' volumetric shadows on the light of a point or spot light inside a convex refractive mesh, in the
scattering medium outside (media/slab.py `out_of_faces`): along the part [lo, hi] of a camera segment q(x) = o + x w
beyond a face's plane, the pieces where the light's straight leg outside, from its refraction point E(x) on that
plane (Fermat's path, slab.py `fermat`) to q(x), clears every occluder, those where one blocks it, and undecided
stretches between them (`face_pieces`). The exact sphere's counterpart is media/globe_shadows.py, whose patches,
per-cell test (`_state`) and candidates (`_candidates`) this module reuses.

The breaks are found, not sampled: `_scan` halves the part from [lo, hi]. On a cell (midpoint m, half width h) the
legs of the cell lie within rho = max(h, D) + slack of the midpoint's leg q(m) E(m) (proven): the point a fraction
lambda along the leg of x is (1 - lambda) q(x) + lambda E(x), within (1 - lambda) |q(x) - q(m)| + lambda |E(x) -
E(m)| of the midpoint leg's, and |q(x) - q(m)| <= h; D bounds |E(x) - E(m)| (`_spread`):
- |dE/dx| <= 1 / cos2(x), cos2 the leg's cosine to the face's normal (proven, elementary): in the plane of incidence
  the refraction point lies between the feet of the light and of q, at distance rho_E from the light's foot, and q's
  foot at rho_q = rho_E + z tan2 (z: q's height above the plane), tan2 increasing with rho_E (Snell: sin2 = sin1 /
  eta, eta = 1 / ior, sin1 = rho_E / sqrt(rho_E^2 + hl^2)); so a sideways move of q turns E about the light's foot
  by at most as much (rho_E <= rho_q), a move along rho_q moves rho_E by at most as much (d rho_q / d rho_E = 1 + z
  d tan2 / d rho_E >= 1), a move up by dz moves rho_E by at most tan2 dz, and by Cauchy-Schwarz |dE| <= |dq| sqrt(1 +
  tan2^2) = |dq| / cos2 (the same as the brief's tube: the refracted wavefront's focal surfaces are virtual, on the
  light's side, so the legs spread at most as from E);
- cos2 >= c(D) = sqrt(1 - (sin1(rho_E(m) + D) / eta)^2) wherever |E(x) - E(m)| <= D (rho_E(x) <= rho_E(m) + D);
  with D0 = 2 h / cos2(m), if h / c(D0) < D0 then |E(x) - E(m)| stays below D0 over the cell (at a first x where
  it reached D0 it would be at most h / c(D0)), so D = h / c(D0); else the cell is undecided.
Every leg of the cell therefore lies in the tube of radius rho about the midpoint's leg and in the hull of the
cell's camera stretch and the ball of radius D + slack about E(m): `_state` with the ball (E(m), D) and the axis
q(m) -> E(m) decides each planar patch (its edges outside the hull or more than rho from the axis, the stretch not
crossing it: the midpoint leg's state; the ball and the stretch on one side of its plane: lit). The leg's ends do
not cross an occluder: q(x) where the stretch does not, E(x) on the glass's face, which no other shape reaches into
(interiors/support.py refuses those). A cell is dark where a patch blocks it so, lit where every patch clears it so,
else halved while h > slack (then an undecided stretch, about slack wide, which `out_of_faces` counts dark and
bounds as the globe's). The legs of points whose refraction point lies off the face carry no light; the test covers
them all the same (the infinite plane's path is unique and continuous in x). slack = SLACK of |q(m)| + |E(m)| + the
leg covers E(m)'s rounding (bisection to the resolution of doubles: argued, as the globe's). Patches are culled
against the shape's bounding ball (`_candidates`: every leg that carries light ends on the shape). Unproven after
MAX_CELLS cells (the rest classified by their midpoints' legs)."""
from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from .globe_shadows import (DARK, LIT, MAX_CELLS, SLACK, UNDECIDED, _apart, _candidates, _crosses, _one_side,
                            _point_segment, _push, _segments)
from .slab import FACE_COLUMNS, GEO_COLUMNS, face_part, fermat, leaving_row


@njit
def _exit(x, row, eta):
    """(E, z, leg, rho_e) of the face row (media/slab.py `refracting_faces`, normals toward the light) at x: the
    refraction point of the light's path to the segment's point at x, that point's height above the plane, the leg's
    length and E's distance from the light's foot."""
    z = row[0] + row[1] * x
    rho, r = fermat(x, row[0], row[3], row[4], row[1], row[2], eta)
    t = r / rho if rho > 0.0 else 0.0
    e = np.empty(3)
    for c in range(3):
        e[c] = row[8 + c] + x * row[11 + c] + t * (row[14 + c] - x * row[11 + c])
    return e, z, math.sqrt(r * r + z * z), rho - r


@njit
def _spread(h, z, z_min, leg, o_min, rho_e, hl, eta):
    """D >= |E(x) - E(m)| over |x - m| <= h (module docstring): the smaller of h r / z_min and the bootstrap's
    h k / c(D0) (k = r / (o_min + r), D0 = 2 h k / cos2(m)); inf where neither holds."""
    r = hl / ((1.0 - eta * eta) ** 1.5 / eta)  # the focal distances' bound: hl / (ior cos1^3), cos1 >= sqrt(1 - eta^2)
    d = h * r / z_min if z_min > 0.0 else math.inf
    if not (z > 0.0 and leg > 0.0):
        return d
    k = r / (max(o_min, 0.0) + r)
    d0 = 2.0 * h * k * leg / z
    far = rho_e + d0
    s2 = far / math.sqrt(far * far + hl * hl) / eta
    if s2 < 1.0 and h * k / math.sqrt(1.0 - s2 * s2) < d0:
        d = min(d, h * k / math.sqrt(1.0 - s2 * s2))
    return d


CONE_STEPS = 24  # the midpoint leg's pieces in `_state` (from q(m), each half the rest: radii down to 2^-24 h + D)


@njit
def _off_slab(points, plane, top, slack):
    """Whether the points (..., 3) all lie above the height top over the face's plane, or all below it (the legs of
    the cell lie between: heights 0 at E to at most top at q)."""
    flat = points.ravel()
    above = below = True
    for i in range(0, flat.shape[0], 3):
        z = plane[0] * flat[i] + plane[1] * flat[i + 1] + plane[2] * flat[i + 2] - plane[3]
        above = above and z > top + slack
        below = below and z < -slack
    return above or below


@njit
def _state(tris, edges, qa, qb, qm, e, h, d, c, radius, plane, top, slack):
    """LIT or DARK where the planar patch of triangles tris (its boundary edges (E, 2, 3)) keeps one state over the
    cell, else UNDECIDED (module docstring): the leg of x lies, at each fraction lambda, within (1 - lambda) h +
    lambda d + slack of the midpoint's leg qm -> e (taken on CONE_STEPS pieces, each at its largest radius), between
    the cell's camera stretch qa qb and the ball (c, radius) that holds every E(x), and between the face's plane and
    the height top above it."""
    if _off_slab(tris, plane, top, slack) or _one_side(tris[0], c, radius + slack, qa, qb, slack):
        return LIT
    for t in range(tris.shape[0]):
        if _crosses(tris[t], qa, qb):
            return UNDECIDED
    for j in range(edges.shape[0]):
        a, b = edges[j, 0], edges[j, 1]
        if _off_slab(edges[j], plane, top, slack) or _apart(a, b, qa, qb, c, radius + 2.0 * slack):
            continue
        lam, near = 0.0, qm
        for i in range(CONE_STEPS + 1):
            nxt = 1.0 if i == CONE_STEPS else 1.0 - 0.5 ** (i + 1)
            far = qm + nxt * (e - qm)
            if not _segments(a, b, near, far) > (1.0 - lam) * h + nxt * d + slack:
                return UNDECIDED
            lam, near = nxt, far
    for t in range(tris.shape[0]):
        if _crosses(tris[t], qm, e):
            return DARK
    return LIT


@njit
def _scan(o, w, lo, ell, row, plane, eta, tris, tstart, edges, estart, near):
    """(ends, flags, count, proven) of face row's part [lo, lo + ell] of the segment o + x w (module docstring)
    against the planar patches `near`: the pieces' ends relative to lo (count + 1, from 0 to ell) and flags."""
    ends, flags = np.empty(16), np.empty(16)
    ends[0] = 0.0
    n, cells, proven = 0, 0, True
    foot = row[8:11] + row[14:17]  # the light's foot on the plane
    disc = row[2] * eta / math.sqrt(1.0 - eta * eta)  # every E within it of the foot (sin1 <= eta)
    stack = [(0.0, ell)]
    while len(stack):
        a, b = stack.pop()
        m, h = 0.5 * (a + b), 0.5 * (b - a)
        qa, qb, qm = o + (lo + a) * w, o + (lo + b) * w, o + (lo + m) * w
        e, z, leg, rho_e = _exit(m, row, eta)
        slack = SLACK * (math.sqrt(qm[0] * qm[0] + qm[1] * qm[1] + qm[2] * qm[2])
                         + math.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]) + leg)
        z_min, top = min(row[0] + row[1] * a, row[0] + row[1] * b), max(row[0] + row[1] * a, row[0] + row[1] * b)
        o_min = max(z_min, _point_segment(foot, qa, qb) - disc)
        d = _spread(h, z, z_min, leg, o_min, rho_e, row[2], eta)
        c, radius = (e, d) if d < disc else (foot, disc)
        cells += 1
        state = LIT
        for i in near:
            st = _state(tris[tstart[i]:tstart[i + 1]], edges[estart[i]:estart[i + 1]], qa, qb, qm, e, h, d, c, radius,
                        plane, top, slack)
            if st == DARK:
                state = DARK
                break
            if st == UNDECIDED:
                state = UNDECIDED
        if state == UNDECIDED and cells > MAX_CELLS:  # out of budget: the midpoint's leg decides
            proven = False
            state = LIT
            for i in near:
                for k in range(tstart[i], tstart[i + 1]):
                    if _crosses(tris[k], qm, e):
                        state = DARK
        if state == UNDECIDED and h > slack:
            stack.append((m, b))
            stack.append((a, m))
            continue
        n, ends, flags = _push(ends, flags, n, b, state)
    return ends, flags, n, proven


@njit
def face_pieces(geo, planes, ell, eta, ball, tris, tstart, edges, estart):
    """Per segment s (geo rows of media/slab.py's GEO_COLUMNS, ell its length) and face f of the convex shape
    `planes` (k = s F + f) the pieces of f's part [lo, hi] of [0, ell] (slab.py `face_part`), relative to lo, lit
    (LIT), shadowed (DARK) or undecided (UNDECIDED) on the leg of the light inside (eta = 1 / ior) through f by the
    occluders, planar patches of triangles outside the shape (media/globe_shadows.py `patches`: tris, tstart,
    edges, estart), culled against `ball` (centre, radius: a ball holding the shape) (`_scan`): (start (N F + 1,),
    ends, flags, proven (N F,)); part k's pieces are flags[start[k] - k : start[k + 1] - k - 1] between
    ends[start[k] : start[k + 1]]. A part no patch may reach is one lit piece, unscanned."""
    nseg, nf = geo.shape[0], planes.shape[0]
    c, radius = ball[:3].copy(), ball[3]
    toward = -planes
    rows = np.empty((max(nf, 1), FACE_COLUMNS))
    point = np.empty(GEO_COLUMNS)
    start = np.zeros(nseg * nf + 1, dtype=np.int64)
    ends, flags = np.empty(4 * nseg * nf + 16), np.empty(4 * nseg * nf + 16)
    proven = np.ones(nseg * nf, dtype=np.bool_)
    for s in range(nseg):
        o, w = geo[s, :3].copy(), geo[s, 3:6].copy()
        length = max(ell[s], 0.0)
        near = _candidates(o, w, length, c, radius, tris, tstart)
        for f in range(nf):
            k = s * nf + f
            lo, hi = face_part(geo[s], planes[f], length)
            part = max(hi - lo, 0.0)
            if part > 0.0 and len(near) and leaving_row(geo[s], lo, toward, f, point, rows):
                e, fl, n, proven[k] = _scan(o, w, lo, part, rows[0].copy(), planes[f], eta, tris, tstart, edges, estart,
                                            near)
            else:
                e, fl, n = np.array([0.0, part]), np.array([LIT]), 1
            j = start[k] - k  # the flags' offset
            while start[k] + n + 1 > ends.shape[0] or j + n > flags.shape[0]:
                ends, flags = np.concatenate((ends, np.empty(ends.shape[0]))), np.concatenate((flags, np.empty(
                    flags.shape[0])))
            ends[start[k]:start[k] + n + 1], flags[j:j + n] = e[:n + 1], fl[:n]
            start[k + 1] = start[k] + n + 1
    return start, ends[:start[-1]], flags[:start[-1] - nseg * nf], proven
