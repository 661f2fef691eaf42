"""Exact lit intervals: the pieces of camera-ray segments that a light reaches, by shadow frusta.

A point P is in the shadow of triangle ABC under a point light L when the segment L-P crosses the
triangle: P lies inside the three planes through L and each edge (on the side of the third vertex)
and beyond the triangle's plane (on the side away from L). Under a directional light of travel
direction d the three edge planes contain d instead of L, and "beyond" is further along d. On a
segment P(x) = o + x w every one of these conditions is a x + b > 0 with a, b dot products, so a
triangle's frustum meets the segment in one interval, in closed form. A segment's shadowed set is
the union of those intervals over the triangles, its lit pieces the complement: no sampling, no
parameter that trades accuracy, boundaries exact to float64 geometry. Where frusta meet (a shared
edge, a vertex of a closed mesh, the surface a segment ends on), the roots of their different
planes may differ by rounding: a lit piece shorter than GAP_REL (64 ulps) of the scene's size is
that rounding, not light, and is dropped.

Exactness. Two triangles sharing an edge share the plane through it: the plane is computed from
the edge's vertices in one canonical order (lexicographic), so both triangles get the same root
bit for bit and their shadows meet without a gap; the side each keeps is a sign (that of the
orientation determinant D = det(A - L, B - L, C - L), resp. n . d). A triangle whose D is within
rounding of zero (seen exactly edge-on, or of zero area) has a frustum of no volume and is left
out, as are, for point lights, triangles whose plane passes within the shadow-ray epsilon of the
light (1e-5 of the scene's size; seen edge-on to within epsilon / distance radians): they are taken
to hold the light, so a light on a surface (placed on it up to rounding, on either side) lights
both sides of it. A segment that ends on a surface ends inside that triangle's frustum exactly
when the light is on the surface's far side, so no surface normal is needed.

Acceleration (memory linear in the triangle count for a given resolution): each light has a cube
map (point and spot lights, R x R texels per face) or an orthographic grid perpendicular to its
direction (directional lights) whose texels list the triangles whose frusta may meet them
(conservative rasterisation: clipped to the face, the texel's corners, dilated by DILATE, tested
against the triangle's edge planes), sorted by a lower bound on their distance from the light
(depth along the light for directional lights). A texel also keeps the nearest triangle covering
it whole and that triangle's farthest depth inside it; triangles wholly behind that depth are
dropped from the texel (their shadow there is inside the cover's). A segment walks the texels its
projection crosses (a DDA in the face's projective coordinates, linear in x along a face); per
texel run, a run nearer than every listed triangle is lit, a run beyond the cover is inside the
cover's frustum, and otherwise the listed triangles nearer than the run's far end are candidates.
Each candidate's exact interval is computed once per segment. The resolution is a speed hint
only: it can never change a result.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..geometry.sphere import lit_parts
from ..geometry.vectors import perpendicular
from ..jit import exact_njit, njit
from ..geometry.sorting import sort_few
from ..methods import Segments

DILATE = 1e-8  # texels are binned as if larger by this much (face units; grid size for the ortho grid)
REL = 1e-12  # relative slack of the depth comparisons
GAP_REL = 64 * 2.0**-52  # lit pieces shorter than this x the scene's size: rounding between frusta that meet
EDGE_ON = 8.0 * 2.0**-52  # |D| below this x |AB| |AC| |A - L| (or |n . d| below this x |AB| |AC|): no volume
CUBE, ORTHO = 0, 1
POINTS, SUNS, BOTH = 0, 1, 2  # the kinds of light a variant of the kernels serves (`_kernels`)

STATS_NAMES = ("segments searched", "texel runs", "runs nearer than every occluder", "runs behind a covering triangle",
               "frusta intersected", "shadow intervals", "lit intervals", "segments fully shadowed")
ST_SEGMENTS, ST_RUNS, ST_NEAR, ST_COVERED, ST_FRUSTA, ST_SHADOWS, ST_LIT, ST_DARK = range(len(STATS_NAMES))


@dataclass(frozen=True)
class LightBins:
    """One light's frusta and texel lists. `planes` (T, 4, 4): per kept triangle its three edge
    planes (canonical order) and its own plane as (nx, ny, nz, kappa): the condition is
    sign * (n . (P - origin) - kappa) > 0, `signs` (T, 4). `start` (texels + 1) and `tri`, `lb`:
    each texel's triangles and their depth lower bounds, ascending; `cover`, `cover_depth`: the
    covering triangle (-1: none) and its largest depth in the texel. `kind`: CUBE (texel
    (face, i, j) at (face nu + i) nv + j) or ORTHO (one face); `grid`: the face coordinates of
    texel (0, 0) and the texel sizes and counts; `frame` (4, 3): the origin of the planes (the
    light, or zero for the sun), the grid's axes u, v and the sun's direction of travel d. `kinds`:
    the variant of the kernels that built them (`_kernels`), which `lit_pieces` walks them with."""
    planes: np.ndarray
    signs: np.ndarray
    start: np.ndarray
    tri: np.ndarray
    lb: np.ndarray
    cover: np.ndarray
    cover_depth: np.ndarray
    kind: int
    res: int
    grid: np.ndarray  # (u0, v0, du, dv, nu, nv)
    frame: np.ndarray
    slack: float  # absolute slack of depth comparisons (REL x the scene's size)
    spheres: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))  # exact sphere occluders (geometry/sphere.py)
    kinds: int = BOTH


def default_resolution(n_triangles: int) -> int:
    """Texels per cube-face edge (per grid edge for directional lights): a power of two near
    sqrt(triangles) / 4, between 16 and 256 (measured on Sibenik: 64 for its 75,000 triangles)."""
    return int(min(256, max(16, 2 ** round(math.log2(max(n_triangles, 1) ** 0.5 / 4.0)))))


def build(accel, lights, resolution: int | None = None, select: np.ndarray | None = None,
          rows: np.ndarray | None = None) -> list[LightBins | None]:
    """The frusta and texel lists of every light (a list indexed like `lights`) of the triangles
    `select` (a boolean mask over accel.triangles; all if None); the exact spheres among them
    (accel.sphere_of) shadow as spheres (`LightBins.spheres`), not by their meshes. `rows` (a boolean
    mask over `lights`; None: all): the lights built, None in the others' places (the kernels' variant
    is still that of all of `lights`)."""
    select = np.ones(len(accel.triangles), bool) if select is None else select
    tris = accel.triangles[select & (accel.sphere_of < 0)]
    spheres = accel.spheres[np.unique(accel.sphere_of[select & (accel.sphere_of >= 0)])]
    res = resolution or default_resolution(len(tris))
    suns, points = bool(lights.distant.any()), bool((~lights.distant).any())
    out = []
    for li in range(len(lights)):
        if rows is not None and not rows[li]:
            out.append(None)
            continue
        if lights.distant[li]:
            bins = sun_bins(tris, lights.axis[li], accel.epsilon, accel.scale, res, points)
        else:
            frame = np.array([lights.position[li], [1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]])
            bins = _light_bins(tris, frame, False, res, accel.epsilon, REL * accel.scale, suns)
        out.append(replace(bins, spheres=spheres) if len(spheres) else bins)
    return out


def sun_bins(tris, axis, epsilon: float, scale: float, resolution: int | None = None,
             points: bool = False) -> LightBins:
    """The frusta and texel lists of the triangles `tris` (T, 3, 3) under a directional light whose
    direction of travel is `axis` (any length), for a scene of size `scale` and shadow-ray
    `epsilon`: `build`'s for one sun, for triangles that need not be the accelerator's (interiors/crossing.py
    builds them for the light refracted into a shape, from the triangles inside it). `points`: whether
    the scene has point lights too (`_variant`)."""
    d = axis / np.linalg.norm(axis)
    u = perpendicular(d)
    frame = np.array([np.zeros(3), u, np.cross(d, u), d])
    return _light_bins(tris, frame, True, resolution or default_resolution(len(tris)), epsilon, REL * scale, True,
                       points)


def _variant(points: bool, suns: bool) -> int:
    """The variant of the kernels (`_kernels`) for a scene with point lights (`points`) and suns
    (`suns`): each kind's code alone, or both in one specialisation."""
    return BOTH if points and suns else (SUNS if suns else POINTS)


