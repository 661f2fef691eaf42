"""Straight light paths through convex index-matched shapes, in float64 from their face planes, and
the outside medium's single scattering behind them (inside_paths.through_quadrature's kernel).

A convex shape is {q : n_f·q <= c_f} (rows n_x, n_y, n_z, c of `planes`, n outward and unit). The
segment p + s u, 0 <= s <= dist (u unit), lies inside for s in [lo, hi] with

    lo = max(0, max_{n_f·u < 0} s_f),  hi = min(dist, min_{n_f·u > 0} s_f),  s_f = (c_f - n_f·p) / (n_f·u),

and none of it where a face parallel to u has p outside it; its chord is max(hi - lo, 0) (`chord`, `clip`
per face; `boundary_chords` for arrays of segments).

An exact sphere (`primitive = "sphere"`, `exact = true`) is the other boundary kind: one row (centre,
radius) of kind SPHERE beside the planes' PLANES. Its chord is max(min(t1, dist) - max(t0, 0), 0) from
the stable roots t0 <= t1 of geometry/sphere.py `sphere_roots` (`sphere_chord`), and the exit from a
point inside it is the far root t1 (`sphere_exit`). The chord toward a point light of the points of a
line outside the sphere has a square-root kink where the path to the light turns tangent to the sphere
(the light's tangent cone, a quadratic in x: sphere.py `shadow_breaks`); those are its kinks
(`boundary_kinks`), as the polygon's vertices are a convex shape's.

`through_pieces` integrates, per piece o + x w, x in [0, end], lit by a point or spot light at l,

    ks Phi(mu) F exp(-kt (x + d)) / d^2 · I exp(-sum_j (kt_j - kt) k_j),                       (1)

d = |l - p|, mu the cosine between w and l - p, F a spot's falloff, k_j the chord toward the light
of shape j: the unshadowed air-light attenuated by each shape's denser (or thinner) medium. Its
rule is inside_paths.adaptive's, per piece: panels halved until their 10- and 20-point
Gauss-Legendre values agree to rtol in every channel, or to rtol/10 of the first 20-point value of
the whole per unit length; a panel still open after max_levels halvings is dropped and counted.
The batched driver's memory bound (inside_paths.MAX_OPEN open panels per level) becomes a bound of
max_panels panels per piece here, past which panels are accepted at their 20-point value, counted.
Verified (tests/test_convex_chords.py): chords against a brute-force ray-triangle parity twin on a
rotated box and two prisms, 1e-12; integrals against inside_paths.adaptive over through_integrand
(NumPy) on a render's pieces, 1e-12; images against the scipy twin of tests/test_interior_shadows.py.
"""
import math

import numpy as np

from ..geometry.sphere import shadow_breaks, sphere_roots
from ..jit import njit
from ..lights import falloff
from ..geometry.sorting import sort_few
from .phase import phase_value


@njit(inline="always")
def clip(lo, hi, num, den):
    """The parameter range [lo, hi] of a segment p + s u cut by one face: num = c - n·p (>= 0 inside),
    den = n·u; empty (inf, -inf) where the segment is parallel to the face and outside it."""
    if den < 0.0:
        return max(lo, num / den), hi
    if den > 0.0:
        return lo, min(hi, num / den)
    if num < 0.0:
        return math.inf, -math.inf
    return lo, hi


@njit(inline="always")
def chord(planes, first, stop, px, py, pz, ux, uy, uz, dist):
    """The length of the segment p + s u, 0 <= s <= dist (u unit, dist <= inf), inside the convex
    shape of the face planes planes[first:stop]."""
    lo, hi = 0.0, math.inf
    for f in range(first, stop):
        nx, ny, nz = planes[f, 0], planes[f, 1], planes[f, 2]
        lo, hi = clip(lo, hi, planes[f, 3] - (nx * px + ny * py + nz * pz), nx * ux + ny * uy + nz * uz)
    return max(min(hi, dist) - lo, 0.0)


PLANES, SPHERE = 0, 1  # boundary kinds: rows of face planes (n_x, n_y, n_z, c), or one row (centre, radius)
END_SNAP = 1e-12  # of the scene's scale about a piece: a sphere's kink this close to its end is taken to lie on it


