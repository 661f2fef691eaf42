"""Point and spot light into refractive shapes that are not convex: Fermat's path through every face.

Inside a closed mesh of relative index eta that is not convex, a point or spot light at L reaches an inside
point X through each triangle F whose plane separates X from L, on Fermat's path through that plane
(Snell's law in the plane of incidence, as media/slab.py `refraction_point`, and `refracted_at`, Fresnel's T on
the way in, the ray tube's irradiance of a point source through a plane, a spot's falloff on the direction the
light leaves in), where its refraction point R lies inside F and both legs are clear of the mesh: X to R meets
no other face (it stays inside), R to L meets none (it stays outside). The legs are tested by the caller
(interiors/paths.py `refracted_integrand`, Embree); this module finds the candidate paths. Each face is taken in
either orientation (its plane's normal turned toward the light): a face whose outside looks toward X gives a
leg that leaves the shape before reaching it, which the leg tests reject.

The integrand jumps where a path appears or disappears: R crossing an edge of its triangle, a leg grazing
another face, and (a spot) the direction the light leaves in crossing a level of its cone. `face_breaks` locates
the first and the last kind per candidate face along each segment as roots of functions of R, isolated with a
Lipschitz bound as in shadows/fermat_legs.py: in F's plane (normal n toward the light) R moves at a speed
|R'| <= K_R over an interval of the segment (media/fermat_rounding.py `fermat_speed`, from the ends' horizontal
distances to the light and the least depth). Edge e from E0, v = +-n x e its inward normal in the plane:
g = v.(R - E0), R inside F where the three are >= 0, |g'| <= |v| K_R. A cone level c: g = A.(R - L) / |R - L| - c,
|g'| <= K_R / hl (|R - L| >= hl). An interval [lo, hi] holds no break of F where an edge has g(lo) + g(hi) <
-|g'| (hi - lo) (then g < 0 all along: R off F), or where every function has |g(lo)| + |g(hi)| > |g'| (hi - lo)
(no root); both with ROUNDING's allowance. Others are halved down to RESOLUTION of the scene's size, where a sign
change is bisected to the resolution of doubles (two roots closer than that, a sliver, are not resolved). A
search cut off after MAX_EVALS evaluations takes its undecided intervals' ends as breaks and reports that the
segment's breaks were not all found.

The bound (interiors/paths.py `refracted_quadrature`). `lit_scan` proves where each face lights each segment:
the same isolation over the face's edges, its cone levels and, for every other triangle G that may meet a leg
(`_blockers`: not on the face's plane, meeting the hull the leg lies in: X's stretch where R may lie on the face
(`_face_span`) and the face inside, the face and the light outside; found by descending a bounding-volume tree,
`face_tree`, so that a fine mesh costs its neighbourhood, not its size), the conditions under which G blocks it:
the leg's ends on opposite sides of G's plane and the line from its apex (X inside, the light outside) through
its other end inside G's three edge planes. The inside leg's conditions are functions of X (linear) and of R and
X together (`_scan` bounds their derivatives); the outside leg's are linear in R. Where the face lies on one side
of G's plane (exactly: orient3d's sign beyond its error bound at each corner, `_face_side`) and the leg's apex
(X, the light) strictly on that side too, G is clear of the leg for every R on the face: this settles G's
neighbours on a fine tessellation, whose planes R stays within rounding of. Tolerances are proven bounds
on the values' rounding: R's error from media/fermat_rounding.py `point_error` (first order, doubled), the
planes' from `plane_errors`. What is left undecided at RESOLUTION x the scene's size forms clusters; between
them each face is proven lit or dark. The quadrature keeps Embree's leg tests (its image is unchanged) and
checks them at every node against the scan: where they differ, or a node falls in a cluster, the bound is inf.
Each cluster adds its width times twice the face's bare term at its ends (at least its jump: the term varies by
far less over that width; where X leaves the face's plane lit within RESOLUTION x the size of the segment's
start or end, its value just inside); one that holds a change of the lit state or a cone level with no panel end within
RESOLUTION x the size of it (an unlocated jump inside a panel) makes the bound inf. The nodes' rounding is
`path_rounding`'s (media/fermat_rounding.py `term_rounding` per path).
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from ..lights import NO_CONE, SMOOTHSTEP, band_slope, has_cone
from .fermat_rounding import fermat_speed, point_error, refraction_newton, term_rounding
from .slab import phase_condition, refracted_at

SPAN_SLACK = 1e-9  # relative margin of the triangle's span along the foot's line (`_span`) before Snell's root
PATH_COLUMNS = 10  # rows of `face_paths`: point, face, R (3), the per unit light value, k, o, the legs' cosines
RESOLUTION = 1e-13  # x the scene's size: `face_breaks`' intervals this short are not halved, only bisected
ROUNDING = 1e-14  # x the scene's size: the rounding allowed in R's position (`face_breaks`)
MAX_EVALS = 4000  # evaluations of R per segment and face in `face_breaks`
SCAN_EVALS = 16000  # in `lit_scan` (a leg grazing an edge: its band of rounding, some 1e-10 of the segment, is halved to RESOLUTION)
SCAN_WORK = 40000  # `lit_scan`'s tests of other triangles per segment, the culled blockers included (beyond: not found, bound inf)


def face_planes(tris):
    """Unit normals and offsets (T, 4) of the triangles (T, 3, 3) (zero rows for degenerate ones)."""
    tris = np.asarray(tris, dtype=np.float64)
    cross = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    area = np.linalg.norm(cross, axis=1)
    n = np.where(area[:, None] > 0.0, cross / np.where(area > 0.0, area, 1.0)[:, None], 0.0)
    return np.ascontiguousarray(np.column_stack([n, np.einsum("ij,ij->i", n, tris[:, 0])]))


@njit
def candidates(tris, planes, geo, seg, lo, hi, eta, lists, starts, stops, faces, counts, out, fill):
    """The faces that may light the pieces [lo[i], hi[i]] of segments seg[i] (geo rows of media/slab.py
    GEO_COLUMNS: start, direction, the light's position) among faces[starts[lists[i]]:stops[lists[i]]]
    (`every` for all of them), a bounding test (`_may_light`): the light off the face's plane, some of
    the piece on the other side, and the box of the feet on that plane of the piece's ends and the light
    (which holds every refraction point through it: R lies between X's foot and the light's) meeting the
    triangle's box; for eta > 1 that box is cut to the feet of the piece's ends widened by `reach` of
    their depths. counts[i] = their number; with `fill`, out (sum counts) receives them, piece by piece."""
    m = 0
    row = np.empty(geo.shape[1])
    for i in range(seg.shape[0]):
        row[:] = geo[seg[i]]
        for k in range(3):
            row[k] += lo[i] * row[3 + k]
        c = 0
        for j in range(starts[lists[i]], stops[lists[i]]):
            f = faces[j]
            if _may_light(tris[f], planes[f], row, hi[i] - lo[i], eta):
                if fill:
                    out[m] = f
                m += 1
                c += 1
        counts[i] = c


def every(n_faces):
    """`candidates`' starts, stops and faces of one list (lists 0) that holds every face."""
    return np.zeros(1, np.int64), np.array([n_faces], np.int64), np.arange(n_faces, dtype=np.int64)


@njit
def reach(eta):
    """r / z at most on a path refracted into relative index eta > 1 (sin2 <= 1 / eta: r <= z / sqrt(eta^2 - 1));
    inf for eta <= 1."""
    return 1.0 / math.sqrt(eta * eta - 1.0) if eta > 1.0 else math.inf


@njit
def _may_light(tri, plane, row, end, eta):
    n0, n1, n2, cf = plane[0], plane[1], plane[2], plane[3]
    if n0 == 0.0 and n1 == 0.0 and n2 == 0.0:
        return False
    hl = n0 * row[6] + n1 * row[7] + n2 * row[8] - cf
    if hl == 0.0:
        return False
    e0, e1, e2 = row[0] + end * row[3], row[1] + end * row[4], row[2] + end * row[5]
    h0 = n0 * row[0] + n1 * row[1] + n2 * row[2] - cf
    h1 = n0 * e0 + n1 * e1 + n2 * e2 - cf
    if not (h0 * hl < 0.0 or h1 * hl < 0.0):
        return False
    size = abs(cf) + abs(row[6]) + abs(row[7]) + abs(row[8]) + abs(row[0]) + abs(e0) + abs(e1) + abs(e2)
    slack = 1e-9 * size
    wide = reach(eta) * max(abs(h0), abs(h1)) + slack
    for k in range(3):
        a, b = row[k] - h0 * plane[k], row[k] + end * row[3 + k] - h1 * plane[k]
        lo = max(min(a, b, row[6 + k] - hl * plane[k]), min(a, b) - wide)
        hi = min(max(a, b, row[6 + k] - hl * plane[k]), max(a, b) + wide)
        if hi < min(tri[0, k], tri[1, k], tri[2, k]) - slack or lo > max(tri[0, k], tri[1, k], tri[2, k]) + slack:
            return False
    return True


@njit
def _span(f0, f1, f2, l0, l1, l2, tri, n0, n1, n2):
    """The interval [lo, hi] of t in [0, 1] where f + t l (on the triangle's plane, unit normal n) lies inside
    the triangle (lo > hi: nowhere): each edge's side n·(u × (q - v)) is linear in t."""
    lo, hi = 0.0, 1.0
    u0, u1, u2 = tri[1, 0] - tri[0, 0], tri[1, 1] - tri[0, 1], tri[1, 2] - tri[0, 2]
    v0, v1, v2 = tri[2, 0] - tri[1, 0], tri[2, 1] - tri[1, 1], tri[2, 2] - tri[1, 2]
    turn = n0 * (u1 * v2 - u2 * v1) + n1 * (u2 * v0 - u0 * v2) + n2 * (u0 * v1 - u1 * v0)
    sign = 1.0 if turn > 0.0 else -1.0
    for k in range(3):
        v, e = tri[k], tri[(k + 1) % 3]
        ux, uy, uz = e[0] - v[0], e[1] - v[1], e[2] - v[2]
        px, py, pz = f0 - v[0], f1 - v[1], f2 - v[2]
        at0 = sign * (n0 * (uy * pz - uz * py) + n1 * (uz * px - ux * pz) + n2 * (ux * py - uy * px))
        slope = sign * (n0 * (uy * l2 - uz * l1) + n1 * (uz * l0 - ux * l2) + n2 * (ux * l1 - uy * l0))
        if slope > 0.0:
            lo = max(lo, -at0 / slope)
        elif slope < 0.0:
            hi = min(hi, -at0 / slope)
        elif at0 < 0.0:
            return 1.0, 0.0
    return lo, hi


@njit
def _snell(r, rho, z, hl, eta):
    """media/slab.py `refraction_point`'s Snell function (rho - r) / o - eta r / k, decreasing in r."""
    return (rho - r) / math.sqrt((rho - r) * (rho - r) + hl * hl) - eta * r / math.sqrt(r * r + z * z)


@njit
def _snell_root(lo, hi, rho, z, hl, eta):
    """The root of `_snell` in [lo, hi] (its value >= 0 at lo, <= 0 at hi): Newton's method, its derivative
    -hl^2 / o^3 - eta z^2 / k^3, kept inside the bracket (bisection where a step leaves it), to the
    resolution of doubles."""
    r = 0.5 * (lo + hi)
    for _ in range(100):
        o2, k2 = (rho - r) * (rho - r) + hl * hl, r * r + z * z
        o, k = math.sqrt(o2), math.sqrt(k2)
        value = (rho - r) / o - eta * r / k
        if value == 0.0:
            return r
        if value > 0.0:
            lo = r
        else:
            hi = r
        step = r - value / (-hl * hl / (o2 * o) - eta * z * z / (k2 * k))
        if not lo < step < hi:
            step = 0.5 * (lo + hi)
        if abs(step - r) <= 2e-16 * rho or not lo < step < hi:
            return step if lo <= step <= hi else r
        r = step
    return r


@njit
def _inside_triangle(q0, q1, q2, tri, n0, n1, n2):
    """Whether the point q, on the triangle's plane (unit normal n), lies inside it (edges included)."""
    ax, ay, az = tri[0, 0], tri[0, 1], tri[0, 2]
    bx, by, bz = tri[1, 0], tri[1, 1], tri[1, 2]
    cx, cy, cz = tri[2, 0], tri[2, 1], tri[2, 2]
    s = 0.0
    for k in range(3):
        if k == 0:
            ux, uy, uz, vx, vy, vz = bx - ax, by - ay, bz - az, q0 - ax, q1 - ay, q2 - az
        elif k == 1:
            ux, uy, uz, vx, vy, vz = cx - bx, cy - by, cz - bz, q0 - bx, q1 - by, q2 - bz
        else:
            ux, uy, uz, vx, vy, vz = ax - cx, ay - cy, az - cz, q0 - cx, q1 - cy, q2 - cz
        side = n0 * (uy * vz - uz * vy) + n1 * (uz * vx - ux * vz) + n2 * (ux * vy - uy * vx)
        if side * s < 0.0:
            return False
        if side != 0.0:
            s = side
    return True


@njit
def face_paths(seg, lists, x, geo, tris, planes, starts, stops, faces, eta, code, g, out):
    """The Fermat paths through single faces at the points x along segments seg (geo rows of media/slab.py
    GEO_COLUMNS: start, direction w, the light's position, a spot's axis, cone and curve), for the
    candidate faces faces[starts[lists[i]]:stops[lists[i]]] of each point i (`candidates`): where the face's
    plane separates X = p + x w from the light (normal n turned toward it: the light at height hl above
    the plane, X at depth z below it), R = X + z n + (r / rho) L_h (L_h the light's offset from X's foot,
    rho its length, r the root of Snell's law, `_snell_root`, sought only where the line from X's foot
    toward the light's crosses the triangle, `_span`) inside the triangle, one row of PATH_COLUMNS in out:
    the point's index, the face, R, media/slab.py `refracted_at`'s value per unit light without the
    exponential (ks = 1, kt = kt_out = 0: Phi(mu) E F), the legs' lengths k inside and o outside, and their
    cosines to the face's normal, z / k and hl / o. Returns the rows' count (at most out's rows; the caller
    sizes out by the candidates)."""
    m = 0
    for i in range(x.shape[0]):
        row = geo[seg[i]]
        X0, X1, X2 = row[0] + x[i] * row[3], row[1] + x[i] * row[4], row[2] + x[i] * row[5]
        r0, r1, r2 = row[6] - X0, row[7] - X1, row[8] - X2
        for j in range(starts[lists[i]], stops[lists[i]]):
            f = faces[j]
            n0, n1, n2 = planes[f, 0], planes[f, 1], planes[f, 2]
            hl = n0 * row[6] + n1 * row[7] + n2 * row[8] - planes[f, 3]
            z = planes[f, 3] - (n0 * X0 + n1 * X1 + n2 * X2)
            if hl < 0.0:  # the normal turned toward the light
                n0, n1, n2, hl, z = -n0, -n1, -n2, -hl, -z
            if not (hl > 0.0 and z > 0.0):
                continue
            up = hl + z
            l0, l1, l2 = r0 - up * n0, r1 - up * n1, r2 - up * n2
            f0, f1, f2 = X0 + z * n0, X1 + z * n1, X2 + z * n2  # X's foot; R lies between it and the light's
            lo, hi = _span(f0, f1, f2, l0, l1, l2, tris[f], n0, n1, n2)
            rho = math.sqrt(l0 * l0 + l1 * l1 + l2 * l2)
            lo, hi = max(lo - SPAN_SLACK, 0.0) * rho, min(hi + SPAN_SLACK, 1.0) * rho
            hi = min(hi, (1.0 + SPAN_SLACK) * reach(eta) * z)
            if lo > hi or _snell(lo, rho, z, hl, eta) < 0.0 or _snell(hi, rho, z, hl, eta) > 0.0:
                continue  # Snell's root lies outside the triangle's span
            r = _snell_root(lo, hi, rho, z, hl, eta)
            t = r / rho if rho > 0.0 else 0.0
            q0, q1, q2 = f0 + t * l0, f1 + t * l1, f2 + t * l2
            if not _inside_triangle(q0, q1, q2, tris[f], n0, n1, n2):
                continue
            a = -(n0 * row[3] + n1 * row[4] + n2 * row[5])
            wl = row[3] * l0 + row[4] * l1 + row[5] * l2
            na = n0 * row[9] + n1 * row[10] + n2 * row[11]
            la = l0 * row[9] + l1 * row[10] + l2 * row[11]
            value = refracted_at(0.0, z, rho, r, wl, a, hl, eta, 0.0, 1.0, code, g, 0.0, 0.0, la, na, row[12],
                                 row[13], row[17])
            if value == 0.0:
                continue
            k = math.sqrt(r * r + z * z)
            o = math.sqrt((rho - r) * (rho - r) + hl * hl)
            out[m, 0], out[m, 1], out[m, 2], out[m, 3], out[m, 4] = i, f, q0, q1, q2
            out[m, 5], out[m, 6], out[m, 7], out[m, 8], out[m, 9] = value, k, o, z / k if k > 0.0 else 1.0, hl / o
            m += 1
    return m



@njit
def face_breaks(geo, ell, tris, planes, starts, stops, faces, eta, scale):
    """The breaks of every candidate face's path along the segments (geo rows of media/slab.py GEO_COLUMNS;
    faces[starts[i]:stops[i]] for segment i: `candidates` over [0, ell[i]]): R crossing an edge of the face, a
    spot's leaving direction crossing a level of its cone (module docstring), as rows (segment, x, face, R (3))
    segment by segment, unsorted; and whether each segment's were all found (N,)."""
    out = np.empty((64, 6))
    m = 0
    found = np.ones(ell.shape[0], np.bool_)
    vec, e0, level, lip = np.empty((5, 3)), np.empty((5, 3)), np.empty(5), np.empty(5)
    stack = np.empty((128, 12))
    for s in range(ell.shape[0]):
        row = geo[s]
        p, w, light = row[0:3], row[3:6], row[6:9]
        for j in range(starts[s], stops[s]):
            f = faces[j]
            n, c, hl, z0, a, lo, hi = _face_frame(planes[f], p, w, light, ell[s])
            if not (hl > 0.0 and lo < hi and z0 + a * (0.5 * (lo + hi)) > 0.0):
                continue
            nf = _break_functions(tris[f], n, row, hl, vec, e0, level, lip)
            ok, out, m = _isolate(s, f, lo, hi, p + z0 * n, w + a * n, light - hl * n, z0, a, hl, eta, nf, vec, e0,
                                  level, lip, scale, stack, out, m)
            found[s] = found[s] and ok
    return out[:m].copy(), found


@njit
def _face_frame(plane, p, w, light, ell):
    """A face's plane seen from a segment (start p, direction w, length ell) and the light: its normal n and offset
    c turned toward the light, the light's height hl above it, the depth z0 of p below it and its rate a along
    w, and [lo, hi] where X lies below it."""
    n = plane[:3].copy()
    c = plane[3]
    hl = n @ light - c
    if hl < 0.0:
        n, c, hl = -n, -c, -hl
    z0, a = c - n @ p, -(n @ w)
    lo, hi = 0.0, ell
    if a > 0.0:
        lo = max(lo, -z0 / a)
    elif a < 0.0:
        hi = min(hi, z0 / -a)
    return n, c, hl, z0, a, lo, hi


@njit
def _break_functions(tri, n, row, hl, vec, e0, level, lip):
    """Fill vec, e0, level and lip (the factor of K_R in the Lipschitz bound) of the face's break functions
    (module docstring): its three edges (vec their inward normals in the plane, e0 their starts, level nan),
    then a spot's cone levels (vec its axis, e0 the light, lip 1 / hl); returns their number."""
    for k in range(3):
        e = tri[(k + 1) % 3] - tri[k]
        v = np.array([n[1] * e[2] - n[2] * e[1], n[2] * e[0] - n[0] * e[2], n[0] * e[1] - n[1] * e[0]])
        if v @ (tri[(k + 2) % 3] - tri[k]) < 0.0:
            v = -v
        vec[k], e0[k], level[k], lip[k] = v, tri[k], math.nan, math.sqrt(v @ v)
    m = 3
    if has_cone(row[13]):  # a spot: its cone's levels (cos_end, cos_start)
        for cut in (row[12], row[13]):
            if m == 4 and cut == row[12]:
                break
            vec[m], e0[m], level[m], lip[m] = row[9:12], row[6:9], cut, 1.0 / hl
            m += 1
    return m


@njit
def _values(x, pf, wh, lf, z0, a, hl, eta, nf, vec, e0, level, out):
    """The break functions at x (out[:nf]): R on the face's plane (Fermat's path, media/fermat_rounding.py
    `refraction_newton`), then v.(R - E0) of the edges and A.(R - L) / |R - L| - c of the cone's levels."""
    rp = _point(x, pf, wh, lf, z0, a, hl, eta)
    for k in range(nf):
        if math.isnan(level[k]):
            out[k] = vec[k] @ (rp - e0[k])
        else:
            q = rp - e0[k]
            out[k] = vec[k] @ q / math.sqrt(q @ q) - level[k]


@njit
def _point(x, pf, wh, lf, z0, a, hl, eta):
    """R at x: X's foot pf + x wh moved toward the light's foot lf by Snell's root."""
    xf = pf + x * wh
    d = lf - xf
    rho = math.sqrt(d @ d)
    if not rho > 0.0:
        return xf
    return xf + (refraction_newton(rho, max(z0 + a * x, 0.0), hl, eta) / rho) * d


@njit
def _isolate(s, f, lo, hi, pf, wh, lf, z0, a, hl, eta, nf, vec, e0, level, lip, scale, stack, out, m):
    """Append to out (`face_breaks`' rows) from m the roots in (lo, hi) of face f's break functions along segment
    s (module docstring); returns (whether all were found, out, m)."""
    width = RESOLUTION * scale
    tol = np.empty(nf)
    for k in range(nf):
        tol[k] = ROUNDING * scale * (lip[k] if math.isnan(level[k]) else lip[k] + 1.0)
    g = np.empty(nf)
    stack[0, 0], stack[0, 1] = lo, hi
    _values(lo, pf, wh, lf, z0, a, hl, eta, nf, vec, e0, level, stack[0, 2:7])
    _values(hi, pf, wh, lf, z0, a, hl, eta, nf, vec, e0, level, stack[0, 7:12])
    top, evals, ok = 1, 2, True
    while top > 0:
        top -= 1
        x0, x1 = stack[top, 0], stack[top, 1]
        g0, g1 = stack[top, 2:7].copy(), stack[top, 7:12].copy()
        d0, d1 = lf - pf - x0 * wh, lf - pf - x1 * wh
        speed = fermat_speed(math.sqrt(d0 @ d0), math.sqrt(d1 @ d1), min(z0 + a * x0, z0 + a * x1), a, eta)
        off, near = False, False
        for k in range(nf):
            span = lip[k] * speed * (x1 - x0)
            if math.isnan(level[k]) and g0[k] + g1[k] + 2.0 * tol[k] < -span:
                off = True  # R off the face all along
            near = near or not abs(g0[k]) + abs(g1[k]) > span + 2.0 * tol[k]
        if off or not near:
            continue
        if x1 - x0 <= width:
            for k in range(nf):
                if g0[k] * g1[k] < 0.0:
                    xb = _bisect(x0, x1, g0[k], k, pf, wh, lf, z0, a, hl, eta, nf, vec, e0, level, g)
                    out, m = _push(out, m, s, xb, f, _point(xb, pf, wh, lf, z0, a, hl, eta))
            continue
        if evals >= MAX_EVALS or top + 2 > stack.shape[0]:  # undecided: its ends are breaks
            out, m = _push(out, m, s, x0, f, _point(x0, pf, wh, lf, z0, a, hl, eta))
            out, m = _push(out, m, s, x1, f, _point(x1, pf, wh, lf, z0, a, hl, eta))
            ok = False
            continue
        mid = 0.5 * (x0 + x1)
        _values(mid, pf, wh, lf, z0, a, hl, eta, nf, vec, e0, level, g)
        evals += 1
        stack[top, 0], stack[top, 1], stack[top, 2:2 + nf], stack[top, 7:7 + nf] = mid, x1, g, g1[:nf]
        stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2:2 + nf], stack[top + 1, 7:7 + nf] = x0, mid, g0[:nf], g
        top += 2
    return ok, out, m


