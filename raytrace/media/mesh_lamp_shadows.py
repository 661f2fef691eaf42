"""Other shapes' volumetric shadows on the light of a point or spot light inside a convex refractive mesh, in the
scattering medium outside (media/slab.py `out_of_faces`): along the part [lo, hi] of a camera segment q(x) = o + x w
beyond a face's plane, the pieces where the light's straight leg outside, from its refraction point E(x) on that
plane (Fermat's path, slab.py `fermat`) to q(x), clears every occluder, those where one blocks it, and undecided
stretches between them (`face_pieces`). The exact sphere's counterpart is media/globe_shadows.py, whose patches,
per-cell test (`_state`) and candidates (`candidate_patches`) this module reuses.

The breaks are found, not sampled: `_scan` halves the part from [lo, hi]. On a cell (midpoint m, half width h) the
point a fraction lambda along the leg of x, (1 - lambda) q(x) + lambda E(x), lies within (1 - lambda) |q(x) - q(m)| +
lambda |E(x) - E(m)| <= (1 - lambda) h + lambda D of the midpoint leg's (proven): a cone about the leg q(m) E(m),
narrowing toward the glass, where D bounds |E(x) - E(m)| (`_spread`). The refraction point's speed:
- |dE/dq| <= (r / (o + r)) / cos2 with o the leg's length, cos2 its cosine to the face's normal and r the larger of
  the distances from E back to the refracted wavefront's two focal points, which are virtual, on the light's side
  (argued from the focal distances of refraction at a plane: sagittal hl / (ior cos1), tangential hl cos2^2 / (ior
  cos1^3), hl the light's depth; both at most r_max = hl / (ior cos_c^3), cos_c = sqrt(1 - eta^2), eta = 1 / ior,
  since sin1 <= eta on every path): a move of q across the ray moves the ray about its focal point, so its crossing
  of the plane by r / (o + r) of it, over cos2 along the plane; a move along the ray does not move E. The elementary
  half of it, |dE/dq| <= 1 / cos2, is proven in the plane of incidence: E lies between the feet of the light and of
  q, rho_q = rho_E + z tan2 with tan2 increasing in rho_E, so a move of q turns or slides E by at most as much
  sideways or along rho, and up by dz moves it by at most tan2 dz (Cauchy-Schwarz).
- So D = h r_max / z_min (1 / cos2 <= o / z), or from the bootstrap: cos2 >= c(D) = sqrt(1 - (sin1(rho_E(m) + D) /
  eta)^2) wherever |E(x) - E(m)| <= D; with k = r_max / (o_min + r_max) and D0 = 2 h k / cos2(m), if h k / c(D0) <
  D0 the distance never reaches D0 over the cell (at a first x where it did it would be at most h k / c(D0)), so D
  = h k / c(D0); the smaller of the two, inf where neither holds. o_min: the larger of the least height z_min and the
  stretch's distance from the disc about the light's foot that holds every E (sin1 <= eta).
Every leg of the cell lies in that cone, in the hull of the cell's camera stretch and a ball holding every E(x) (E(m)'s
of radius D, or the disc's), and between the face's plane and the stretch's greatest height above it; `_state`
decides each planar patch with them (the patch off that slab, or its plane leaving the ball and the stretch on one
side: lit; else its edges outside the hull or the slab or the cone (taken on CONE_STEPS pieces, each at its largest
radius) and the stretch not crossing it: the midpoint leg's state). The leg's ends do not cross an occluder: q(x)
where the stretch does not, E(x) on the glass's face, which no other shape reaches into (interiors/support.py
refuses those). A cell is dark where a patch blocks it so, lit where every patch clears it so, else halved while h >
slack (then an undecided stretch, about slack wide, which `out_of_faces` counts dark and bounds as the globe's). The
legs of points whose refraction point lies off the face carry no light; the test covers them all the same (the
infinite plane's path is unique and continuous in x). slack = SLACK of |q(m)| + |E(m)| + the leg covers E(m)'s
rounding (bisection to the resolution of doubles: argued, as the globe's). Patches are culled against the shape's
bounding ball (`candidate_patches`: every leg that carries light ends on the shape). Unproven after MAX_CELLS cells (the
rest classified by their midpoints' legs): rays that graze an occluder's edge over a long stretch (below a finite
floor, toward the horizon)."""
from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from .globe_shadows import (DARK, LIT, MAX_CELLS, SLACK, UNDECIDED, candidate_patches, midpoint_state, one_side,
                            point_segment_distance, push_piece, segment_apart, segment_crosses, segment_distance)
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
    if _off_slab(tris, plane, top, slack) or one_side(tris[0], c, radius + slack, qa, qb, slack):
        return LIT
    for t in range(tris.shape[0]):
        if segment_crosses(tris[t], qa, qb):
            return UNDECIDED
    for j in range(edges.shape[0]):
        a, b = edges[j, 0], edges[j, 1]
        if _off_slab(edges[j], plane, top, slack) or segment_apart(a, b, qa, qb, c, radius + 2.0 * slack):
            continue
        lam, near = 0.0, qm
        for i in range(CONE_STEPS + 1):
            nxt = 1.0 if i == CONE_STEPS else 1.0 - 0.5 ** (i + 1)
            far = qm + nxt * (e - qm)
            if not segment_distance(a, b, near, far) > (1.0 - lam) * h + nxt * d + slack:
                return UNDECIDED
            lam, near = nxt, far
    for t in range(tris.shape[0]):
        if segment_crosses(tris[t], qm, e):
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
        o_min = max(z_min, point_segment_distance(foot, qa, qb) - disc)
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
            state = midpoint_state(near, tris, tstart, qm, e)
        if state == UNDECIDED and h > slack:
            stack.append((m, b))
            stack.append((a, m))
            continue
        n, ends, flags = push_piece(ends, flags, n, b, state)
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
        near = candidate_patches(o, w, length, c, radius, tris, tstart)
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