@njit(inline="always")
def sphere_chord(row, px, py, pz, ux, uy, uz, dist):
    """The length of the segment p + s u, 0 <= s <= dist (u unit, dist <= inf), inside the sphere
    row = (centre, radius): between the stable roots of `sphere_roots`, 0 where the line misses it."""
    t0, t1 = sphere_roots((px, py, pz), (ux, uy, uz), (row[0], row[1], row[2]), row[3])
    if t1 == math.inf:
        return 0.0
    return max(min(t1, dist) - max(t0, 0.0), 0.0)


@njit(inline="always")
def sphere_exit(row, px, py, pz, ux, uy, uz):
    """The distance from p inside the sphere row = (centre, radius) along the unit u to its surface:
    the far root of `sphere_roots`; 0 where rounding puts p off the sphere with the line missing it
    or the root behind p (the exact distance is then within the rounding, sphere_rounding)."""
    t0, t1 = sphere_roots((px, py, pz), (ux, uy, uz), (row[0], row[1], row[2]), row[3])
    return max(t1, 0.0) if t1 < math.inf else 0.0


@njit(inline="always")
def boundary_chord(kind, rows, first, stop, px, py, pz, ux, uy, uz, dist):
    """`chord` of the convex shape of rows[first:stop] (PLANES) or `sphere_chord` of the sphere
    rows[first] (SPHERE)."""
    if kind == SPHERE:
        return sphere_chord(rows[first], px, py, pz, ux, uy, uz, dist)
    return chord(rows, first, stop, px, py, pz, ux, uy, uz, dist)


@njit
def boundary_chords(points, dirs, dist, kind, rows, out):
    """out[i] = `boundary_chord` of the segments from points[i] along dirs[i] over dist[i]."""
    for i in range(points.shape[0]):
        out[i] = boundary_chord(kind, rows, 0, rows.shape[0], points[i, 0], points[i, 1], points[i, 2], dirs[i, 0],
                                dirs[i, 1], dirs[i, 2], dist[i])


U = 2.0 ** -53  # unit roundoff of doubles


@njit(inline="always")
def sphere_chord_error(row, px, py, pz, ux, uy, uz, k, dx, du, dd):
    """A bound on the rounding of `sphere_chord` k toward a point light, at p along the computed unit u
    (p off by dx from its exact point, u off by du from the exact direction to the light, the distance
    to the light by dd). With f = p - c, b = f·u and h = |f - b u| the line's offset from the centre c,
    the roots are -b -+ s, s = sqrt(q), q = rho^2 - h^2: b and h are off by db = dx + |f| du + 8u |f|
    and dh = dx + |f| du + 16u |f| (inputs and own rounding, as sphere_roots's), q by dq = dh (2h + dh)
    + 8u (rho^2 + h^2), so s by ds = 2 min(sqrt(dq), dq / s) (|sqrt(a) - sqrt(b)| <= min(sqrt|a - b|,
    |a - b| / sqrt(b)), once for these values, once for sphere_roots's); the far root's form c0 / q'
    (c0 = |f|^2 - rho^2, |q'| = |b| + s) adds 8u (|f|^2 + rho^2) / |q'|, each root 12u (|b| + s).
    The chord max(min(t1, d) - max(t0, 0), 0) moves by at most the two roots' errors (each 2 db + ds
    + its own rounding) plus dd; it is 0 where h - dh > rho (the exact line misses the sphere: the
    error is k itself), and within [0, 2 rho (1 + 8u)] either way, so never off by more than 4 rho."""
    rho = row[3]
    fx, fy, fz = px - row[0], py - row[1], pz - row[2]
    nf = math.sqrt(fx * fx + fy * fy + fz * fz)
    b = fx * ux + fy * uy + fz * uz
    hx, hy, hz = fx - b * ux, fy - b * uy, fz - b * uz
    h = math.sqrt(hx * hx + hy * hy + hz * hz)
    move = dx + nf * du
    db, dh = move + 8.0 * U * nf, move + 16.0 * U * nf
    if h - dh > rho:
        return k
    dq = dh * (2.0 * h + dh) + 8.0 * U * (rho * rho + h * h)
    s = math.sqrt(max((rho - h) * (rho + h), 0.0))
    ds = 2.0 * (min(math.sqrt(dq), dq / s) if s > 0.0 else math.sqrt(dq))
    low = abs(b) + s - 2.0 * db - ds  # |q'| at least
    if not low > 0.0:
        return 4.0 * rho
    root = 12.0 * U * (abs(b) + s) + 8.0 * U * (nf * nf + rho * rho) / low
    return min(4.0 * db + 2.0 * ds + 2.0 * root + dd, 4.0 * rho)