@njit
def _bisect(x0, x1, g0, k, pf, wh, lf, z0, a, hl, eta, nf, vec, e0, level, g):
    """The sign change of break function k in [x0, x1] (g0 its value at x0) to the resolution of doubles."""
    for _ in range(200):
        mid = 0.5 * (x0 + x1)
        if not x0 < mid < x1:
            break
        _values(mid, pf, wh, lf, z0, a, hl, eta, nf, vec, e0, level, g)
        if g[k] * g0 > 0.0:
            x0 = mid
        else:
            x1 = mid
    return 0.5 * (x0 + x1)


@njit
def _push(out, m, s, x, f, rp):
    if m == out.shape[0]:
        out = np.concatenate((out, np.empty_like(out)))
    out[m, 0], out[m, 1], out[m, 2], out[m, 3:6] = s, x, f, rp
    return out, m + 1


# rows of `lit_scan`: segment, face, x0, x1, kind (LIT or CLUSTER), the face's bare term at the cluster's ends (per
# unit light, no falloff nor exponential: at least its jump there), whether a spot's cone level may be crossed in it
SCAN_COLUMNS = 7
LIT, CLUSTER = 1.0, 2.0
U = 2.0 ** -53
SQ3 = math.sqrt(3.0)
ZERO = np.zeros(3)  # the light's speed in `_apex_states`
IN_LEG, OUT_LEG = 1, 2  # `_blockers`' flags: the triangle may meet the leg inside (X to R), outside (R to L)
FACE_POS, FACE_NEG = 4, 8  # and: the face lies on the closed positive (negative) side of the triangle's plane
O3D = (7.0 + 56.0 * 2.0 ** -53) * 2.0 ** -53  # Shewchuk's orient3d error bound's factor (errboundA)