def _light_bins(tris, frame, sun, res, epsilon, slack, suns=True, points=True) -> LightBins:
    """`sun_bins`' and `build`'s: `suns`, `points` whether the scene has directional and point lights
    (`_variant`)."""
    kinds = _variant(points, suns)
    _frusta, _bin, _ = _kernels(kinds)
    n_t = len(tris)
    planes, signs, lb, keep = np.zeros((n_t, 4, 4)), np.zeros((n_t, 4)), np.zeros(n_t), np.zeros(n_t, bool)
    _frusta(tris, frame[0], frame[3], epsilon, planes, signs, lb, keep, sun)
    planes, signs, lb = planes[keep], signs[keep], lb[keep]
    if sun:
        pu = np.einsum("tvk,k->tv", tris[keep], frame[1]) if len(lb) else np.zeros((0, 3))
        pv = np.einsum("tvk,k->tv", tris[keep], frame[2]) if len(lb) else np.zeros((0, 3))
        lo_u, hi_u = (pu.min(), pu.max()) if len(lb) else (0.0, 1.0)
        lo_v, hi_v = (pv.min(), pv.max()) if len(lb) else (0.0, 1.0)
        size = max(hi_u - lo_u, hi_v - lo_v, slack)
        nu = max(1, min(res, int(math.ceil(res * (hi_u - lo_u) / size))))
        nv = max(1, min(res, int(math.ceil(res * (hi_v - lo_v) / size))))
        du, dv = max(hi_u - lo_u, slack) / nu, max(hi_v - lo_v, slack) / nv
        grid = np.array([lo_u, lo_v, du, dv, nu, nv], float)
        kind, n_tex = ORTHO, nu * nv
    else:
        grid = np.array([-1.0, -1.0, 2.0 / res, 2.0 / res, res, res], float)
        kind, n_tex = CUBE, 6 * res * res
    rel = tris[keep] - (0.0 if sun else frame[0])
    count = np.zeros(n_tex + 1, np.int64)
    cover = np.full(n_tex, -1, np.int64)
    cover_depth = np.full(n_tex, np.inf)
    _bin(planes, signs, rel, res, grid, frame, np.arange(len(lb)), lb, True, count, count, count, lb, cover, cover_depth,
         sun)
    # the lists, filled in ascending depth lower bound (so each texel's is in order), less what its cover hides
    start = np.concatenate([[0], np.cumsum(count[:-1])]).astype(np.int64)
    tri, tlb, fill = np.empty(int(start[-1]), np.int64), np.empty(int(start[-1])), np.zeros(n_tex, np.int64)
    _bin(planes, signs, rel, res, grid, frame, np.argsort(lb, kind="stable"), lb, False, start, fill, tri, tlb, cover,
         cover_depth, sun)
    slot = np.arange(len(tri)) - np.repeat(start[:-1], count[:-1])
    kept = slot < np.repeat(fill, count[:-1])
    start = np.concatenate([[0], np.cumsum(fill)]).astype(np.int64)
    return LightBins(planes, signs, start, tri[kept], tlb[kept], cover, cover_depth, kind, res, grid, frame, slack,
                     kinds=kinds)


@exact_njit
def point_triangle_distance(px, py, pz, a, b, c):
    """Distance from the point p to the triangle abc (Ericson, Real-Time Collision Detection 5.1.5).
    Without fastmath: inlined into `_frusta`'s variants (with and without the sun's code) it rounds the
    same in each, so a scene's texel lists do not depend on which variant built them."""
    abx, aby, abz = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    acx, acy, acz = c[0] - a[0], c[1] - a[1], c[2] - a[2]
    apx, apy, apz = px - a[0], py - a[1], pz - a[2]
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return math.sqrt(apx * apx + apy * apy + apz * apz)
    bpx, bpy, bpz = px - b[0], py - b[1], pz - b[2]
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        return math.sqrt(bpx * bpx + bpy * bpy + bpz * bpz)
    cpx, cpy, cpz = px - c[0], py - c[1], pz - c[2]
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        return math.sqrt(cpx * cpx + cpy * cpy + cpz * cpz)
    vc = d1 * d4 - d3 * d2
    vb = d5 * d2 - d1 * d6
    va = d3 * d6 - d5 * d4
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        qx, qy, qz = a[0] + v * abx, a[1] + v * aby, a[2] + v * abz
    elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        v = d2 / (d2 - d6)
        qx, qy, qz = a[0] + v * acx, a[1] + v * acy, a[2] + v * acz
    elif va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        v = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        qx, qy, qz = b[0] + v * (c[0] - b[0]), b[1] + v * (c[1] - b[1]), b[2] + v * (c[2] - b[2])
    else:
        den = 1.0 / (va + vb + vc)
        v, w = vb * den, vc * den
        qx, qy, qz = a[0] + abx * v + acx * w, a[1] + aby * v + acy * w, a[2] + abz * v + acz * w
    return math.sqrt((px - qx) ** 2 + (py - qy) ** 2 + (pz - qz) ** 2)