@njit
def boundary_kinks(kind, rows, first, stop, o, w, light, end, out):
    """The kinks in (0, end) of the chords toward the point light along the line o + x w (into out,
    ascending; >= stop - first + 4 long; returns their count): `section_kinks` of a convex shape, a
    sphere's tangent-cone crossings (`shadow_breaks`, which also gives where the line itself crosses
    the sphere: the ends of a piece outside it) in [0, end], those within END_SNAP (end + |o - c| + |L - c|
    + R) of an end at that end (a piece that the frusta end at the sphere's shadow ends on its tangent cone:
    a square-root kink at the end, which the rule must know of as well; the kink is found to the
    rounding of those magnitudes, not of the piece's length: a short piece starting on the cone far
    from the sphere would miss it)."""
    if kind != SPHERE:
        return section_kinks(rows, first, stop, o, w, light, end, out)
    buf = np.empty(4)
    n = shadow_breaks(o, w, light, False, rows[first, :3], rows[first, 3], buf)
    m = 0
    c = rows[first]
    far = math.sqrt((o[0] - c[0]) ** 2 + (o[1] - c[1]) ** 2 + (o[2] - c[2]) ** 2)
    tol = END_SNAP * (end + far + math.sqrt((light[0] - c[0]) ** 2 + (light[1] - c[1]) ** 2 + (light[2] - c[2]) ** 2)
                      + abs(c[3]))
    for j in range(n):
        if -tol <= buf[j] <= end + tol:
            out[m] = min(max(buf[j], 0.0), end)
            m += 1
    sort_few(out, 0, m)
    return m