@njit
def lit_scan(geo, ell, tris, planes, tree, starts, stops, faces, eta, dn, dc, code, g):
    """Where each candidate face lights each segment (faces[starts[s]:stops[s]] of segment s, geo rows of
    media/slab.py GEO_COLUMNS over [0, ell[s]]), proven: the rows (SCAN_COLUMNS) of the intervals where its
    path's refraction point lies inside it and both legs are clear of the shape's other triangles (LIT), and of
    the clusters of undecided intervals, each no wider than RESOLUTION x the scene's size, that hold every
    place where that may change or a spot's cone level be crossed (CLUSTER; module docstring of `_scan`); and
    whether every segment's scan finished (SCAN_EVALS evaluations per face, SCAN_WORK tests of other triangles per
    segment, the blockers kept by the culling included, eta > 1 and a finite tolerance). A face is first bracketed
    (`_face_span`: the stretch [a, b] outside which R is proven off it), then its blockers are culled by `face_tree`
    (`tree`) against the hulls its legs lie in over that stretch (`_blockers`).
    dn, dc: the planes' errors on each normal component and on the offsets (`plane_errors`)."""
    out = np.empty((64, SCAN_COLUMNS))
    m = 0
    found = np.ones(ell.shape[0], np.bool_)
    vec, e0, level, lip = np.empty((5, 3)), np.empty((5, 3)), np.empty(5), np.empty(5)
    vmax, cmax = 0.0, 0.0
    for t in range(tris.shape[0]):
        cmax = max(cmax, abs(planes[t, 3]))
        for k in range(3):
            vmax = max(vmax, math.sqrt(tris[t, k] @ tris[t, k]))
    blockers, flags = np.empty(tris.shape[0], np.int64), np.empty(tris.shape[0], np.int64)
    nodes = np.empty(tree[0].shape[0], np.int64)
    for s in range(ell.shape[0]):
        row = geo[s]
        p, w, light = row[0:3], row[3:6], row[6:9]
        if not eta > 1.0:
            found[s] = found[s] and starts[s] == stops[s]
            continue
        pn, ln = math.sqrt(p @ p), math.sqrt(light @ light)
        size = max(pn + ell[s], ln, vmax)
        mags = (pn, ln, math.sqrt((light - p) @ (light - p)), pn + ell[s] + ln + cmax)
        work = SCAN_WORK
        for j in range(starts[s], stops[s]):
            f = faces[j]
            n, c, hl, z0, a, lo, hi = _face_frame(planes[f], p, w, light, ell[s])
            if not (hl > 0.0 and lo < hi and z0 + a * (0.5 * (lo + hi)) > 0.0):
                continue
            if work <= 0:
                found[s] = False
                break
            pf, wh, lf = p + z0 * n, w + a * n, light - hl * n
            tol_r = _point_tolerance(lo, hi, pf, wh, lf, z0, a, hl, eta, dn, dc, mags)
            if not tol_r < math.inf:
                found[s] = False
                continue
            nf = _break_functions(tris[f], n, row, hl, vec, e0, level, lip)
            tol = _edge_tolerances(nf, level, lip, tol_r, dn, hl, size)
            xa, xb = _face_span(lo, hi, pf, wh, lf, z0, a, hl, eta, nf, vec, e0, level, lip, tol)
            if xa > xb:
                continue  # R off the face all along: dark
            nb = _blockers(tris, planes, tree, nodes, f, n, c, p + xa * w, p + xb * w, light, dn, dc, size,
                           blockers, flags)
            work -= max(nb, 0)
            if nb < 0:
                found[s] = False
                continue
            ok, out, m, work = _scan(work, s, f, lo, hi, ell[s], p, w, light, n, pf, wh, lf, z0, a, hl, eta, nf, vec,
                                     e0, level, lip, tol, tris, planes, blockers[:nb], flags[:nb], tol_r, dn, dc, size,
                                     code, g, out, m)
            found[s] = found[s] and ok
    return out[:m].copy(), found


