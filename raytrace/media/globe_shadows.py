"""Other shapes' volumetric shadows on the light of a point or spot light well inside a refractive exact sphere, in the
scattering medium outside (media/sphere_refraction.py `out_of_sphere`): along a camera segment q(x) = o + x w, the
pieces where the light's straight leg outside, from its exit point E(x) on the sphere to q(x), clears every occluder,
those where one blocks it, and undecided stretches between them (`shadow_pieces`).

The breaks are found, not sampled. Occluders are planar patches of triangles (`patches`: a quad's two triangles are
one), outside the ball. A patch changes whether it blocks the leg only where the leg meets one of its boundary
edges or the camera segment crosses it (the leg's ends: q(x), and E(x) on the sphere, never on it; a segment meets a
plane once). `_scan` halves the segment from [0, ell] (`_split`); on a cell [a, b] (midpoint m, half width h) every
leg lies in the tube of radius rho = h (1 + s_max / o_min) + slack about the midpoint's leg q(m) + s t(m), s in
[0, s_max] (where o_min > 0):
- q(x) is within h of q(m); the unit direction t(x) from q(x) toward E(x) is the outgoing wavefront's normal, whose
  derivative is its shape operator, of principal curvatures 1 / (o + r_i) with r_i >= 0 the distances from E back to
  the focal points (there is no real caustic outside: every point outside has one path, sphere_refraction.py's
  claim, tests/test_globe_fog.py; proven below where k > 0), so |dt/dx| <= 1 / o <= 1 / o_min, o_min = min over the
  cell of |q - c| - R;
- the leg's length o(x) is at most the tangent length sqrt(|q - c|^2 - R^2) (the leg does not cross the ball: E is
  visible from q), s_max its largest over the cell (the ends: |q - c| is convex in x).
Every leg also lies within width = h min(1, r_max / (o_min + r_max)) / cos_min + slack of the triangle q(a) q(b)
E(m) (the hull of the stretch and the ball of that radius about E(m), which holds every E(x)), by the exit points'
motion (`exit_rate`), proven: the light at distance d = rho R from the centre, a path leaves at E with cosines c1
inside (to the normal) and c2 outside, sin(theta_1) <= rho (R sin(theta_1) is the centre's distance from the chord
through L), so c2 = sqrt(1 - eta^2 sin^2(theta_1)) >= cos_min = sqrt(1 - eta^2 rho^2) > 0, and the chord from L is
s <= R (c1 + rho). Coddington's equations for the way out (index eta to 1, the centre on the incoming side; the
module docstring of sphere_refraction.py has the way in) give the outgoing wavefront's curvatures at E,
    1 / r_s = eta / s - (eta c1 - c2) / R,   1 / r_t = (eta c1^2 / s - (eta c1 - c2) / R) / c2^2,
and eta c1 - c2 grows with theta_1 (its derivative eta sin(theta_1) (eta / c2 - 1 / c1) >= 0), so with c1 >=
sqrt(1 - rho^2), 1 / (1 + rho) >= 1 - rho and c2 <= 1 both are at least k / R, k = eta (1 - rho) - eta sqrt(1 -
rho^2) + cos_min: 0 < r_i <= r_max = R / k where k > 0 (else r_max = inf). Moving q across the leg by v moves the
leg's point at E across it by at most max_i r_i / (o + r_i) |v| (the wavefront's normals from focal distances o + r_i
at q and r_i at E), and along the leg by what keeps E on the sphere: the leg meets the normal at cosine c2, so |dE/dx|
<= min(1, r_max / (o + r_max)) / cos_min (checked against finite differences of `paths_out`'s exit points on random
lights, iors and segments: at most 0.99999 of it). With o_min <= 0 (a segment leaving the sphere) only this hull
applies. It is the one that settles far and grazing cells: its width at the leg's far end falls as 1 / o, as the legs
converge on the ball, where the tube stays as wide as the cell; `_split` halves a cell whose ends' distances from
the centre differ more than fourfold at their geometric mean, so that far cells are cut in proportion to their
distance.
A patch's state is constant over the cell where each boundary edge keeps out of the tube (the part of the axis past
E(m), inside the ball, by comparing with the edge's distance from the centre), out of the hull of the ball and the
cell's camera stretch (every leg lies in it; it lies within R of the triangle of the stretch's ends and the centre)
or out of the exit points' hull above, and the cell's camera stretch misses it, and then is the midpoint leg's (it
crosses a triangle of the patch or not, a float64 test with every edge out of a hull holding that leg); or where the
ball and the cell's camera stretch lie on one side of its plane (within slack: the camera segment ends on the
surface it hits). A cell is dark where a patch blocks it so, lit where every patch clears it so, else halved while
that narrows the tube or the hull (min(rho, width) > 2 slack); then it is an undecided stretch (at most about 2 slack
wide; `out_of_sphere` counts it dark and adds twice its length times the larger unshadowed integrand of its ends to
the bound: the integrand's change across 1e-12 of the scene is negligible, argued, not proven). slack (SLACK of the
midpoint's distance from the centre plus R) covers t(m)'s and E(m)'s rounding (relative 1e-14 at most, as
`fog_rounding` measures the paths' angles: argued). Unproven where a midpoint's path is not the one proven path, or
after MAX_CELLS cells (the rest classified by their midpoint's leg)."""
from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from .sphere_refraction import MAX_PATHS, paths_out