@njit
def section_kinks(planes, first, stop, o, w, light, end, out, directional=False):
    """The parameters in (0, end) along the line o + x w (w unit) where the straight path toward the
    point light at `light` passes through a vertex of the polygon that the plane through the line and
    the light cuts from the convex shape of planes[first:stop]; ascending in out (>= stop - first + 4
    long); returns their count. Every path from the line toward the light lies in that plane, so
    its chord through the shape, and the face it leaves or enters by, change only there: these are
    the kinks of the integrands. The polygon is a square around the shape clipped by each face's
    line (Sutherland-Hodgman), each vertex solved from its two lines; 0 when the light lies on the
    line. `directional`: `light` is the unit direction toward a directional light, the plane the
    one through the line along it, and the path through a vertex (v_x, v_y) (in the frame of the
    line and the light's direction (l_x, l_y) across it) starts at x = v_x - v_y l_x / l_y."""
    vx, vy, vz = (light[0], light[1], light[2]) if directional else (light[0] - o[0], light[1] - o[1], light[2] - o[2])
    lx = vx * w[0] + vy * w[1] + vz * w[2]  # the light in the plane's frame: (lx, ly), the line is y = 0
    px, py, pz = vx - lx * w[0], vy - lx * w[1], vz - lx * w[2]
    ly = math.sqrt(px * px + py * py + pz * pz)
    if not ly > 1e-12 * math.sqrt(vx * vx + vy * vy + vz * vz):
        return 0
    ex, ey, ez = px / ly, py / ly, pz / ly
    nf = stop - first
    cap = nf + 4
    # face f's line a x + b y <= c in the frame; the square's four lines are -1 .. -4
    la, lb, lc = np.empty(nf + 4), np.empty(nf + 4), np.empty(nf + 4)
    size = 4.0 * (end + abs(lx) + ly + 1.0)
    for f in range(nf):
        row = first + f
        la[f] = planes[row, 0] * w[0] + planes[row, 1] * w[1] + planes[row, 2] * w[2]
        lb[f] = planes[row, 0] * ex + planes[row, 1] * ey + planes[row, 2] * ez
        lc[f] = planes[row, 3] - (planes[row, 0] * o[0] + planes[row, 1] * o[1] + planes[row, 2] * o[2])
        size = max(size, 4.0 * abs(lc[f]))
    for k in range(4):
        la[nf + k] = (1.0, 0.0, -1.0, 0.0)[k]
        lb[nf + k] = (0.0, 1.0, 0.0, -1.0)[k]
        lc[nf + k] = size
    # polygon vertices (x, y) with the lines of the edges before and after them
    xs, ys, before, after = np.empty(cap), np.empty(cap), np.empty(cap, np.int64), np.empty(cap, np.int64)
    nx_, ny_, nb, na = np.empty(cap), np.empty(cap), np.empty(cap, np.int64), np.empty(cap, np.int64)
    m = 4  # the square's corners, counter-clockwise from (size, size)
    before[0], after[0] = nf + 0, nf + 1
    before[1], after[1] = nf + 1, nf + 2
    before[2], after[2] = nf + 2, nf + 3
    before[3], after[3] = nf + 3, nf + 0
    for k in range(4):
        xs[k], ys[k] = _meet(la, lb, lc, before[k], after[k])
    for f in range(nf):
        if la[f] == 0.0 and lb[f] == 0.0:
            if lc[f] < 0.0:
                return 0  # the plane misses the shape
            continue
        count = 0
        for k in range(m):
            j = (k + 1) % m
            inside_k = la[f] * xs[k] + lb[f] * ys[k] <= lc[f]
            inside_j = la[f] * xs[j] + lb[f] * ys[j] <= lc[f]
            edge = after[k]
            if inside_k and inside_j:
                nx_[count], ny_[count], nb[count], na[count] = xs[j], ys[j], before[j], after[j]
                count += 1
            elif inside_k:
                nx_[count], ny_[count] = _meet(la, lb, lc, edge, f)
                nb[count], na[count] = edge, f
                count += 1
            elif inside_j:
                nx_[count], ny_[count] = _meet(la, lb, lc, f, edge)
                nb[count], na[count] = f, edge
                nx_[count + 1], ny_[count + 1], nb[count + 1], na[count + 1] = xs[j], ys[j], before[j], after[j]
                count += 2
        m = count
        if m == 0:
            return 0
        for k in range(m):
            xs[k], ys[k], before[k], after[k] = nx_[k], ny_[k], nb[k], na[k]
    count = 0
    for k in range(m):
        if before[k] >= nf or after[k] >= nf:
            continue  # a corner of the square: the shape is open there
        dy = ys[k] - ly
        if dy == 0.0 and not directional:
            continue  # the path through this vertex runs parallel to the line
        x = xs[k] - ys[k] * lx / ly if directional else lx - (xs[k] - lx) * ly / dy
        if 0.0 < x < end:
            out[count] = x
            count += 1
    sort_few(out, 0, count)
    return count


@njit(inline="always")
def _meet(la, lb, lc, i, j):
    """The point where lines i and j of a x + b y = c meet (their Cramer solution)."""
    det = la[i] * lb[j] - la[j] * lb[i]
    if det == 0.0:
        return math.inf, math.inf
    return (lc[i] * lb[j] - lc[j] * lb[i]) / det, (la[i] * lc[j] - la[j] * lc[i]) / det