@njit
def _point_tolerance(lo, hi, pf, wh, lf, z0, a, hl, eta, dn, dc, mags):
    """A bound on the error of the refraction point R over [lo, hi] (media/fermat_rounding.py `point_error` at the
    piece's worst: its largest x, legs and least horizontal distance rho, with `refraction_newton`'s 4e-16 rho of
    bisection, doubled); inf below the light (rho <= 1e-12 (hl + z) somewhere)."""
    d0, dw = lf - pf, wh @ wh
    r0, r1 = math.sqrt((d0 - lo * wh) @ (d0 - lo * wh)), math.sqrt((d0 - hi * wh) @ (d0 - hi * wh))
    rmin, rmax = min(r0, r1), max(r0, r1)
    if dw > 0.0:
        t = (d0 @ wh) / dw
        if lo < t < hi:
            rmin = math.sqrt(max((d0 - t * wh) @ (d0 - t * wh), 0.0))
    zmax = max(z0 + a * lo, z0 + a * hi)
    if not rmin > 1e-12 * (hl + zmax):
        return math.inf
    kmax = math.sqrt(rmax * rmax + zmax * zmax)
    return point_error(hi, kmax, rmax, hl, d0 @ d0, rmin, eta, dn, dc, mags, False) + 8.0 * U * rmax