@njit
def _less(a, b):
    """Lexicographic a < b of two points."""
    for k in range(3):
        if a[k] != b[k]:
            return a[k] < b[k]
    return False


@njit(inline="always")
def _side(planes, signs, t, p, x, y, z):
    """sign * (n . X - kappa) of plane p of triangle t at X = (x, y, z)."""
    return signs[t, p] * (planes[t, p, 0] * x + planes[t, p, 1] * y + planes[t, p, 2] * z - planes[t, p, 3])


@njit
def _face_bbox(rel, t, face, buf, buf2):
    """Bounding box (U0, U1, V0, V1) of triangle t's projection clipped to cube face `face`
    (U1 < U0 when it misses the face). Sutherland-Hodgman against |u| <= m, |v| <= m."""
    a = face // 2
    sg = 1.0 - 2.0 * (face % 2)
    n = 3
    for k in range(3):
        buf[k, 0] = sg * rel[t, k, a]
        buf[k, 1] = rel[t, k, (a + 1) % 3]
        buf[k, 2] = rel[t, k, (a + 2) % 3]
    slack = 1.0 + DILATE
    for c in range(4):
        axis = 1 + c // 2
        sgn = 1.0 if c % 2 == 0 else -1.0
        m = 0
        for k in range(n):
            k2 = (k + 1) % n
            f1 = buf[k, 0] * slack - sgn * buf[k, axis]
            f2 = buf[k2, 0] * slack - sgn * buf[k2, axis]
            if f1 >= 0.0:
                for e in range(3):  # element loops: row assignments compile numba's shape-error messages
                    buf2[m, e] = buf[k, e]
                m += 1
            if (f1 >= 0.0) != (f2 >= 0.0):
                s = f1 / (f1 - f2)
                for e in range(3):
                    buf2[m, e] = buf[k, e] + s * (buf[k2, e] - buf[k, e])
                m += 1
        n = m
        for k in range(n):
            for e in range(3):
                buf[k, e] = buf2[k, e]
        if n == 0:
            return 1.0, -1.0, 1.0, -1.0
    u0, u1, v0, v1 = 1.0, -1.0, 1.0, -1.0
    for k in range(n):
        if buf[k, 0] <= 0.0:
            return -1.0, 1.0, -1.0, 1.0  # touches the light's position: the whole face
        u, v = buf[k, 1] / buf[k, 0], buf[k, 2] / buf[k, 0]
        u0, u1, v0, v1 = min(u0, u), max(u1, u), min(v0, v), max(v1, v)
    return max(u0, -1.0), min(u1, 1.0), max(v0, -1.0), min(v1, 1.0)


@njit
def _crossing(a_x, b_x, a_m, b_m, c, x):
    """Where the coordinate (a_x + b_x x) / (a_m + b_m x) reaches c, ahead of x on the same branch
    (m > 0); inf if never. Scalars only (a helper taking arrays costs reference counts); LLVM inlines
    it, as numba's inline="always" did, which typed it again at each of its four call sites."""
    den = b_x - c * b_m
    if den == 0.0:
        return math.inf
    r = -(a_x - c * a_m) / den
    if not a_m + b_m * r > 0.0:
        return math.inf
    return max(r, x)


@njit
def _ortho_part(q, w, ell, grid, frame, out):
    """The part of a segment over the ortho grid (dilated), beyond which nothing casts a shadow: row
    (xa, xb, face, a_u, b_u, a_v, b_v, a_m, b_m) of `out` with grid coordinates U = (a_u + b_u x) /
    (a_m + b_m x), V alike, face 0, a_m = 1 and b_m = 0; returns 1, or 0 if it misses the grid."""
    u_0, v_0, du, dv, nu, nv = grid[0], grid[1], grid[2], grid[3], grid[4], grid[5]
    a_u, b_u = q @ frame[1], w @ frame[1]
    a_v, b_v = q @ frame[2], w @ frame[2]
    xa, xb = 0.0, ell
    for a_, b_, lo, hi in ((a_u, b_u, u_0 - DILATE * du * nu, u_0 + du * nu * (1.0 + DILATE)),
                           (a_v, b_v, v_0 - DILATE * dv * nv, v_0 + dv * nv * (1.0 + DILATE))):
        if b_ == 0.0:
            if not lo <= a_ <= hi:
                return 0
        else:
            r1, r2 = (lo - a_) / b_, (hi - a_) / b_
            xa, xb = max(xa, min(r1, r2)), min(xb, max(r1, r2))
    if not xa < xb:
        return 0
    out[0, 0], out[0, 1], out[0, 2] = xa, xb, 0.0
    out[0, 3], out[0, 4], out[0, 5], out[0, 6], out[0, 7], out[0, 8] = a_u, b_u, a_v, b_v, 1.0, 0.0
    return 1


@njit
def _cube_parts(q, w, ell, out):
    """The parts of a segment over one cube face each, split where the largest coordinate changes:
    rows of `out` as `_ortho_part`'s, with face coordinates U = (a_u + b_u x) / (a_m + b_m x), V
    alike, monotone in x on the part; returns their count."""
    roots = np.empty(8)
    nr = 1
    roots[0] = 0.0
    for a in range(3):
        b = (a + 1) % 3
        for sg in (1.0, -1.0):
            den = w[a] - sg * w[b]
            if den != 0.0:
                r = -(q[a] - sg * q[b]) / den
                if 0.0 < r < ell:
                    roots[nr] = r
                    nr += 1
    roots[nr] = ell
    nr += 1
    sort_few(roots, 0, nr - 1)  # the few interior roots (roots[0] = 0 is below them: it stays first)
    n = 0
    for p in range(nr - 1):
        xa, xb = roots[p], roots[p + 1]
        if not xb > xa:
            continue
        xm = 0.5 * (xa + xb) if xb < math.inf else xa + max(abs(xa), 1.0)
        best, a = -1.0, 0
        for c in range(3):
            v = abs(q[c] + xm * w[c])
            if v > best:
                best, a = v, c
        sg = 1.0 if q[a] + xm * w[a] > 0.0 else -1.0
        out[n, 0], out[n, 1], out[n, 2] = xa, xb, 2 * a + (0 if sg > 0.0 else 1)
        out[n, 3], out[n, 4] = q[(a + 1) % 3], w[(a + 1) % 3]
        out[n, 5], out[n, 6] = q[(a + 2) % 3], w[(a + 2) % 3]
        out[n, 7], out[n, 8] = sg * q[a], sg * w[a]
        n += 1
    return n