@njit
def _panel_rounding(i, a, b, wp, n10, n20, origins, dirs, light, positions, planes, offsets, kinds, dk, node_eps,
                    moves, chord_err):
    """The largest relative rounding (3,) of `through_pieces`' evaluations at the 10- and 20-point
    nodes of panel [a, b] (warp wp) of piece i: node_eps[i] + sum_j |dk[j]| (e_j + 16u k_j), e_j
    chord_err[i, j] or `sphere_chord_error` (moves[i] = (dx, du, dd)). Apart from the sums' loop, so
    that their compiled code, and the values, stay as they were."""
    ox, oy, oz, wx, wy, wz = origins[i, 0], origins[i, 1], origins[i, 2], dirs[i, 0], dirs[i, 1], dirs[i, 2]
    lx, ly, lz = positions[light[i], 0], positions[light[i], 1], positions[light[i], 2]
    half, mid = 0.5 * (b - a), 0.5 * (a + b)
    m0 = m1 = m2 = 0.0
    for q in range(n10.shape[0] + n20.shape[0]):
        node = n10[q] if q < n10.shape[0] else n20[q - n10.shape[0]]
        u = 0.5 * (1.0 + node)
        x = mid + half * node if wp == 0 else (a + (b - a) * u * u if wp == 1 else b - (b - a) * u * u)
        px, py, pz = ox + x * wx, oy + x * wy, oz + x * wz
        rx, ry, rz = lx - px, ly - py, lz - pz
        d = max(math.sqrt(rx * rx + ry * ry + rz * rz), 1e-125)
        tx, ty, tz = rx / d, ry / d, rz / d
        a0 = a1 = a2 = 0.0
        for j in range(dk.shape[0]):
            k = boundary_chord(kinds[j], planes, offsets[j], offsets[j + 1], px, py, pz, tx, ty, tz, d)
            ek = 16.0 * U * k + (sphere_chord_error(planes[offsets[j]], px, py, pz, tx, ty, tz, k, moves[i, 0],
                                                    moves[i, 1], moves[i, 2])
                                 if kinds[j] == SPHERE else chord_err[i, j])
            a0 += _times(abs(dk[j, 0]), ek)
            a1 += _times(abs(dk[j, 1]), ek)
            a2 += _times(abs(dk[j, 2]), ek)
        m0, m1, m2 = max(m0, node_eps[i, 0] + a0), max(m1, node_eps[i, 1] + a1), max(m2, node_eps[i, 2] + a2)
    return m0, m1, m2


@njit(inline="always")
def _times(a, b):
    """a b, 0 where a is 0 (an exact 0 carries no error, however large b's bound: not inf x 0 = nan)."""
    return a * b if a != 0.0 else 0.0


@njit(inline="always")
def _airlight(x, d, mu, f, e0, e1, e2, kt0, kt1, kt2, ks0, ks1, ks2, i0, i1, i2, code, g):
    """(1) per channel from the distance d to the light, the cosine mu, the falloff f and the
    exponents e_c = sum_j (kt_j - kt) k_j."""
    ph = phase_value(code, g, mu) * f / (d * d)
    return (ks0 * ph * math.exp(-kt0 * x - kt0 * d - e0) * i0,
            ks1 * ph * math.exp(-kt1 * x - kt1 * d - e1) * i1,
            ks2 * ph * math.exp(-kt2 * x - kt2 * d - e2) * i2)