@njit
def _edge_tolerances(nf, level, lip, tol_r, dn, hl, size):
    """The rounding allowed in the face's break functions at R (`_scan`'s module docstring): an edge's from R's
    tolerance tol_r and the planes' errors, a cone level's from tol_r over the light's height hl."""
    tol = np.empty(nf)
    for k in range(nf):
        if math.isnan(level[k]):
            tol[k] = lip[k] * tol_r + 8.0 * size * (SQ3 * dn + 16.0 * U) * (lip[k] + 1.0)
        else:
            tol[k] = 2.0 * tol_r / hl + 32.0 * U
    return tol


SPAN_DEPTH = 8  # `_face_span` halves [lo, hi] this many times at most


@njit
def _face_span(lo, hi, pf, wh, lf, z0, a, hl, eta, nf, vec, e0, level, lip, tol):
    """(xa, xb): the least and largest x of the pieces of [lo, hi] (halved at most SPAN_DEPTH times) where R is not
    proven off the face by `_scan`'s edge test (some edge function negative all along, tolerance tol); xa > xb
    where it is proven off all along. `_scan`'s dark intervals lie outside [xa, xb] (the same dyadic pieces and
    test), so the legs need be tested there alone."""
    stack = np.empty((SPAN_DEPTH + 2, 9))
    v0, v1 = np.empty(nf), np.empty(nf)
    stack[0, 0], stack[0, 1], stack[0, 8] = lo, hi, 0.0
    stack[0, 2:5], stack[0, 5:8] = _point(lo, pf, wh, lf, z0, a, hl, eta), _point(hi, pf, wh, lf, z0, a, hl, eta)
    top, xa, xb = 1, math.inf, -math.inf
    while top > 0:
        top -= 1
        x0, x1, depth = stack[top, 0], stack[top, 1], int(stack[top, 8])
        if x0 >= xa and x1 <= xb:
            continue  # inside the span already
        r0, r1 = stack[top, 2:5].copy(), stack[top, 5:8].copy()
        d0, d1 = lf - pf - x0 * wh, lf - pf - x1 * wh
        speed = fermat_speed(math.sqrt(d0 @ d0), math.sqrt(d1 @ d1), min(z0 + a * x0, z0 + a * x1), a, eta)
        _face_values(r0, nf, vec, e0, level, v0)
        _face_values(r1, nf, vec, e0, level, v1)
        dark = False
        for k in range(nf):
            if math.isnan(level[k]) and _state(v0[k], v1[k], lip[k] * speed * (x1 - x0), tol[k]) < 0:
                dark = True
        if dark:
            continue
        if depth >= SPAN_DEPTH:
            xa, xb = min(xa, x0), max(xb, x1)
            continue
        mid = 0.5 * (x0 + x1)
        rm = _point(mid, pf, wh, lf, z0, a, hl, eta)
        stack[top, 0], stack[top, 1], stack[top, 2:5], stack[top, 5:8], stack[top, 8] = mid, x1, rm, r1, depth + 1
        stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2:5], stack[top + 1, 5:8], stack[top + 1, 8] = \
            x0, mid, r0, rm, depth + 1
        top += 2
    return xa, xb


LEAF = 8  # `face_tree`'s triangles per leaf at most


@njit
def face_tree(tris):
    """A bounding-volume hierarchy over the triangles (T, 3, 3): (boxes (K, 2, 3): each node's least and largest
    corner, kids (K, 2): its children (-1 at a leaf), span (K, 2): a leaf's range in order, order (T,)): median
    splits of the centroids along their longest extent, at most LEAF triangles per leaf."""
    nt = tris.shape[0]
    order = np.arange(nt)
    cent = (tris[:, 0] + tris[:, 1] + tris[:, 2]) / 3.0
    size = max(2 * nt, 1)
    boxes, kids, span = np.empty((size, 2, 3)), np.full((size, 2), -1, np.int64), np.zeros((size, 2), np.int64)
    stack = np.empty((size, 3), np.int64)
    stack[0] = 0, 0, nt
    top, count = 1, 1
    while top > 0:
        top -= 1
        node, s, e = stack[top]
        boxes[node, 0], boxes[node, 1] = math.inf, -math.inf
        for i in range(s, e):
            for k in range(3):
                for c in range(3):
                    boxes[node, 0, c] = min(boxes[node, 0, c], tris[order[i], k, c])
                    boxes[node, 1, c] = max(boxes[node, 1, c], tris[order[i], k, c])
        if e - s <= LEAF:
            span[node] = s, e
            continue
        axis, best = 0, -1.0
        for c in range(3):
            ext = np.max(cent[order[s:e], c]) - np.min(cent[order[s:e], c])
            if ext > best:
                axis, best = c, ext
        part = order[s:e].copy()
        order[s:e] = part[np.argsort(cent[part, axis], kind="mergesort")]
        mid = (s + e) // 2
        kids[node] = count, count + 1
        stack[top], stack[top + 1] = (count, s, mid), (count + 1, mid, e)
        top += 2
        count += 2
    return boxes[:count].copy(), kids[:count].copy(), span[:count].copy(), order


@njit
def _hull_planes(pts, slack, margin, out):
    """Planes (rows a, b, c, d: a·v <= d inside, unnormalised) whose intersection holds the hull of the points pts
    (P, 3) with every point moved by at most slack: the hull's box, and the supporting planes through three of
    the points (degenerate triples skipped; both sides where the points are flat), each widened by 2 margin +
    slack |(a, b, c)| (margin bounds an evaluation's rounding: `_beyond` asks for more than margin beyond).
    Returns their number (out holds 6 + 2 C(P, 3))."""
    m = 0
    npt = pts.shape[0]
    for k in range(3):
        out[m], out[m + 1] = 0.0, 0.0
        out[m, k], out[m, 3] = 1.0, np.max(pts[:, k]) + 2.0 * margin + slack
        out[m + 1, k], out[m + 1, 3] = -1.0, -np.min(pts[:, k]) + 2.0 * margin + slack
        m += 2
    for i in range(npt):
        for j in range(i + 1, npt):
            for k in range(j + 1, npt):
                u, v = pts[j] - pts[i], pts[k] - pts[i]
                nv = np.array([u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]])
                norm = math.sqrt(nv @ nv)
                if not norm > 0.0:
                    continue
                d = nv @ pts[i]
                widen = 2.0 * margin + slack * norm
                hi, lo = -math.inf, math.inf
                for q in range(npt):
                    h = nv @ pts[q] - d
                    hi, lo = max(hi, h), min(lo, h)
                if hi <= margin:
                    out[m, :3], out[m, 3] = nv, d + widen
                    m += 1
                if lo >= -margin:
                    out[m, :3], out[m, 3] = -nv, -d + widen
                    m += 1
    return m


@njit
def _beyond(planes, nh, lo, hi, margin):
    """Whether the box [lo, hi] lies beyond one of the planes (`_hull_planes`) by more than margin."""
    for h in range(nh):
        least = 0.0
        for k in range(3):
            least += planes[h, k] * (lo[k] if planes[h, k] > 0.0 else hi[k])
        if least - planes[h, 3] > margin:
            return True
    return False


@njit
def _corners_beyond(planes, nh, tri, margin):
    """Whether the triangle's three corners lie beyond one of the planes (`_hull_planes`) by more than margin."""
    for h in range(nh):
        least = math.inf
        for k in range(3):
            least = min(least, planes[h, 0] * tri[k, 0] + planes[h, 1] * tri[k, 1] + planes[h, 2] * tri[k, 2])
        if least - planes[h, 3] > margin:
            return True
    return False