@njit
def _heapsort_pairs(a, b):
    """Sort a (no nan) ascending in place and b alongside, by heapsort (one sift loop, for the heap's
    construction and then its extraction): np.argsort would compile numba's quicksort (about
    1.5 s) for the shadow intervals of a segment. The order of equal a is arbitrary: the union of
    the intervals (a, b) does not depend on it."""
    start, end = a.shape[0] // 2, a.shape[0]
    while end > 1:
        if start > 0:
            start -= 1
        else:
            end -= 1
            a[0], a[end] = a[end], a[0]
            b[0], b[end] = b[end], b[0]
        root = start
        while 2 * root + 1 < end:
            child = 2 * root + 1
            if child + 1 < end and a[child] < a[child + 1]:
                child += 1
            if not a[root] < a[child]:
                break
            a[root], a[child] = a[child], a[root]
            b[root], b[child] = b[child], b[root]
            root = child


@functools.cache
def _kernels(kinds: int):
    """`_frusta`, `_bin` and `_lit` (module docstring) for the lights of `kinds` (`_variant`): every
    test of a light's kind reads the closure's constant `kinds`, so numba prunes the branches it
    makes dead before typing: POINTS compiles the cube map's code only, SUNS the ortho grid's only,
    BOTH both (the trailing `sun`, a bool, then chooses at run time: one specialisation, as two
    pruned ones would compile the texel walk they share twice). numba's cache keeps one entry per
    variant (its index key holds the closure's values)."""

    @njit
    def _frusta(tris, L, d, epsilon, planes, signs, lb, keep, sun):
        """Per triangle, into the zeroed arrays planes, signs, lb and keep: its four planes and their
        signs (LightBins), a lower bound on its depth from the light, and whether it is kept (not
        edge-on within rounding; for a point light, its plane not within epsilon of the light): under
        the sun of direction of travel d if `sun`, else under the point light L."""
        for t in range(tris.shape[0]):
            v = tris[t]
            e1 = v[1] - v[0]
            e2 = v[2] - v[0]
            nx = e1[1] * e2[2] - e1[2] * e2[1]
            ny = e1[2] * e2[0] - e1[0] * e2[2]
            nz = e1[0] * e2[1] - e1[1] * e2[0]
            size = math.sqrt(e1 @ e1) * math.sqrt(e2 @ e2)
            if kinds == SUNS or kinds == BOTH and sun:
                D = nx * d[0] + ny * d[1] + nz * d[2]
                if not abs(D) > EDGE_ON * size:
                    continue
                lb[t] = min(v[0] @ d, v[1] @ d, v[2] @ d)
            else:
                r0 = v[0] - L
                D = nx * r0[0] + ny * r0[1] + nz * r0[2]  # det(A - L, B - L, C - L)
                area2 = math.sqrt(nx * nx + ny * ny + nz * nz)
                if not (abs(D) > EDGE_ON * size * math.sqrt(r0 @ r0) and abs(D) > epsilon * area2):
                    continue
                lb[t] = point_triangle_distance(L[0], L[1], L[2], v[0], v[1], v[2])
            keep[t] = True
            s = 1.0 if D > 0.0 else -1.0
            for e in range(3):
                i, j = e, (e + 1) % 3
                flip = 1.0
                if _less(v[j], v[i]):
                    i, j = j, i
                    flip = -1.0
                a, b = v[i], v[j]
                ex, ey, ez = b[0] - a[0], b[1] - a[1], b[2] - a[2]
                if kinds == SUNS or kinds == BOTH and sun:  # d x (B - A), through A
                    px, py, pz = d[1] * ez - d[2] * ey, d[2] * ex - d[0] * ez, d[0] * ey - d[1] * ex
                    kappa = px * a[0] + py * a[1] + pz * a[2]
                else:  # (A - L) x (B - A), through L
                    rx, ry, rz = a[0] - L[0], a[1] - L[1], a[2] - L[2]
                    px, py, pz = ry * ez - rz * ey, rz * ex - rx * ez, rx * ey - ry * ex
                    kappa = 0.0
                planes[t, e, 0], planes[t, e, 1], planes[t, e, 2], planes[t, e, 3] = px, py, pz, kappa
                signs[t, e] = s * flip
            # own plane: beyond it from the light. Point light: s (n . (P - L)) - |D| > 0; sun: s n . (P - A) > 0
            planes[t, 3, 0], planes[t, 3, 1], planes[t, 3, 2] = nx, ny, nz
            own = D if kinds == POINTS or kinds == BOTH and not sun else nx * v[0][0] + ny * v[0][1] + nz * v[0][2]
            planes[t, 3, 3] = own
            signs[t, 3] = s

    @njit
    def _bin(planes, signs, rel, res, grid, frame, order, lb, counting, start, fill, tri, tlb, cover, cover_depth,
            sun):
        """Conservative rasterisation, the triangles taken in `order`: count (counting) each triangle in
        every texel it may meet into start[texel], and each texel's covering triangle of least largest
        depth (the first in `order` of equal ones); or list it, at start + fill of the texel, with its
        depth lower bound lb less REL (tlb), unless the texel's cover hides it (lb beyond cover_depth).
        `sun`: the ortho grid (ORTHO) if true, else a cube map (CUBE)."""
        u_0, v_0, du, dv, nu, nv = grid[0], grid[1], grid[2], grid[3], int(grid[4]), int(grid[5])
        faces = 6 if kinds == POINTS or kinds == BOTH and not sun else 1
        buf, buf2 = np.empty((8, 3)), np.empty((8, 3))
        cs = np.empty((4, 3))
        du_d = DILATE * (du * nu if kinds == SUNS or kinds == BOTH and sun else 1.0)
        dv_d = DILATE * (dv * nv if kinds == SUNS or kinds == BOTH and sun else 1.0)
        dd = frame[3]
        cn, pn = np.empty(4), np.empty(3)
        for it in range(order.shape[0]):
            t = order[it]
            for p in range(3):
                pn[p] = math.sqrt(planes[t, p, 0] ** 2 + planes[t, p, 1] ** 2 + planes[t, p, 2] ** 2)
            for face in range(faces):
                if kinds == POINTS or kinds == BOTH and not sun:
                    U0, U1, V0, V1 = _face_bbox(rel, t, face, buf, buf2)
                    if U1 < U0 or V1 < V0:
                        continue
                else:
                    U0, U1, V0, V1 = math.inf, -math.inf, math.inf, -math.inf
                    for k in range(3):
                        pu, pv = rel[t, k] @ frame[1], rel[t, k] @ frame[2]
                        U0, U1, V0, V1 = min(U0, pu), max(U1, pu), min(V0, pv), max(V1, pv)
                i0 = max(int(math.floor((U0 - du_d - u_0) / du)), 0)
                i1 = min(int(math.floor((U1 + du_d - u_0) / du)), nu - 1)
                j0 = max(int(math.floor((V0 - dv_d - v_0) / dv)), 0)
                j1 = min(int(math.floor((V1 + dv_d - v_0) / dv)), nv - 1)
                for i in range(i0, i1 + 1):
                    for j in range(j0, j1 + 1):
                        for c in range(4):
                            U = u_0 + (i + c % 2) * du + (du_d if c % 2 else -du_d)
                            V = v_0 + (j + c // 2) * dv + (dv_d if c // 2 else -dv_d)
                            if kinds == POINTS or kinds == BOTH and not sun:  # a direction from the light on `face`
                                a = face // 2
                                cs[c, a] = 1.0 - 2.0 * (face % 2)
                                cs[c, (a + 1) % 3] = U
                                cs[c, (a + 2) % 3] = V
                            else:  # a point of the ortho grid's plane
                                for k in range(3):
                                    cs[c, k] = U * frame[1, k] + V * frame[2, k]
                        for c in range(4):
                            cn[c] = math.sqrt(cs[c, 0] ** 2 + cs[c, 1] ** 2 + cs[c, 2] ** 2)
                        inside_all = True
                        out = False
                        for p in range(3):
                            n_out = 0
                            for c in range(4):
                                tol = REL * (pn[p] * cn[c] + abs(planes[t, p, 3]))
                                s = _side(planes, signs, t, p, cs[c, 0], cs[c, 1], cs[c, 2])
                                if s < -tol:
                                    n_out += 1
                                if not s > tol:
                                    inside_all = False
                            if n_out == 4:
                                out = True
                                break
                        if out:
                            continue
                        tex = (face * nu + i) * nv + j
                        if counting:
                            start[tex] += 1
                            if inside_all:  # the texel lies inside the frustum's cone: the largest depth at a corner
                                depth = 0.0
                                for c in range(4):
                                    x, y, z = cs[c, 0], cs[c, 1], cs[c, 2]
                                    nc = planes[t, 3, 0] * x + planes[t, 3, 1] * y + planes[t, 3, 2] * z
                                    if kinds == POINTS or kinds == BOTH and not sun:  # own plane n . X = D at X = s c
                                        s = planes[t, 3, 3] / nc if nc != 0.0 else math.inf
                                        depth = max(depth, s * cn[c] if s > 0 else math.inf)
                                    else:  # along c + s d
                                        nd = planes[t, 3, 0] * dd[0] + planes[t, 3, 1] * dd[1] + planes[t, 3, 2] * dd[2]
                                        depth = max(depth, (planes[t, 3, 3] - nc) / nd)
                                depth += REL * abs(depth)
                                if depth < cover_depth[tex]:
                                    cover_depth[tex] = depth
                                    cover[tex] = t
                        elif not lb[t] > cover_depth[tex]:
                            tri[start[tex] + fill[tex]] = t
                            tlb[start[tex] + fill[tex]] = lb[t] - REL * abs(lb[t])
                            fill[tex] += 1

    @njit
    def _lit(origins, dirs, length, grid, frame, start, tri, lb, cover, cover_depth, planes, signs, slack, gap, stats,
            sun):
        """(segment, x0, x1) of every lit piece of every segment, in segment order. Per segment: each
        face part is walked texel by texel (a DDA); each texel run is lit (nearer than every listed
        triangle), inside the cover's frustum, or gives candidates (module docstring), whose exact
        frustum intervals are computed once per segment; the lit pieces are the complement of their
        union. One flat loop: helpers taking arrays, even inlined, cost reference counts per call. `sun`:
        as `_bin`'s."""
        n_t = planes.shape[0]
        stamp = np.empty(n_t, np.int64)
        for t in range(n_t):
            stamp[t] = -1
        c_lo, c_hi = np.empty(n_t + 1), np.empty(n_t + 1)
        cap = 2 * origins.shape[0] + 16
        src, x0, x1 = np.empty(cap, np.int64), np.empty(cap), np.empty(cap)
        m = 0
        parts = np.empty((8, 9))
        q = np.empty(3)
        d = frame[3]
        u_0, v_0, du, dv, nu, nv = grid[0], grid[1], grid[2], grid[3], int(grid[4]), int(grid[5])
        n_runs = n_near = n_cov = n_fr = 0
        for s in range(origins.shape[0]):
            ell = length[s]
            w = dirs[s]
            for a in range(3):
                q[a] = origins[s, a] - (frame[0, a] if kinds == POINTS or kinds == BOTH and not sun else 0.0)
            k = 0
            n_parts = 0
            if n_t and ell > 0.0:
                if kinds == SUNS or kinds == BOTH and sun:
                    n_parts = _ortho_part(q, w, ell, grid, frame, parts)
                else:
                    n_parts = _cube_parts(q, w, ell, parts)
            for p in range(n_parts):
                xa, xb, face = parts[p, 0], parts[p, 1], int(parts[p, 2])
                a_u, b_u, a_v, b_v = parts[p, 3], parts[p, 4], parts[p, 5], parts[p, 6]
                a_m, b_m = parts[p, 7], parts[p, 8]
                den = a_m + b_m * xa
                if den > 0.0:
                    U, V = (a_u + b_u * xa) / den, (a_v + b_v * xa) / den
                else:  # the part starts at the light: the limit along the ray
                    U, V = b_u / b_m, b_v / b_m
                i = min(max(int(math.floor((U - u_0) / du)), 0), nu - 1)
                j = min(max(int(math.floor((V - v_0) / dv)), 0), nv - 1)
                su = b_u * a_m - a_u * b_m
                sv = b_v * a_m - a_v * b_m
                x = xa
                while True:
                    xu = math.inf
                    if su > 0.0 and i < nu - 1:
                        xu = _crossing(a_u, b_u, a_m, b_m, u_0 + (i + 1) * du, x)
                    elif su < 0.0 and i > 0:
                        xu = _crossing(a_u, b_u, a_m, b_m, u_0 + i * du, x)
                    xv = math.inf
                    if sv > 0.0 and j < nv - 1:
                        xv = _crossing(a_v, b_v, a_m, b_m, v_0 + (j + 1) * dv, x)
                    elif sv < 0.0 and j > 0:
                        xv = _crossing(a_v, b_v, a_m, b_m, v_0 + j * dv, x)
                    xn = min(xu, xv, xb)
                    # --- the run [x, xn] through texel tex
                    tex = (face * nu + i) * nv + j
                    n_runs += 1
                    first, last = start[tex], start[tex + 1]
                    if first == last:
                        n_near += 1
                    else:
                        if kinds == POINTS or kinds == BOTH and not sun:
                            r1 = math.sqrt((q[0] + x * w[0]) ** 2 + (q[1] + x * w[1]) ** 2 + (q[2] + x * w[2]) ** 2)
                            r2 = math.inf
                            if xn < math.inf:
                                r2 = math.sqrt((q[0] + xn * w[0]) ** 2 + (q[1] + xn * w[1]) ** 2
                                               + (q[2] + xn * w[2]) ** 2)
                            rmax, rmin = max(r1, r2), min(r1, r2)
                            xh = -(q[0] * w[0] + q[1] * w[1] + q[2] * w[2])
                            if x < xh < xn:  # the foot point: the nearest to the light
                                rmin = math.sqrt((q[0] + xh * w[0]) ** 2 + (q[1] + xh * w[1]) ** 2
                                                 + (q[2] + xh * w[2]) ** 2)
                        else:
                            z0 = q[0] * d[0] + q[1] * d[1] + q[2] * d[2]
                            dz = w[0] * d[0] + w[1] * d[1] + w[2] * d[2]
                            z1 = z0 + x * dz
                            z2 = z0 + xn * dz if xn < math.inf else (z0 if dz == 0.0 else math.copysign(math.inf, dz))
                            rmax, rmin = max(z1, z2), min(z1, z2)
                        far = rmax + REL * abs(rmax) + slack
                        near = rmin - REL * abs(rmin) - slack
                        covered = near > cover_depth[tex]
                        if far < lb[first]:
                            n_near += 1
                            last = first
                        elif covered:  # the cover's frustum holds the whole run: the only candidate
                            n_cov += 1
                            last = first + 1
                        for e in range(first, last):
                            if covered:
                                t = cover[tex]
                            elif lb[e] >= far:
                                break
                            else:
                                t = tri[e]
                            if stamp[t] == s:
                                continue
                            stamp[t] = s
                            n_fr += 1
                            lo, hi = 0.0, ell
                            for pl in range(4):  # sign * (a + b x) > 0 for every plane
                                av = planes[t, pl, 0] * q[0] + planes[t, pl, 1] * q[1] + planes[t, pl, 2] * q[2] \
                                    - planes[t, pl, 3]
                                bv = planes[t, pl, 0] * w[0] + planes[t, pl, 1] * w[1] + planes[t, pl, 2] * w[2]
                                sg = signs[t, pl]
                                if bv == 0.0:
                                    if not sg * av > 0.0:
                                        hi = -math.inf
                                elif sg * bv > 0.0:
                                    lo = max(lo, -av / bv)
                                else:
                                    hi = min(hi, -av / bv)
                                if not lo < hi:
                                    break
                            if lo < hi:
                                c_lo[k], c_hi[k] = lo, hi
                                k += 1
                    # ---
                    if xn >= xb:
                        break
                    if xu <= xv:
                        i += 1 if su > 0.0 else -1
                    else:
                        j += 1 if sv > 0.0 else -1
                    x = xn
            stats[ST_SHADOWS] += k
            if m + k + 1 > cap:
                cap = 2 * (m + k + 1)
                src2, a2, b2 = np.empty(cap, np.int64), np.empty(cap), np.empty(cap)
                for e in range(m):  # an element loop: slice assignments compile numba's shape-error messages
                    src2[e], a2[e], b2[e] = src[e], x0[e], x1[e]
                src, x0, x1 = src2, a2, b2
            before = m
            cur = 0.0
            if k:
                _heapsort_pairs(c_lo[:k], c_hi[:k])
                for e in range(k):
                    if c_lo[e] - cur > gap:
                        src[m], x0[m], x1[m] = s, cur, c_lo[e]
                        m += 1
                    cur = max(cur, c_hi[e])
            if ell - cur > gap:
                src[m], x0[m], x1[m] = s, cur, ell
                m += 1
            if m == before:
                stats[ST_DARK] += 1
        stats[ST_RUNS] += n_runs
        stats[ST_NEAR] += n_near
        stats[ST_COVERED] += n_cov
        stats[ST_FRUSTA] += n_fr
        stats[ST_LIT] += m
        return src[:m].copy(), x0[:m].copy(), x1[:m].copy()

    return _frusta, _bin, _lit


_frusta_points = _kernels(POINTS)[0]  # `_point_lit`'s (its point lights)


def exact_lit_intervals(accel, segs: Segments, lights, n_lights: int, bins: list[LightBins] | None = None):
    """The lit pieces of `segs` as new segments (each from its own start point, t0 along the camera
    ray, stream + n_lights x piece number), and the statistics
    (STATS_NAMES). `bins`: `build(accel, lights)`, built here if None (build it once per scene)."""
    bins = build(accel, lights) if bins is None else bins
    stats = np.zeros(len(STATS_NAMES))
    src, x0, x1 = lit_pieces(segs, bins, accel.scale, stats)
    piece = np.arange(len(src)) - np.searchsorted(src, src)
    return _take(segs, src, x0, x1, segs.stream[src] + n_lights * piece), stats


def split_lit(accel, segs: Segments, n_lights: int, bins: list[LightBins]):
    """`segs` cut into the pieces outside every frustum of `bins` (their light reaches them past no
    triangle of the bins: `clear`) and the pieces inside one (`behind`), as segments from their own
    start points, and the statistics (STATS_NAMES). Streams are renumbered per camera ray and light
    over the clear pieces (light + n_lights x rank, as whole rays number them); the behind pieces
    keep their segment's (interiors/rows.py integrates them without random numbers)."""
    stats = np.zeros(len(STATS_NAMES))
    src, x0, x1 = lit_pieces(segs, bins, accel.scale, stats)
    clear = _take(segs, src, x0, x1, np.zeros(len(src), np.int64))
    order = np.lexsort((clear.t0, clear.light, clear.ray))
    clear = clear.take(order)
    group = clear.ray * n_lights + clear.light
    rank = np.arange(len(group)) - np.searchsorted(group, group)
    clear = Segments(clear.origins, clear.dirs, clear.length, clear.light, clear.ray, clear.t0, clear.keys,
                     clear.light + n_lights * rank, segs.seed, segs.scale)
    # the gaps between each segment's clear pieces: from 0 and from every piece's end to the next start
    n, m = len(segs), len(src)
    count = np.bincount(src, minlength=n)
    at = np.arange(m) + src  # piece i's slot in the gaps list (a segment s has count[s] + 1 slots)
    g0, g1 = np.zeros(n + m), np.empty(n + m)
    g0[at + 1] = x1
    g1[at] = x0
    g1[np.cumsum(count + 1) - 1] = segs.length
    parent = np.repeat(np.arange(n), count + 1)
    with np.errstate(invalid="ignore"):  # inf - inf after a piece to infinity: no gap
        keep = g1 - g0 > GAP_REL * accel.scale
    behind = _take(segs, parent[keep], g0[keep], g1[keep], segs.stream[parent[keep]])
    return clear, behind, stats


def lit_pieces(segs: Segments, bins: list[LightBins], scale: float, stats):
    """(segment, x0, x1) of the lit pieces of `segs` under `bins` (indexed by segs.light) in a scene
    of size `scale`, in segment order and, per segment, in x; the statistics add to `stats`."""
    stats[ST_SEGMENTS] += len(segs)
    srcs, a, b = [np.zeros(0, np.int64)], [np.zeros(0)], [np.zeros(0)]
    for li in np.unique(segs.light):
        idx = np.nonzero(segs.light == li)[0]
        lb_ = bins[li]
        src, x0, x1 = _kernels(lb_.kinds)[2](
                           np.ascontiguousarray(segs.origins[idx]), np.ascontiguousarray(segs.dirs[idx]),
                           np.ascontiguousarray(segs.length[idx]), lb_.grid, lb_.frame, lb_.start, lb_.tri,
                           lb_.lb, lb_.cover, lb_.cover_depth, lb_.planes, lb_.signs, lb_.slack,
                           GAP_REL * scale, stats, lb_.kind == ORTHO)
        if len(lb_.spheres):
            sun = lb_.kind == ORTHO
            src, x0, x1 = _cut_by_spheres(src, x0, x1, segs.origins[idx], segs.dirs[idx],
                                          -lb_.frame[3] if sun else lb_.frame[0], sun, lb_.spheres, GAP_REL * scale)
        srcs.append(idx[src])
        a.append(x0)
        b.append(x1)
    src, x0, x1 = np.concatenate(srcs), np.concatenate(a), np.concatenate(b)
    order = np.argsort(src, kind="stable")
    return src[order], x0[order], x1[order]


@njit
def _cut_by_spheres(src, x0, x1, origins, dirs, light, sun, spheres, gap):
    """The lit pieces (src, x0, x1) less the shadows of the exact spheres (geometry/sphere.py, lit_parts):
    `light` the point light's position, or (sun) the unit direction toward the light."""
    per = 4 * spheres.shape[0] + 1
    o_src, o0, o1 = np.empty(len(src) * per, np.int64), np.empty(len(src) * per), np.empty(len(src) * per)
    buf = np.empty((per, 2))
    m = 0
    for i in range(len(src)):
        k = lit_parts(origins[src[i]], dirs[src[i]], x0[i], x1[i], light, sun, spheres, gap, buf)
        for j in range(k):
            o_src[m], o0[m], o1[m] = src[i], buf[j, 0], buf[j, 1]
            m += 1
    return o_src[:m], o0[:m], o1[:m]


def _take(segs, src, x0, x1, stream):
    """Pieces [x0, x1] of segments `src` as segments from their own start points."""
    return Segments(segs.origins[src] + x0[:, None] * segs.dirs[src], segs.dirs[src], x1 - x0, segs.light[src],
                    segs.ray[src], segs.t0[src] + x0, segs.keys[src], stream, segs.seed, segs.scale)


def point_lit_pieces(accel, segs: Segments, points, group, box_of, select: np.ndarray | None):
    """(segment, x0, x1) of the lit pieces of `segs` each under its own point light `points` (S, 3)
    (an emitter's samples: no texel lists, which are per fixed light), in segment order and per
    segment in x, by the same exact frusta as `lit_pieces`: the candidates of segment s are the
    triangles of `select` (a mask over accel.triangles; None: all) whose bounding boxes meet the box
    of its `group` (S,) (box_of: (G, 3) lows, (G, 3) highs; it must hold the group's points and
    segments; recomputed where the group changes from one segment to the next), the exact spheres
    among them shadowing as spheres."""
    select = np.ones(len(accel.triangles), bool) if select is None else select
    tris = np.ascontiguousarray(accel.triangles[select & (accel.sphere_of < 0)])
    spheres = accel.spheres[np.unique(accel.sphere_of[select & (accel.sphere_of >= 0)])]
    return _point_lit(tris, tris.min(axis=1), tris.max(axis=1), np.ascontiguousarray(segs.origins),
                      np.ascontiguousarray(segs.dirs), np.ascontiguousarray(segs.length), np.ascontiguousarray(points),
                      np.asarray(group, np.int64), box_of[0], box_of[1], accel.epsilon, REL * accel.scale,
                      GAP_REL * accel.scale, np.ascontiguousarray(spheres, dtype=np.float64).reshape(-1, 4), False)


@njit
def _point_lit(tris, t_lo, t_hi, origins, dirs, length, points, group, g_lo, g_hi, epsilon, slack, gap, spheres, sun):
    """`point_lit_pieces`' kernel: per group its candidate triangles (bounding boxes overlapping); per
    segment those that meet the plane through its point and its line (within rounding), their frusta
    from the point (`_frusta`), each clipped to the segment directly where `_lit` would take it as a
    candidate in a cube map of one texel a face (its depth lower bound below the far end, with the
    same slack, of one of the segment's face parts: every triangle is listed in every face) and by
    `_lit`'s expressions, without its lists, walk and buffers per segment (the pieces `_lit`'s bit for
    bit under the same fastmath flags: tests/test_penumbra_glue.py); then the
    spheres' shadows (`lit_parts`). `sun`: False, passed from Python so that `_frusta` gets the bool
    `build` gives it (a constant here would be typed a literal, and compile `_frusta` once more)."""
    n_t = tris.shape[0]
    ctris, straddle = np.empty((n_t, 3, 3)), np.empty((n_t, 3, 3))
    # np.empty and element loops only: np.zeros, full, eye and array would each compile a function more
    planes, signs, lb, keep = np.empty((n_t, 4, 4)), np.empty((n_t, 4)), np.empty(n_t), np.empty(n_t, np.bool_)
    c_lo, c_hi, parts, q, zero = np.empty(n_t + 1), np.empty(n_t + 1), np.empty((8, 9)), np.empty(3), np.empty(3)
    for a in range(3):
        zero[a] = 0.0
    per = 4 * spheres.shape[0] + 1
    cap = 2 * origins.shape[0] + 16
    src, x0, x1 = np.empty(cap, np.int64), np.empty(cap), np.empty(cap)
    buf = np.empty((per, 2))
    m, nc, current = 0, 0, -1
    for s in range(origins.shape[0]):
        g = group[s]
        if g != current:
            current, nc = g, 0
            for t in range(n_t):
                inside = True
                for a in range(3):
                    if t_hi[t, a] < g_lo[g, a] or t_lo[t, a] > g_hi[g, a]:
                        inside = False
                if inside:  # element loops here and below: row assignments compile numba's shape-error messages
                    for v in range(3):
                        for a in range(3):
                            ctris[nc, v, a] = tris[t, v, a]
                    nc += 1
        w = dirs[s]
        for a in range(3):
            q[a] = origins[s, a] - points[s, a]
        # only triangles that meet the plane through the light and the ray can block the segment
        nx, ny, nz = q[1] * w[2] - q[2] * w[1], q[2] * w[0] - q[0] * w[2], q[0] * w[1] - q[1] * w[0]
        tol = gap * math.sqrt(nx * nx + ny * ny + nz * nz)
        ns = 0
        for t in range(nc):
            above = below = 0
            for v in range(3):
                side = (nx * (ctris[t, v, 0] - points[s, 0]) + ny * (ctris[t, v, 1] - points[s, 1])
                        + nz * (ctris[t, v, 2] - points[s, 2]))
                above += side > -tol
                below += side < tol
            if above and below:
                for v in range(3):
                    for a in range(3):
                        straddle[ns, v, a] = ctris[t, v, a]
                ns += 1
        for t in range(ns):
            keep[t] = False
        _frusta_points(straddle[:ns], points[s], zero, epsilon, planes, signs, lb, keep, sun)
        ell = length[s]
        k = 0
        if ns and ell > 0.0:
            # `_lit`'s runs are the face parts; one whose far end (with slack) is not beyond a
            # triangle's depth bound skips it (a NaN end takes every triangle, as there)
            far, every = -math.inf, False
            for p in range(_cube_parts(q, w, ell, parts)):
                x, xn = parts[p, 0], parts[p, 1]
                r1 = math.sqrt((q[0] + x * w[0]) ** 2 + (q[1] + x * w[1]) ** 2 + (q[2] + x * w[2]) ** 2)
                r2 = math.inf
                if xn < math.inf:
                    r2 = math.sqrt((q[0] + xn * w[0]) ** 2 + (q[1] + xn * w[1]) ** 2 + (q[2] + xn * w[2]) ** 2)
                rmax = max(r1, r2)
                f = rmax + REL * abs(rmax) + slack
                every = every or f != f
                far = max(far, f)
            for t in range(ns):
                if not keep[t] or not (every or lb[t] < far):
                    continue
                lo, hi = 0.0, ell
                for pl in range(4):  # sign * (a + b x) > 0 for every plane, as `_lit` clips
                    av = planes[t, pl, 0] * q[0] + planes[t, pl, 1] * q[1] + planes[t, pl, 2] * q[2] - planes[t, pl, 3]
                    bv = planes[t, pl, 0] * w[0] + planes[t, pl, 1] * w[1] + planes[t, pl, 2] * w[2]
                    sg = signs[t, pl]
                    if bv == 0.0:
                        if not sg * av > 0.0:
                            hi = -math.inf
                    elif sg * bv > 0.0:
                        lo = max(lo, -av / bv)
                    else:
                        hi = min(hi, -av / bv)
                    if not lo < hi:
                        break
                if lo < hi:
                    c_lo[k], c_hi[k] = lo, hi
                    k += 1
        if m + (k + 1) * per > cap:
            cap = 2 * (m + (k + 1) * per)
            src2, a2, b2 = np.empty(cap, np.int64), np.empty(cap), np.empty(cap)
            for e in range(m):
                src2[e], a2[e], b2[e] = src[e], x0[e], x1[e]
            src, x0, x1 = src2, a2, b2
        _heapsort_pairs(c_lo[:k], c_hi[:k])
        cur = 0.0
        for e in range(k + 1):  # the lit pieces: the gaps between the shadows' union, then its end to ell
            lo, hi = (c_lo[e], c_hi[e]) if e < k else (ell, ell)
            if lo - cur > gap:
                if spheres.shape[0]:
                    n = lit_parts(origins[s], w, cur, lo, points[s], False, spheres, gap, buf)
                    for i in range(n):
                        src[m], x0[m], x1[m] = s, buf[i, 0], buf[i, 1]
                        m += 1
                else:
                    src[m], x0[m], x1[m] = s, cur, lo
                    m += 1
            cur = max(cur, hi)
    return src[:m].copy(), x0[:m].copy(), x1[:m].copy()