@njit
def through_pieces(origins, dirs, end, light, positions, axes, cones, intensities, planes, offsets, kinds, dk, kt,
                   ks, code, g, rtol, max_levels, max_panels, n10, w10, n20, w20, node_eps, moves, chord_err, out,
                   bound, stats):
    """out[i] (3,) = ∫_0^end[i] of (1) along piece i (origins, dirs; light[i] indexes the lights'
    positions, axes, cones (cos_end, cos_start, curve) and intensities) through the shapes whose
    boundaries (of kind kinds[j]: face planes or an exact sphere) are planes[offsets[j]:offsets[j + 1]]
    (dk[j] = their sigma_t minus kt); stats[0] += the panels dropped at max_levels or accepted at
    max_panels, short of their tolerance. The first panels are cut at the kinks of the chords
    (`boundary_kinks` of every shape), so that the adaptive rule meets only smooth panels (a finely
    tessellated sphere: one kink per facet edge the light's paths sweep). An exact sphere's kinks are
    square-root ones (the chord grows as sqrt(x - x_b) past the tangent cone), which Gauss-Legendre
    meets at h^1.5 on a panel of width h beside them: a first panel that ends at one is integrated in
    u with x = x_b + (x_other - x_b) u^2 (smooth in u), its halves in u the quarter beside x_b (warped
    again) and the rest (plain); a panel with such a kink at both ends is halved first. One loop with
    its helpers inlined: helpers called per evaluation with arrays and tuples (their reference counts)
    took half of the kernel's time.

    bound[i] (3,): the rule's bound per accepted panel, max(rtol |G20|, the floor times its width)
    (each panel's 20-point value taken to be within |G20 - G10| of its integral, as the test keeps
    it), + twice the 20-point sum's and once the 10-point sum's rounding (the test reads computed
    sums): the evaluations' largest relative rounding (`_panel_rounding`) x (2 |G20| + |G10|) (the
    integrand and the weights are positive), + u per panel x (|out| + bound); inf where a panel was
    dropped or accepted at max_panels. An evaluation's relative rounding: node_eps[i] (3,) (the
    unattenuated integrand's, the exponent sum's and a spot's, interiors/paths.py `piece_errors`) +
    sum_j |dk[j]| (e_j + 16u k_j), e_j the chord's rounding: chord_err[i, j] for face planes
    (shadows/through_others.py `point_chord_rounding`), `sphere_chord_error` per evaluation for a
    sphere (moves[i] = (dx, du, dd): the point's, the direction's and the distance's rounding)."""
    n_kinks = 0
    for j in range(offsets.shape[0] - 1):
        n_kinks += offsets[j + 1] - offsets[j] + 4
    size = 2 * n_kinks + max_levels + 4
    lo_stack, hi_stack, depth, warp = np.empty(size), np.empty(size), np.empty(size, np.int64), np.empty(size, np.int64)
    kinks = np.empty(n_kinks + 1)
    rooted = np.zeros(n_kinks + 1, dtype=np.bool_)  # a square-root kink (an exact sphere's)
    found = np.empty(n_kinks + 1)
    n_nodes = n10.shape[0] + n20.shape[0]
    for i in range(origins.shape[0]):
        out[i, 0] = out[i, 1] = out[i, 2] = 0.0
        bound[i, 0] = bound[i, 1] = bound[i, 2] = 0.0
        if not end[i] > 0.0:
            continue
        li = light[i]
        ox, oy, oz, wx, wy, wz = origins[i, 0], origins[i, 1], origins[i, 2], dirs[i, 0], dirs[i, 1], dirs[i, 2]
        lx, ly, lz = positions[li, 0], positions[li, 1], positions[li, 2]
        floor0 = floor1 = floor2 = 0.0
        m = 0
        for j in range(offsets.shape[0] - 1):
            c = boundary_kinks(kinds[j], planes, offsets[j], offsets[j + 1], origins[i], dirs[i], positions[li], end[i],
                               found)
            kinks[m:m + c] = found[:c]
            rooted[m:m + c] = kinds[j] == SPHERE
            m += c
        order = np.argsort(kinks[:m])
        cuts, roots = kinks[:m][order], rooted[:m][order]
        top = 0  # the first panels, the lowest on top; warp 1 (2): a square-root kink at the start (end)
        b, at_b = end[i], False
        for k in range(m, -1, -1):
            a, at_a = (cuts[k - 1], roots[k - 1]) if k > 0 else (0.0, False)
            if not a < b:
                at_b = at_b or at_a
                continue
            if at_a and at_b:
                mid = 0.5 * (a + b)
                lo_stack[top], hi_stack[top], depth[top], warp[top] = mid, b, 0, 2
                lo_stack[top + 1], hi_stack[top + 1], depth[top + 1], warp[top + 1] = a, mid, 0, 1
                top += 2
            else:
                lo_stack[top], hi_stack[top], depth[top], warp[top] = a, b, 0, 1 if at_a else (2 if at_b else 0)
                top += 1
            b, at_b = a, at_a
        panels, accepted, short = 0, 0, False
        while top > 0:
            top -= 1
            a, b, level, wp = lo_stack[top], hi_stack[top], depth[top], warp[top]
            half, mid = 0.5 * (b - a), 0.5 * (a + b)
            c0 = c1 = c2 = f0 = f1 = f2 = 0.0  # the 10- and 20-point sums
            for q in range(n_nodes):
                coarse = q < n10.shape[0]
                node, weight = (n10[q], w10[q]) if coarse else (n20[q - n10.shape[0]], w20[q - n10.shape[0]])
                if wp == 0:
                    x = mid + half * node
                else:  # x = x_b ± (b - a) u^2, u = (1 + node) / 2: dx = half 2u dnode
                    u = 0.5 * (1.0 + node)
                    x = a + (b - a) * u * u if wp == 1 else b - (b - a) * u * u
                    weight *= 2.0 * u
                px, py, pz = ox + x * wx, oy + x * wy, oz + x * wz
                rx, ry, rz = lx - px, ly - py, lz - pz
                d = max(math.sqrt(rx * rx + ry * ry + rz * rz), 1e-125)
                tx, ty, tz = rx / d, ry / d, rz / d
                f = falloff(-(tx * axes[li, 0] + ty * axes[li, 1] + tz * axes[li, 2]), cones[li, 0], cones[li, 1],
                            cones[li, 2])
                if f == 0.0:  # outside a spot's cone: no chords measured
                    continue
                e0 = e1 = e2 = 0.0
                for j in range(dk.shape[0]):
                    k = boundary_chord(kinds[j], planes, offsets[j], offsets[j + 1], px, py, pz, tx, ty, tz, d)
                    e0 += k * dk[j, 0]
                    e1 += k * dk[j, 1]
                    e2 += k * dk[j, 2]
                v0, v1, v2 = _airlight(x, d, tx * wx + ty * wy + tz * wz, f, e0, e1, e2, kt[0], kt[1], kt[2],
                                       ks[0], ks[1], ks[2], intensities[li, 0], intensities[li, 1],
                                       intensities[li, 2], code, g)
                if coarse:
                    c0, c1, c2 = c0 + weight * v0, c1 + weight * v1, c2 + weight * v2
                else:
                    f0, f1, f2 = f0 + weight * v0, f1 + weight * v1, f2 + weight * v2
            c0, c1, c2, f0, f1, f2 = c0 * half, c1 * half, c2 * half, f0 * half, f1 * half, f2 * half
            panels += 1
            if panels == 1:  # the floor: rtol/10 of the first panel's mean 20-point value per unit length
                scale = 0.1 * rtol / (b - a)
                floor0, floor1, floor2 = abs(f0) * scale, abs(f1) * scale, abs(f2) * scale
            width = b - a
            ok = (abs(f0 - c0) <= max(rtol * abs(f0), floor0 * width)
                  and abs(f1 - c1) <= max(rtol * abs(f1), floor1 * width)
                  and abs(f2 - c2) <= max(rtol * abs(f2), floor2 * width))
            if ok or panels >= max_panels:
                if not ok:
                    stats[0] += 1.0
                    short = True
                out[i, 0] += f0
                out[i, 1] += f1
                out[i, 2] += f2
                m0, m1, m2 = _panel_rounding(i, a, b, wp, n10, n20, origins, dirs, light, positions, planes, offsets,
                                             kinds, dk, node_eps, moves, chord_err)
                bound[i, 0] += max(rtol * abs(f0), floor0 * width) + _times(m0, 2.0 * abs(f0) + abs(c0))
                bound[i, 1] += max(rtol * abs(f1), floor1 * width) + _times(m1, 2.0 * abs(f1) + abs(c1))
                bound[i, 2] += max(rtol * abs(f2), floor2 * width) + _times(m2, 2.0 * abs(f2) + abs(c2))
                accepted += 1
            elif level + 1 >= max_levels:  # dropped, as inside_paths.adaptive drops it
                stats[0] += 1.0
                short = True
            else:  # halves in x, or in u: the quarter beside the kink (warped) and the rest (plain)
                cut = mid if wp == 0 else (a + 0.25 * (b - a) if wp == 1 else b - 0.25 * (b - a))
                lo_stack[top], hi_stack[top], depth[top], warp[top] = cut, b, level + 1, 2 if wp == 2 else 0
                lo_stack[top + 1], hi_stack[top + 1], depth[top + 1] = a, cut, level + 1
                warp[top + 1] = 1 if wp == 1 else 0
                top += 2
        for c in range(3):
            bound[i, c] = math.inf if short else bound[i, c] + accepted * U * (abs(out[i, c]) + bound[i, c])