@njit
def _blockers(tris, planes, tree, nodes, f, n, c, x0, x1, light, dn, dc, size, out, flags):
    """The other triangles that may meet face f's legs over the stretch x0 x1 of X (out, with IN_LEG / OUT_LEG
    flags; returns their number, -1 where the light lies within rounding of one's plane): not within rounding of
    f's plane (its legs meet that plane at R alone), some corner below it (the side of X) and its box meeting the
    hull of X's stretch and f, which holds every inside leg X R (IN_LEG), some corner above it and its box meeting
    the hull of f and the light (OUT_LEG), found by descending `face_tree` (tree; nodes: its stack) with the
    boxes and then the corners tested against both hulls' planes (`_hull_planes`; an evaluation's rounding at most
    2048 u size^3, as the products of three differences of coordinates within size are; X within 8 u size)."""
    tol = dc + SQ3 * dn * size + 16.0 * U * size
    margin = 2048.0 * U * size ** 3
    pin, pout = np.empty((5, 3)), np.empty((4, 3))
    pin[0], pin[1], pin[2:] = x0, x1, tris[f]
    pout[0], pout[1:] = light, tris[f]
    hin, hout = np.empty((26, 4)), np.empty((14, 4))
    nin = _hull_planes(pin, 8.0 * U * size + tol, margin, hin)
    nout = _hull_planes(pout, tol, margin, hout)
    boxes, kids, span, order = tree
    m, top = 0, 1
    nodes[0] = 0
    while top > 0:
        top -= 1
        node = nodes[top]
        lo, hi = boxes[node, 0], boxes[node, 1]
        inside = not _beyond(hin, nin, lo, hi, margin)
        outside = not _beyond(hout, nout, lo, hi, margin)
        if not (inside or outside):
            continue
        if kids[node, 0] >= 0:
            nodes[top], nodes[top + 1] = kids[node, 0], kids[node, 1]
            top += 2
            continue
        for i in range(span[node, 0], span[node, 1]):
            t = order[i]
            if t == f or not _dot(planes[t, :3], planes[t, :3]) > 0.0:  # a degenerate triangle blocks nothing
                continue
            below, above = False, False
            for k in range(3):
                h = _dot(n, tris[t, k]) - c
                below = below or h < -tol
                above = above or h > tol
            fin = below and inside and not _corners_beyond(hin, nin, tris[t], margin)
            fout = above and outside and not _corners_beyond(hout, nout, tris[t], margin)
            hl = _dot(planes[t, :3], light) - planes[t, 3]
            if fout and abs(hl) <= tol:
                return -1
            side = _face_side(tris[t], tris[f])
            if side != 0:  # the face on one side of the plane: a leg whose apex lies strictly on it is clear
                fout = fout and hl * side < 0.0
                h0, h1 = _dot(planes[t, :3], x0) - planes[t, 3], _dot(planes[t, :3], x1) - planes[t, 3]
                fin = fin and not (h0 * side > tol + 8.0 * U * size and h1 * side > tol + 8.0 * U * size)
            if fin or fout:
                out[m] = t
                flags[m] = (IN_LEG if fin else 0) | (OUT_LEG if fout else 0) | (FACE_POS if side > 0 else 0) | \
                    (FACE_NEG if side < 0 else 0)
                m += 1
    return m


@njit
def _face_side(tri, face):
    """+1 (-1) where the face's three corners lie on the closed positive (negative) side of the exact plane through
    tri (its normal (B - A) x (C - A), as `face_planes`), not all on it; 0 where that is not proven. Each corner's
    side is the sign of Shewchuk's orient3d, certain beyond its error bound (O3D x the permanent), exactly 0 where
    every product is 0 (a shared corner)."""
    pos, neg = False, False
    for k in range(3):
        d = face[k]
        ax, ay, az = tri[0, 0] - d[0], tri[0, 1] - d[1], tri[0, 2] - d[2]
        bx, by, bz = tri[1, 0] - d[0], tri[1, 1] - d[1], tri[1, 2] - d[2]
        cx, cy, cz = tri[2, 0] - d[0], tri[2, 1] - d[1], tri[2, 2] - d[2]
        det = ax * (by * cz - bz * cy) + bx * (cy * az - cz * ay) + cx * (ay * bz - az * by)
        perm = (abs(by * cz) + abs(bz * cy)) * abs(ax) + (abs(cy * az) + abs(cz * ay)) * abs(bx) \
            + (abs(ay * bz) + abs(az * by)) * abs(cx)
        if det > O3D * perm:
            neg = True  # orient3d > 0: the corner below the plane (opposite its normal)
        elif det < -O3D * perm:
            pos = True
        elif perm != 0.0:
            return 0
    if pos and neg:
        return 0
    return 1 if pos else (-1 if neg else 0)


@njit
def _state(v0, v1, span, tol):
    """+1 (-1) where a function within tol of values v0, v1 at an interval's ends and changing by at most span
    over it is positive (negative) all along; 0: undecided."""
    if v0 + v1 > span + 2.0 * tol:
        return 1
    if v0 + v1 < -(span + 2.0 * tol):
        return -1
    return 0


@njit
def _scan(work, s, f, lo, hi, full, p, w, light, n, pf, wh, lf, z0, a, hl, eta, nf, vec, e0, level, lip, tol, tris,
          planes, blk, flags, tol_r, dn, dc, size, code, g, out, m):
    """`lit_scan` of face f along segment s over [lo, hi] (where X lies below its plane): an interval is decided
    (module docstring's Lipschitz tests, `_state`, on the values at its ends) where an edge function of the face
    is negative all along (R off the face: dark), where some other triangle blocks a leg all along (dark: the
    leg's ends on opposite sides of its plane, and the line from the leg's apex, X inside, the light outside,
    through the other end inside its three edges' planes, each sign proven), or where every edge function is
    positive, each cone level's sign proven and every other triangle proven clear of both legs (the ends on
    one side of its plane, or the edges' planes of opposite signs): LIT. A triangle proven clear of an interval
    is not tested on its parts (`drop`: the depth it was dropped at, reset for the next sibling). The others
    are halved down to RESOLUTION x size and appended as CLUSTER rows (adjacent ones merged). Lipschitz
    bounds with K_R = `fermat_speed`: an edge's or a plane's value at R, |v| K_R; a cone level, K_R / hl;
    a plane at X, |n·w|; the apex X's edge planes ((E_k - X) x (E_k+1 - X))·(R - X), whose derivative is
    (w x (E_k - E_k+1))·(R - X) + ((E_k - X) x (E_k+1 - X))·(R' - w): |e| |R - X| + |(E_k - X) x (E_k+1 - X)|
    (K_R + 1), the first at most the mean of its ends plus (K_R + 1) / 2 times the width, the second the
    larger of its ends (convex); the light's, |(E_k - L) x (E_k+1 - L)| K_R. Tolerances: R within tol_r
    (`_point_tolerance`; tol: the face's functions', `_edge_tolerances`), X within 8u size, the planes' errors
    dn, dc, and the products' rounding."""
    width = RESOLUTION * size
    tol_x = 8.0 * U * size
    tol_plane = dc + 2.0 * SQ3 * dn * size + 16.0 * U * size
    drop = np.full(blk.shape[0], 1 << 30)
    stack = np.empty((128, 9))
    stack[0, 0], stack[0, 1] = lo, hi
    stack[0, 2:5], stack[0, 5:8], stack[0, 8] = _point(lo, pf, wh, lf, z0, a, hl, eta), \
        _point(hi, pf, wh, lf, z0, a, hl, eta), 0.0
    top, evals, ok = 1, 2, True
    v0, v1 = np.empty(nf), np.empty(nf)
    while top > 0:
        top -= 1
        x0, x1, depth = stack[top, 0], stack[top, 1], int(stack[top, 8])
        r0, r1 = stack[top, 2:5].copy(), stack[top, 5:8].copy()
        for b in range(blk.shape[0]):
            if drop[b] >= depth:
                drop[b] = 1 << 30
        X0, X1 = p + x0 * w, p + x1 * w
        d0, d1 = lf - pf - x0 * wh, lf - pf - x1 * wh
        speed = fermat_speed(math.sqrt(d0 @ d0), math.sqrt(d1 @ d1), min(z0 + a * x0, z0 + a * x1), a, eta)
        _face_values(r0, nf, vec, e0, level, v0)
        _face_values(r1, nf, vec, e0, level, v1)
        dark, edges, cones = False, True, True
        for k in range(nf):
            st = _state(v0[k], v1[k], lip[k] * speed * (x1 - x0), tol[k])
            if math.isnan(level[k]):
                dark = dark or st < 0
                edges = edges and st > 0
            else:
                cones = cones and st != 0
        undecided = False
        if not dark:
            for b in range(blk.shape[0]):
                if drop[b] < depth:
                    continue
                work -= 1
                st = _leg_states(tris[blk[b]], planes[blk[b]], flags[b], X0, X1, r0, r1, w, light, n,
                                 speed, x1 - x0, tol_r, tol_x, tol_plane)
                if st < 0:
                    dark = True
                    break
                if st > 0:
                    drop[b] = depth
                else:
                    undecided = True
        if dark:
            continue
        if edges and cones and not undecided:
            if x0 == lo and lo > 0.0:  # X leaves the face's plane lit: a jump where no break may be cut
                jump = math.inf
                if lo <= width:  # but within width of the segment's start, a panel's end
                    jump = 2.0 * _plane_value(min(lo + width, x1), p, w, light, n, hl, z0, a, eta, code, g)
                out, m = _append(out, m, s, f, lo, lo, CLUSTER, jump if jump > 0.0 else math.inf, 1.0)
            out, m = _append(out, m, s, f, x0, x1, LIT, 0.0, 0.0)
            if x1 == hi and hi < full:
                jump = math.inf
                if full - hi <= width:  # within width of the segment's end
                    jump = 2.0 * _plane_value(max(hi - width, x0), p, w, light, n, hl, z0, a, eta, code, g)
                out, m = _append(out, m, s, f, hi, hi, CLUSTER, jump if jump > 0.0 else math.inf, 1.0)
            continue
        if x1 - x0 <= width:
            jump = 2.0 * max(_plane_value(x0, p, w, light, n, hl, z0, a, eta, code, g),
                             _plane_value(x1, p, w, light, n, hl, z0, a, eta, code, g))
            cone = 0.0
            for k in range(nf):
                if not math.isnan(level[k]) and not v0[k] * v1[k] > 0.0:
                    cone = 1.0
            out, m = _append(out, m, s, f, x0, x1, CLUSTER, jump, cone)
            continue
        if evals >= SCAN_EVALS or work <= 0 or top + 2 > stack.shape[0]:
            ok = False
            continue
        mid = 0.5 * (x0 + x1)
        rm = _point(mid, pf, wh, lf, z0, a, hl, eta)
        evals += 1
        stack[top, 0], stack[top, 1], stack[top, 2:5], stack[top, 5:8], stack[top, 8] = mid, x1, rm, r1, depth + 1
        stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2:5], stack[top + 1, 5:8], stack[top + 1, 8] = \
            x0, mid, r0, rm, depth + 1
        top += 2
    return ok, out, m, work