SLACK = 1e-12  # the tube's margin, relative to the scene's size: t(m)'s and E(m)'s rounding
MAX_CELLS = 1024  # cells scanned per segment before it is left unproven (the rest classified by their midpoints)
LIT, DARK, UNDECIDED = 1.0, 0.0, -1.0  # a piece's flag


@njit
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit
def point_segment_distance(p, a, b):
    """The distance from the point p to the segment ab."""
    ab, ap = b - a, p - a
    den = _dot(ab, ab)
    f = min(max(_dot(ap, ab) / den, 0.0), 1.0) if den > 0.0 else 0.0
    return math.sqrt(_dot(ap - f * ab, ap - f * ab))


@njit
def segment_distance(p1, q1, p2, q2):
    """The distance between the segments p1 q1 and p2 q2 (Ericson, Real-Time Collision Detection 5.1.9)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e, f = _dot(d1, d1), _dot(d2, d2), _dot(d2, r)
    if a <= 0.0 and e <= 0.0:
        return math.sqrt(_dot(r, r))
    if a <= 0.0:
        s, t = 0.0, min(max(f / e, 0.0), 1.0)
    else:
        c = _dot(d1, r)
        if e <= 0.0:
            s, t = min(max(-c / a, 0.0), 1.0), 0.0
        else:
            b = _dot(d1, d2)
            den = a * e - b * b
            s = min(max((b * f - c * e) / den, 0.0), 1.0) if den > 0.0 else 0.0
            t = (b * s + f) / e
            if t < 0.0:
                s, t = min(max(-c / a, 0.0), 1.0), 0.0
            elif t > 1.0:
                s, t = min(max((b - c) / a, 0.0), 1.0), 1.0
    v = p1 + s * d1 - p2 - t * d2
    return math.sqrt(_dot(v, v))


@njit
def segment_crosses(tri, p, q):
    """Whether the segment pq crosses the triangle tri (3, 3) (Moller-Trumbore)."""
    e1, e2, d = tri[1] - tri[0], tri[2] - tri[0], q - p
    h = np.array([d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2], d[0] * e2[1] - d[1] * e2[0]])
    det = _dot(e1, h)
    if det == 0.0:
        return False
    s = p - tri[0]
    u = _dot(s, h) / det
    if not 0.0 <= u <= 1.0:
        return False
    k = np.array([s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2], s[0] * e1[1] - s[1] * e1[0]])
    v = _dot(d, k) / det
    t = _dot(e2, k) / det
    return v >= 0.0 and u + v <= 1.0 and 0.0 <= t <= 1.0


@njit
def _point_triangle(p, p0, p1, p2):
    """The distance from the point p to the triangle p0 p1 p2: to its plane where p's foot falls inside, else to its
    nearest edge."""
    n = np.cross(p1 - p0, p2 - p0)
    nn = _dot(n, n)
    if nn > 0.0:
        h = _dot(p - p0, n) / nn
        f = p - h * n
        inside = True
        for a, b in ((p0, p1), (p1, p2), (p2, p0)):
            inside = inside and _dot(np.cross(b - a, f - a), n) >= 0.0
        if inside:
            return abs(h) * math.sqrt(nn)
    return min(point_segment_distance(p, p0, p1), point_segment_distance(p, p1, p2), point_segment_distance(p, p2, p0))


@njit
def segment_apart(a, b, p0, p1, p2, gap):
    """Whether the segment ab keeps more than gap from the triangle p0 p1 p2."""
    tri = np.empty((3, 3))
    tri[0], tri[1], tri[2] = p0, p1, p2
    if segment_crosses(tri, a, b):
        return False
    return min(segment_distance(a, b, p0, p1), segment_distance(a, b, p1, p2), segment_distance(a, b, p2, p0),
               _point_triangle(a, p0, p1, p2), _point_triangle(b, p0, p1, p2)) > gap


@njit
def one_side(tri, c, radius, qa, qb, slack):
    """Whether the ball (c, radius) lies strictly on one side of tri's plane and qa, qb on that side (within slack):
    no leg from the stretch qa qb to the sphere crosses the plane."""
    n = np.cross(tri[1] - tri[0], tri[2] - tri[0])
    nn = math.sqrt(_dot(n, n))
    if not nn > 0.0:
        return False
    n /= nn
    sc = _dot(n, c - tri[0])
    if not abs(sc) > radius + slack:
        return False
    sign = 1.0 if sc > 0.0 else -1.0
    return sign * _dot(n, qa - tri[0]) >= -slack and sign * _dot(n, qb - tri[0]) >= -slack


@njit
def _state(tris, edges, c, radius, qa, qb, qm, e, far, rho, spread, slack):
    """LIT or DARK where the planar patch of triangles tris (its boundary edges (E, 2, 3)) keeps one state over the
    cell (module docstring), else UNDECIDED: the legs lie within rho of the axis qm -> far (E(m) = e on the way), its
    part past e inside the ball, and within spread of the triangle qa qb e."""
    if one_side(tris[0], c, radius, qa, qb, slack):
        return LIT
    for t in range(tris.shape[0]):
        if segment_crosses(tris[t], qa, qb):
            return UNDECIDED
    inner = max(math.sqrt(_dot(e - c, e - c)), math.sqrt(_dot(far - c, far - c))) + rho
    for j in range(edges.shape[0]):
        a, b = edges[j, 0], edges[j, 1]
        # out of a hull of the legs
        if segment_apart(a, b, qa, qb, c, radius + slack) or segment_apart(a, b, qa, qb, e, spread):
            continue
        if not segment_distance(a, b, qm, e) > rho:
            return UNDECIDED
        if not inner < point_segment_distance(c, a, b) and not segment_distance(a, b, e, far) > rho:
            return UNDECIDED
    for t in range(tris.shape[0]):
        if segment_crosses(tris[t], qm, e):
            return DARK
    return LIT


@njit
def exit_rate(d, radius, eta):
    """(r_max, cos_min) for a light at d < radius / eta from the centre: the outgoing wavefront's focal distances
    behind its exit point are at most r_max (inf where the module docstring's k is not positive) and the leg's cosine
    to the normal there at least cos_min (0 for d >= radius / eta)."""
    rho = d / radius
    cos_min = math.sqrt(max(1.0 - eta * eta * rho * rho, 0.0))
    k = eta * (1.0 - rho) - eta * math.sqrt(1.0 - rho * rho) + cos_min
    return (radius / k if k > 0.0 else math.inf), cos_min


@njit
def _leg(q, c, radius, rel, eta, found, spread, value, toward, inside, outside):
    """(t, o, proven) of the light's one path out to q: the unit direction from q toward its exit point and the
    leg's length (`paths_out` with no cone), proven where its scan was and it found one path."""
    axis, cone = np.zeros(3), np.array([-2.0, -1.5, 1.0])
    proven = paths_out(q, c, radius, rel, axis, cone, eta, found, spread, value, toward, inside, outside)
    k, n = 0, 0
    for i in range(MAX_PATHS):
        if outside[i] > 0.0:
            k, n = i, n + 1
    return toward[k].copy(), outside[k], proven and n == 1 and value[k] > 0.0


@njit
def midpoint_state(near, tris, tstart, qm, e):
    """DARK where the midpoint's leg qm e crosses a triangle of the patches `near`, else LIT: a cell left undecided
    after MAX_CELLS cells (unproven)."""
    for i in near:
        for k in range(tstart[i], tstart[i + 1]):
            if segment_crosses(tris[k], qm, e):
                return DARK
    return LIT


@njit
def push_piece(ends, flags, n, x, flag):
    """Appends the piece ending at x with flag (merged with the last where they agree); returns the count and the
    arrays (grown where full)."""
    if n > 0 and flags[n - 1] == flag:
        ends[n] = x
        return n, ends, flags
    if n + 1 >= ends.shape[0]:
        ends2, flags2 = np.empty(2 * ends.shape[0]), np.empty(2 * ends.shape[0])
        ends2[:n + 1], flags2[:n] = ends[:n + 1], flags[:n]
        ends, flags = ends2, flags2
    flags[n] = flag
    ends[n + 1] = x
    return n + 1, ends, flags


@njit
def _split(a, b, da, db):
    """Where the cell [a, b] is halved: its midpoint, or where the distance from the centre (da, db at its ends,
    taken as linear) is their geometric mean where one exceeds four times the other (the hulls' widths scale with
    the cell's width over that distance)."""
    if db > 4.0 * da:
        return a + (b - a) * (math.sqrt(da * db) - da) / (db - da)
    if da > 4.0 * db:
        return b - (b - a) * (math.sqrt(da * db) - db) / (da - db)
    return 0.5 * (a + b)


@njit
def _scan(o, w, ell, c, radius, rel, eta, tris, tstart, edges, estart, near):
    """(ends, flags, count, proven) of one segment (module docstring) against the planar patches `near` (indices
    into tstart, estart: `shadow_pieces`): the pieces' ends (count + 1, from 0 to ell) and flags (count)."""
    ends, flags = np.empty(16), np.empty(16)
    ends[0] = 0.0
    n, cells, proven = 0, 0, True
    found, spread, value = np.empty(MAX_PATHS), np.empty(MAX_PATHS), np.empty(MAX_PATHS)
    toward, inside, outside = np.empty((MAX_PATHS, 3)), np.empty(MAX_PATHS), np.empty(MAX_PATHS)
    r_max, cos_min = exit_rate(math.sqrt(_dot(rel, rel)), radius, eta)
    stack = [(0.0, ell)]
    while len(stack):
        a, b = stack.pop()
        m, h = 0.5 * (a + b), 0.5 * (b - a)
        qa, qb, qm = o + a * w, o + b * w, o + m * w
        size = math.sqrt(_dot(qm - c, qm - c)) + radius
        slack = SLACK * size
        t, om, ok = _leg(qm, c, radius, rel, eta, found, spread, value, toward, inside, outside)
        cells += 1
        ab = qb - qa
        f = min(max(_dot(c - qa, ab) / _dot(ab, ab), 0.0), 1.0) if _dot(ab, ab) > 0.0 else 0.0
        closest = qa + f * ab - c
        o_min = math.sqrt(_dot(closest, closest)) - radius
        s_max = math.sqrt(max(_dot(qa - c, qa - c), _dot(qb - c, qb - c), radius * radius) - radius * radius)
        state = LIT
        if not (ok and cos_min > 0.0):  # not the one proven path: unshadowed, unproven
            proven = False
        else:
            rho = h * (1.0 + s_max / o_min) + slack if o_min > 0.0 else math.inf
            width = h * min(1.0, r_max / (max(o_min, 0.0) + r_max)) / cos_min + slack
            e, far = qm + om * t, qm + max(s_max, om) * t
            for i in near:
                st = _state(tris[tstart[i]:tstart[i + 1]], edges[estart[i]:estart[i + 1]], c, radius, qa, qb, qm, e,
                            far, rho, width, slack)
                if st == DARK:
                    state = DARK
                    break
                if st == UNDECIDED:
                    state = UNDECIDED
            if state == UNDECIDED and cells > MAX_CELLS:  # out of budget: the midpoint's leg decides
                proven = False
                state = midpoint_state(near, tris, tstart, qm, e)
            if state == UNDECIDED and min(rho, width) > 2.0 * slack:  # halving still narrows the hulls
                split = _split(a, b, math.sqrt(_dot(qa - c, qa - c)), math.sqrt(_dot(qb - c, qb - c)))
                stack.append((split, b))
                stack.append((a, split))
                continue
        n, ends, flags = push_piece(ends, flags, n, b, state)
    return ends, flags, n, proven


@njit
def candidate_patches(o, w, ell, c, radius, tris, tstart):
    """The patches that may block a leg from the segment: a triangle not wholly beyond one side of its plane with the
    ball and the segment (`one_side`), its box meeting the box of the ball and the segment."""
    p, q = o, o + ell * w
    keep = []
    for i in range(tstart.shape[0] - 1):
        for j in range(tstart[i], tstart[i + 1]):
            if one_side(tris[j], c, radius, p, q, SLACK * (math.sqrt(_dot(p - c, p - c)) + ell + radius)):
                continue
            meets = True
            for k in range(3):
                lo, hi = min(p[k], q[k], c[k] - radius), max(p[k], q[k], c[k] + radius)
                meets = meets and tris[j, :, k].min() <= hi and tris[j, :, k].max() >= lo
            if meets:
                keep.append(i)
                break
    return keep


@njit
def shadow_pieces(geo, sphere, ell, eta, tris, tstart, edges, estart):
    """Per segment (geo rows of media/slab.py's GEO_COLUMNS: origin, unit direction, the light; ell its length) the
    pieces of [0, ell] lit (LIT), shadowed (DARK) or undecided (UNDECIDED) by the occluders, all outside the ball:
    planar patches of triangles (`patches`: patch i's triangles tris[tstart[i]:tstart[i + 1]], its boundary edges
    edges[estart[i]:estart[i + 1]] (E, 2, 3)) (`_scan`): (start (N + 1,), ends, flags, proven (N,)); segment s's
    pieces are flags[start[s] - s : start[s + 1] - s - 1] between ends[start[s] : start[s + 1]]. A segment no patch
    may reach is one lit piece, unscanned."""
    c, radius = sphere[:3].copy(), sphere[3]
    nseg = geo.shape[0]
    start = np.zeros(nseg + 1, dtype=np.int64)
    ends, flags = np.empty(4 * nseg + 16), np.empty(4 * nseg + 16)
    proven = np.ones(nseg, dtype=np.bool_)
    for s in range(nseg):
        o, w, rel = geo[s, :3].copy(), geo[s, 3:6].copy(), geo[s, 6:9] - c
        length = max(ell[s], 0.0)
        near = candidate_patches(o, w, length, c, radius, tris, tstart)
        if length > 0.0 and len(near):
            e, f, n, proven[s] = _scan(o, w, length, c, radius, rel, eta, tris, tstart, edges, estart, near)
        else:
            e, f, n = np.array([0.0, length]), np.array([LIT]), 1
        j = start[s] - s  # the flags' offset
        while start[s] + n + 1 > ends.shape[0] or j + n > flags.shape[0]:
            ends, flags = np.concatenate((ends, np.empty(ends.shape[0]))), np.concatenate((flags, np.empty(
                flags.shape[0])))
        ends[start[s]:start[s] + n + 1], flags[j:j + n] = e[:n + 1], f[:n]
        start[s + 1] = start[s] + n + 1
    return start, ends[:start[nseg]], flags[:start[nseg] - nseg], proven


def patches(tris, shape_ids, tol=1e-14):
    """(tris, tstart, edges, estart) of the triangles tris (T, 3, 3) of shapes shape_ids (T,) grouped into planar
    patches for `shadow_pieces`: triangles of one shape sharing an edge (the same two corners) and one plane (their
    unit normals parallel: |n.n'| within tol of 1, a dihedral angle below 1.5e-7) join; a patch's boundary edges are those
    not shared inside it (a segment's crossing of a planar patch changes only where it meets one)."""
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None]
    parent = list(range(len(tris)))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    owner = {}
    for t in range(len(tris)):
        for j in range(3):
            key = (int(shape_ids[t]), *sorted((tuple(tris[t, j]), tuple(tris[t, (j + 1) % 3]))))
            u = owner.setdefault(key, t)
            if u != t and abs(abs(n[t] @ n[u]) - 1.0) <= tol:
                parent[root(t)] = root(u)
    ids = np.array([root(t) for t in range(len(tris))], dtype=np.int64)
    order = np.argsort(ids, kind="stable")
    _, first = np.unique(ids[order], return_index=True)
    tstart = np.append(first, len(tris)).astype(np.int64)
    count = {}
    for t in order:
        for j in range(3):
            key = (int(ids[t]), *sorted((tuple(tris[t, j]), tuple(tris[t, (j + 1) % 3]))))
            count[key] = count.get(key, 0) + 1
    edges, estart = [], [0]
    for key, v in count.items():  # in the patches' order (dicts keep insertion order)
        if key[0] != ids[order][first][len(estart) - 1]:
            estart.append(len(edges))
        if v == 1:
            edges.append(key[1:])
    estart.append(len(edges))
    return (np.ascontiguousarray(tris[order]), tstart, np.array(edges, dtype=np.float64).reshape(-1, 2, 3),
            np.array(estart, dtype=np.int64))