@njit
def _face_values(rp, nf, vec, e0, level, out):
    """The face's break functions at R = rp (out[:nf]): v·(R - E0) of its edges, A·(R - L) / |R - L| - c of the
    cone's levels."""
    for k in range(nf):
        q0, q1, q2 = rp[0] - e0[k, 0], rp[1] - e0[k, 1], rp[2] - e0[k, 2]
        g = vec[k, 0] * q0 + vec[k, 1] * q1 + vec[k, 2] * q2
        out[k] = g if math.isnan(level[k]) else g / math.sqrt(q0 * q0 + q1 * q1 + q2 * q2) - level[k]


@njit
def _leg_states(tri, plane, flag, X0, X1, r0, r1, w, light, nf, speed, width, tol_r, tol_x, tol_plane):
    """-1 where triangle tri blocks a leg all along the interval (`_scan`), +1 where it is clear of both, 0
    undecided. nf: the face's normal (R moves in its plane: a function u·R changes at |u - (u·nf) nf| K_R)."""
    n, c = plane[:3], plane[3]
    sr = _state(_dot(n, r0) - c, _dot(n, r1) - c, _along(n, nf) * speed * width, tol_plane + tol_r)
    clear = True
    side = 1 if flag & FACE_POS else (-1 if flag & FACE_NEG else 0)
    if flag & IN_LEG:
        sx = _state(_dot(n, X0) - c, _dot(n, X1) - c, abs(_dot(n, w)) * width, tol_plane + tol_x)
        if sx != 0 and (sx == sr or sx == side):
            clear = True
        else:
            st = _apex_states(tri, X0, X1, r0, r1, w, nf, speed, width, tol_r, tol_x)
            if sx != 0 and sr == -sx and abs(st) == 3:
                return -1
            clear = st == 0
    if flag & OUT_LEG:
        sl = 1 if _dot(n, light) - c > 0.0 else -1
        if sr != sl and sl != side:
            st = _apex_states(tri, light, light, r0, r1, ZERO, nf, speed, width, tol_r, 0.0)
            if sr == -sl and abs(st) == 3:
                return -1
            clear = clear and st == 0
    return 1 if clear else 0


@njit
def _dot(u, v):
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


@njit
def _along(u, nf):
    """|u - (u·nf) nf|: the part of u in the plane of unit normal nf."""
    d = _dot(u, nf)
    return math.sqrt(max(_dot(u, u) - d * d, 0.0))


@njit
def _apex_states(tri, Y0, Y1, r0, r1, v, nf, speed, width, tol_r, tol_y):
    """For the line from apex Y (Y0, Y1 at the interval's ends, moving at v: X along the segment, or the light)
    to R: +3 (-3) where its three edge planes' functions ((E_k - Y) x (E_k+1 - Y))·(R - Y) are all positive
    (negative) all along (`_scan`'s bounds, R' in the face's plane of normal nf), 0 where two have opposite
    signs all along, else 1. Each function's tolerance, with a = E_k - Y, b = E_k+1 - Y, r = R - Y at their
    largest over the ends: R within tol_r moves it by |a x b| tol_r, Y within tol_y by (|a||b| + |a||r| +
    |b||r|) tol_y (first order, both doubled), the products' rounding 32u |a||b||r|."""
    pos, neg = 0, 0
    moving = v[0] != 0.0 or v[1] != 0.0 or v[2] != 0.0
    q0 = math.sqrt((r0[0] - Y0[0]) ** 2 + (r0[1] - Y0[1]) ** 2 + (r0[2] - Y0[2]) ** 2)
    q1 = math.sqrt((r1[0] - Y1[0]) ** 2 + (r1[1] - Y1[1]) ** 2 + (r1[2] - Y1[2]) ** 2)
    q = max(q0, q1) + tol_r + tol_y
    for k in range(3):
        ka, kb = k, (k + 1) % 3
        g0, big0, par0 = _edge_plane(tri, ka, kb, Y0, r0, nf)
        g1, big1, par1 = _edge_plane(tri, ka, kb, Y1, r1, nf)
        la = max(_distance(tri[ka], Y0), _distance(tri[ka], Y1)) + tol_y
        lb = max(_distance(tri[kb], Y0), _distance(tri[kb], Y1)) + tol_y
        tol = 2.0 * ((max(big0, big1) + 4.0 * U * la * lb) * tol_r + (la * lb + la * q + lb * q) * tol_y) \
            + 32.0 * U * la * lb * q
        turn = max(par0, par1) * speed
        if moving:
            e = math.sqrt((tri[ka, 0] - tri[kb, 0]) ** 2 + (tri[ka, 1] - tri[kb, 1]) ** 2
                          + (tri[ka, 2] - tri[kb, 2]) ** 2)
            turn += e * 0.5 * (q0 + q1 + (speed + 1.0) * width) + max(big0, big1)
        st = _state(g0, g1, turn * width, tol)
        pos += st > 0
        neg += st < 0
    if pos and neg:
        return 0
    return 3 if pos == 3 else (-3 if neg == 3 else 1)


@njit
def _distance(a, b):
    return math.sqrt((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2 + (a[2] - b[2]) ** 2)


@njit
def _edge_plane(tri, ka, kb, y, r, nf):
    """(c·(R - Y), |c|, |c - (c·nf) nf|) of c = (E_ka - Y) x (E_kb - Y)."""
    ax, ay, az = tri[ka, 0] - y[0], tri[ka, 1] - y[1], tri[ka, 2] - y[2]
    bx, by, bz = tri[kb, 0] - y[0], tri[kb, 1] - y[1], tri[kb, 2] - y[2]
    cx, cy, cz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    cc = cx * cx + cy * cy + cz * cz
    cn = cx * nf[0] + cy * nf[1] + cz * nf[2]
    return (cx * (r[0] - y[0]) + cy * (r[1] - y[1]) + cz * (r[2] - y[2]), math.sqrt(cc),
            math.sqrt(max(cc - cn * cn, 0.0)))


@njit
def _plane_value(x, p, w, light, n, hl, z0, a, eta, code, g):
    """The face's path's value per unit light at x through its whole plane (normal n toward the light, at height
    hl above it; media/slab.py `refracted_at` with no falloff nor attenuation), 0 above the plane."""
    z = z0 + a * x
    if not z > 0.0:
        return 0.0
    l = light - (p + x * w) - (hl + z) * n
    rho = math.sqrt(l @ l)
    r = refraction_newton(rho, z, hl, eta)
    return refracted_at(0.0, z, rho, r, w @ l, a, hl, eta, 0.0, 1.0, code, g, 0.0, 0.0, 0.0, 0.0, NO_CONE[0],
                        NO_CONE[1], SMOOTHSTEP)


@njit
def _append(out, m, s, f, x0, x1, kind, jump, cone):
    """Append a `lit_scan` row, merged into the last where it continues it (same segment, face and kind)."""
    if m and out[m - 1, 0] == s and out[m - 1, 1] == f and out[m - 1, 4] == kind and out[m - 1, 3] == x0:
        out[m - 1, 3] = x1
        out[m - 1, 5] = max(out[m - 1, 5], jump)
        out[m - 1, 6] = max(out[m - 1, 6], cone)
        return out, m
    if m == out.shape[0]:
        out = np.concatenate((out, np.empty_like(out)))
    out[m, 0], out[m, 1], out[m, 2], out[m, 3], out[m, 4], out[m, 5], out[m, 6] = s, f, x0, x1, kind, jump, cone
    return out, m + 1


def plane_errors(tris, planes):
    """(dn, dc) of `face_planes` (T, 4) from the triangles (T, 3, 3) (each given exactly in float64: their edges are
    exact): a cross product's component is within 3u |e1| |e2| of the exact one, so a unit normal's within
    dn = 10u |e1| |e2| / |e1 x e2| + 4u, and an offset n·v0 within dc = sqrt(3) dn |v0| + 4u |v0| of the exact
    plane's through the triangle (largest over the triangles, degenerate ones left out)."""
    e1, e2 = tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    area = np.linalg.norm(np.cross(e1, e2), axis=1)
    live = area > 0.0
    if not np.any(live):
        return 0.0, 0.0
    dn = float(np.max(10.0 * U * np.linalg.norm(e1, axis=1)[live] * np.linalg.norm(e2, axis=1)[live] / area[live]))
    dn += 4.0 * U
    return dn, float(np.max((SQ3 * dn + 4.0 * U) * np.linalg.norm(tris[live, 0], axis=1)))


@njit
def scan_status(gid, x0, x1, kind, qgid, qx, first):
    """For each query (face key qgid = segment x faces + face, x), `lit_scan`'s kind there (rows sorted by key
    and x0: gid, x0, x1, kind; first: np.searchsorted(gid, qgid)): LIT, CLUSTER (a cluster's ends included), or
    0 (dark: no row holds x)."""
    out = np.zeros(qx.shape[0])
    for i in range(qx.shape[0]):
        j = first[i]
        while j < gid.shape[0] and gid[j] == qgid[i] and x0[j] <= qx[i]:
            if qx[i] <= x1[j] and (out[i] == 0.0 or kind[j] == CLUSTER):
                out[i] = kind[j]
            j += 1
    return out


@njit
def cluster_jumps(seg, x0, x1, jump, first, qseg, qx):
    """For each query (segment qseg, x), the sum of the jumps of `lit_scan`'s clusters that hold x, its ends included
    (cluster rows sorted by segment and x0: seg, x0, x1, jump; first: np.searchsorted(seg, qseg)): the most a node
    there may be off where the legs' tests decide a face the scan could not (interiors/paths.py
    `refracted_quadrature`)."""
    out = np.zeros(qx.shape[0])
    for i in range(qx.shape[0]):
        j = first[i]
        while j < seg.shape[0] and seg[j] == qseg[i] and x0[j] <= qx[i]:
            if qx[i] <= x1[j]:
                out[i] += jump[j]
            j += 1
    return out


@njit
def path_rounding(seg, x, face, rp, geo, planes, eta, ell, kts, kt_outs, code, g, dn, dc, cmax, eps, spot):
    """eps (M, C): a bound on the relative rounding of each path's term (point i: segment seg[i] at x[i], through
    face[i] at its refraction point rp[i] (`face_paths`'); channels kts, kt_outs) by media/fermat_rounding.py `term_rounding` in the face's frame (dn, dc the
    planes' errors, `plane_errors`; cmax the largest |c_f|; the phase's condition of code, g), and spot (M,) the
    falloff's absolute part where the leaving cosine lies within its error of the spot's band (media/slab.py
    `term_error`'s: the falloff's slope x the cosine's error x the term without falloff nor attenuation)."""
    ph = phase_condition(code, g)
    for i in range(x.shape[0]):
        row = geo[seg[i]]
        f = face[i]
        sg = 1.0 if _dot(planes[f, :3], row[6:9]) - planes[f, 3] >= 0.0 else -1.0  # the normal toward the light
        n0, n1, n2, c = sg * planes[f, 0], sg * planes[f, 1], sg * planes[f, 2], sg * planes[f, 3]
        hl = n0 * row[6] + n1 * row[7] + n2 * row[8] - c
        z0, a = c - (n0 * row[0] + n1 * row[1] + n2 * row[2]), -(n0 * row[3] + n1 * row[4] + n2 * row[5])
        u = z0 + x[i] * a  # X's foot: X + z n; the light's: L - hl n
        f0, f1, f2 = row[0] + x[i] * row[3] + u * n0, row[1] + x[i] * row[4] + u * n1, row[2] + x[i] * row[5] + u * n2
        d0, d1, d2 = row[6] - hl * n0 - f0, row[7] - hl * n1 - f1, row[8] - hl * n2 - f2
        b0, b1, b2 = row[6] - hl * n0 - row[0] - z0 * n0, row[7] - hl * n1 - row[1] - z0 * n1, \
            row[8] - hl * n2 - row[2] - z0 * n2  # at x = 0
        rho = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        r = math.sqrt((rp[i, 0] - f0) ** 2 + (rp[i, 1] - f1) ** 2 + (rp[i, 2] - f2) ** 2)
        pn, ln = math.sqrt(_dot(row, row)), math.sqrt(_dot(row[6:9], row[6:9]))
        lp = math.sqrt((row[6] - row[0]) ** 2 + (row[7] - row[1]) ** 2 + (row[8] - row[2]) ** 2)
        mags = (pn, ln, lp, pn + ell[seg[i]] + ln + cmax)
        dcos = 0.0
        for ch in range(kts.shape[0]):
            eps[i, ch], dcos = term_rounding(x[i], z0, a, hl, b0 * b0 + b1 * b1 + b2 * b2, rho, r, eta, kts[ch],
                                             kt_outs[ch], ph, dn, dc, mags, False)
        spot[i] = 0.0
        if has_cone(row[13]) and row[13] > row[12]:
            q = rp[i] - row[6:9]
            cos = row[9:12] @ q / math.sqrt(q @ q)
            if row[12] - dcos < cos < row[13] + dcos:
                spot[i] = band_slope(row[12], row[13], int(row[17])) / (row[13] - row[12]) * dcos * (1.0 + eps[i, 0]) \
                    * _plane_value(x[i], row[0:3], row[3:6], row[6:9], np.array([n0, n1, n2]), hl, z0, a, eta, code, g)
