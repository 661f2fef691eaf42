"""Flat emitters (quad, disk) about a point of their plane: the rules that the air-light of a camera ray
passing near or ending on the emitter needs (rendering/near_emitters.py, docs/area_lights.md, "Rays
near an emitter").

Along a camera ray the air-light of one emitter point y behaves like 1 / rho(y), rho the distance from
y to the ray, which vanishes at the ray's foot point f on the plane (where it crosses it). A rule whose
Jacobian vanishes like |y - f| makes that integrand smooth in its parameters:
- a convex polygon: the triangles (f, a, b) over its edges, the edge at signed distance h from f
  (perpendicular m, direction e): y = f + r |h| (m + sinh(u) e), r in [0, 1], dA = r h^2 cosh(u) dr du,
  signed by the side of the edge f lies on (f outside the polygon: the triangles beyond it subtract);
  Gauss–Legendre in u (panels of at most SPAN) and `graded` in r (sinh: 1 / rho = 1 / (r |h| cosh u)
  times the Jacobian is smooth however near f lies to the edge's line); a ray that grazes the plane
  (the sine s of its angle to it below GRAZE) puts 1 / rho in a ridge along its projection p on the
  plane: rho = |y - f| sqrt(sin^2 delta + cos^2 delta s^2), delta the angle of y - f off p, a peak about
  s wide in angle. There u = u0 + w sinh(s') (s' Gauss–Legendre, panels of at most SPAN) grades each
  triangle toward the angle u0 = asinh(tan phi0) where the line along p meets its edge's line (tan phi0
  = (p . e) / (p . m)), w = s cosh(u0) the peak's width in u (d phi / du = 1 / cosh u): `peaks`;
- a disk: polar coordinates (rho, phi) about f, dA = rho drho dphi, Gauss–Legendre in rho between the
  rim's crossings (`graded` from f where f lies inside); f inside: phi = psi + (a / 2) sin(2 psi) from the
  direction of f off the centre, psi equally spaced (periodic; the chord to the rim is nearly singular
  at right angles to that direction when f lies near the rim, which a = 1 - sqrt(R^2 - D^2) / D, D the
  distance of f from the centre, crowds the nodes toward); f outside: phi = phi_c + delta sin theta over
  the rim's tangent cone (theta Gauss–Legendre: the chord's square root at the tangents is smooth in theta).

A ray that passes near the emitter grazing its plane but crosses it beyond (cubature.PASSING, not near by
the foot-point test) puts the ridge along its projection over the emitter with no singular point on it: the
polygon's rule for such rays (`ridge_about`) takes the coordinates along and across the projection, graded
across it by sinh about the ridge's width, the tensor rule's 1 / n convergence on the ridge replaced by
Gauss–Legendre's on a smooth function (a disk keeps its rows there).
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..jit import njit
from .area import gauss_legendre


SPAN = 2.0  # the longest stretch of u one Gauss–Legendre panel takes (a foot point near an edge's line: longer)
TINY = 1e-9  # of an edge's length: nearer its line a foot point's triangle counts as of no area
GRAZE = 0.5  # a ray whose sine to the plane is below this grazes it: the polygon's rule grades toward it
MAX_TAN = 1e6  # a ray's projection nearer than this (tan) to an edge's direction is not graded toward it
RIDGE_FLOOR = 1e-3  # of the diameter: the narrowest ridge a passing ray's rule grades toward (`ridge`)


def graded(n: int):
    """Gauss–Legendre nodes and weights of r = xi^2 on [0, 1] (xi Gauss–Legendre): the per-point air-light
    about the foot point is c / r + sigma c' log r + smooth, so r times it has an r log r term, which
    the grading makes 4 xi^3 log xi (Gauss–Legendre then converges as for a smooth function of order 3)."""
    xi, w = gauss_legendre(n)
    return xi * xi, 2.0 * xi * w


def cross(u, v):
    """np.cross of (P, 3) rows u and v, each component rounded as np.cross rounds it (two products and
    their difference), without its per-call overhead."""
    out = np.empty_like(u)
    out[:, 0] = u[:, 1] * v[:, 2] - u[:, 2] * v[:, 1]
    out[:, 1] = u[:, 2] * v[:, 0] - u[:, 0] * v[:, 2]
    out[:, 2] = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
    return out


def grazing(normal, dirs, n: int):
    """((n, 3) the unit direction of each ray's projection on the plane, (n,) the sine of its angle to
    the plane), where that sine is below GRAZE (a ray nearly parallel to the plane: its nodes' 1 / rho
    peaks along that direction, module docstring), NaN elsewhere and where `dirs` is None."""
    out, sine = np.full((n, 3), np.nan), np.full(n, np.nan)
    if dirs is None:
        return out, sine
    dn = dirs @ normal
    flat = dirs - dn[:, None] * normal
    length = np.linalg.norm(flat, axis=1)
    on = np.abs(dn) < GRAZE
    out[on], sine[on] = flat[on] / length[on, None], np.abs(dn[on])
    return out, sine


def peaks(graze, toward, along, lo, hi):
    """(centre, width, s_lo, s_hi), each (P,): per triangle (f, edge) over u in [lo, hi] (q = |h| sinh u
    along the edge) the u = centre + width sinh(s) that grades it toward u0, where the line through f
    along the ray's projection meets the edge's line (tan phi0 = (p . along) / (p . toward), u0 =
    asinh(tan phi0)), width the peak's angular width, the ray's sine to the plane, in u (d phi / du =
    1 / cosh u); not graded (centre NaN, s = u) where the ray does not graze or runs along the edge."""
    p, sine = graze
    with np.errstate(divide="ignore", invalid="ignore"):
        tan = (p @ along) / np.einsum("ij,ij->i", p, toward)
    graded = np.isfinite(tan) & (np.abs(tan) < MAX_TAN)
    centre = np.where(graded, np.arcsinh(np.where(graded, tan, 0.0)), np.nan)
    width = np.where(graded, np.maximum(sine, TINY) * np.cosh(np.where(graded, centre, 0.0)), np.nan)
    with np.errstate(invalid="ignore"):
        s_lo = np.where(graded, np.arcsinh((lo - centre) / width), lo)
        s_hi = np.where(graded, np.arcsinh((hi - centre) / width), hi)
    return centre, width, s_lo, s_hi


def _ungraded(s, centre, width):
    """(u, du / ds) of `peaks`' grading (u = s, 1 where the centre is NaN)."""
    graded = ~np.isnan(centre)
    if not graded.any():
        return s, 1.0
    return (np.where(graded, centre + width * np.sinh(s), s),
            np.where(graded, width * np.cosh(np.where(graded, s, 0.0)), 1.0))


def ridge_about(corners, normal, diameter, origins, dirs):
    """rule(at, order) -> (points (M, 3), signed area weights (M,), owner (M,): the index into `at`) over the
    convex polygon `corners` (K, 3) graded toward the ridge of each camera ray (origins, unit dirs) (R, 3) that
    passes near it grazing its plane (module docstring), what does not depend on the order built once.

    In the plane, about f0 the projection of the ray's origin, a along the ray's projection p and b across it
    (q = normal x p): the distance from the plane's point (a, b) to the ray's line is rho = sqrt(g(a)^2 + b^2),
    g(a) = |h0 cos + a s| (h0 the origin's height, s = d . normal, cos = |d - s normal|), a ridge along b = 0
    about g wide; a node's air-light is c(a, b) g / rho^2 (Lorentzian in b: the emission's cosine toward the ray
    is g / rho at its nearest point) or 1 / rho. Outer b = w sinh(sigma), w the ridge's narrowest width over
    the polygon's range of a (at least RIDGE_FLOOR of the diameter), Gauss–Legendre in sigma between the
    corners' b (the chord's ends are linear there) in panels of at most SPAN; inner Gauss–Legendre in a over
    the polygon's chord at b (its singular point, a = -h0 cos / s, lies at least NEAR_FRACTION of the
    diameter from the polygon for a passing ray, where g is smooth at the chord's scale)."""
    corners = np.asarray(corners, float)
    dn = dirs @ normal
    flat = dirs - dn[:, None] * normal
    cos = np.linalg.norm(flat, axis=1)
    p = flat / cos[:, None]
    q = np.cross(normal[None], p)
    h0 = (origins - corners[0]) @ normal
    f0 = origins - h0[:, None] * normal
    a = np.einsum("rkj,rj->rk", corners[None] - f0[:, None], p)  # (R, K) the corners' coordinates
    b = np.einsum("rkj,rj->rk", corners[None] - f0[:, None], q)
    lo, hi = a.min(axis=1), a.max(axis=1)
    g = np.minimum(np.abs(h0 * cos + lo * dn), np.abs(h0 * cos + hi * dn))
    with np.errstate(divide="ignore", invalid="ignore"):
        zero = -h0 * cos / dn
    g = np.where((zero > lo) & (zero < hi), 0.0, g)
    w = np.maximum(g, RIDGE_FLOOR * diameter)
    cuts = np.sort(b, axis=1)
    ray, k = np.nonzero(cuts[:, 1:] > cuts[:, :-1])  # the strips between consecutive corners' b
    s_lo, s_hi = np.arcsinh(cuts[ray, k] / w[ray]), np.arcsinh(cuts[ray, k + 1] / w[ray])
    panels = np.maximum(np.ceil((s_hi - s_lo) / SPAN), 1).astype(np.int64)

    def nodes(at, order):
        x, wx = gauss_legendre(order)
        mine = np.nonzero(np.isin(ray, at))[0]
        start = np.concatenate(([0], np.cumsum(panels[mine] * order * order)))
        return _ridge_nodes(ray[mine], _positions(at, ray[mine]), s_lo[mine], s_hi[mine], panels[mine], start, w,
                            f0, p, q, a, b, x, wx)
    return nodes


@njit
def _ridge_nodes(ray, slot, s_lo, s_hi, panels, start, w, f0, p, q, a, b, x, wx):
    """(points (M, 3), weights (M,), owner (M,)) of `ridge_about`'s strips: strip i of ray ray[i] (owner slot[i])
    between sigma s_lo[i] and s_hi[i] in panels[i] panels, its nodes from start[i]; per ray its width w, frame
    (f0, p, q) and corners' coordinates (a, b) (R, K); x, wx Gauss–Legendre on [0, 1]."""
    n, k_corners, total = len(x), a.shape[1], start[-1]
    points, weights, owner = np.empty((total, 3)), np.empty(total), np.empty(total, np.int64)
    for i in range(len(ray)):
        r, k = ray[i], start[i]
        span = (s_hi[i] - s_lo[i]) / panels[i]
        for j in range(panels[i]):
            for u in range(n):
                sigma = s_lo[i] + span * (j + x[u])
                across = w[r] * math.sinh(sigma)
                jb = w[r] * math.cosh(sigma) * span * wx[u]
                lo, hi = math.inf, -math.inf  # the chord's ends: the two edges that straddle `across`
                for e in range(k_corners):
                    e1 = (e + 1) % k_corners
                    b0, b1 = b[r, e], b[r, e1]
                    if min(b0, b1) < across < max(b0, b1):
                        t = a[r, e] + (across - b0) / (b1 - b0) * (a[r, e1] - a[r, e])
                        lo, hi = min(lo, t), max(hi, t)
                if not lo <= hi:
                    lo, hi = 0.0, 0.0
                for v in range(n):
                    along = lo + (hi - lo) * x[v]
                    for c in range(3):
                        points[k, c] = f0[r, c] + along * p[r, c] + across * q[r, c]
                    weights[k] = jb * (hi - lo) * wx[v]
                    owner[k] = slot[i]
                    k += 1
    return points, weights, owner


def _positions(at, rays):
    """(n,) the index in `at` of each of `rays` (each in `at`, `at` without repeats)."""
    order = np.argsort(at)
    return order[np.searchsorted(at[order], rays)]


@dataclass(frozen=True)
class Planar:
    """A flat emitter as near_emitters.py needs it: a point `centre` (3,) of its plane, the plane's unit
    `normal` (3,), its `diameter`, `outside(f)` the distance (P,) from points f (P, 3) of the plane to the
    emitter (0 on it), and `rule(f, order, dirs=None)` (points (M, 3), signed area weights (M,), owner (M,):
    the f of each node) a rule over the emitter singular at each f (module docstring) whose weights sum
    to the emitter's area for every f; `dirs` (P, 3) the rays' unit directions (the polygon's rule grades
    its nodes toward a grazing ray's projection; the disk's ignores them). `about(f, dirs=None)` -> rule(at,
    order): the same rule about f[at] (owner: the index into `at`), the polygon's part that does not depend
    on the order built once for consecutive calls with the same `at` (a ladder's first two orders:
    rendering/near_emitters.py `_values`)."""
    centre: np.ndarray
    normal: np.ndarray
    diameter: float
    outside: Callable
    rule: Callable
    about: Callable
    pieces: tuple = ()  # (kinds (P,), frames (P, 3, 3)): the emitter as pieces uniform in area (`emitter_pieces`)
    # ridge(origins, dirs) -> rule(at, order) as `about`'s, graded toward the ridge of camera rays that pass near the
    # emitter grazing its plane (`ridge_about`); None: the emitter's rows serve them (a disk)
    ridge: Callable | None = None


def plane_feet(centre, normal, origins, dirs, tmax):
    """((N, 3) feet, (N,) heights): per segment o + t d, 0 <= t <= tmax (unit d), the point of the plane
    (centre, normal) where it crosses it, else the projection of its end nearer the plane (its origin
    where it runs away to infinity), and that end's distance to the plane (0 where it crosses)."""
    h0 = (origins - centre) @ normal
    dn = dirs @ normal
    finite = np.isfinite(tmax)
    end = np.where(finite, tmax, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        tc = np.where(dn != 0.0, -h0 / dn, -1.0)
    crosses = (tc >= 0.0) & (tc <= tmax)
    t = np.where(crosses, tc, np.where(np.abs(h0 + end * dn) < np.abs(h0), end, 0.0))
    height = np.where(crosses, 0.0, np.abs(h0 + t * dn))
    points = origins + t[:, None] * dirs
    return points - ((points - centre) @ normal)[:, None] * normal, height


def polygon(corners, normal) -> Planar:
    """The `Planar` of a convex polygon of `corners` (M, 3) in order about its `normal`."""
    corners = np.asarray(corners, float)
    edges = np.roll(corners, -1, axis=0) - corners
    diameter = max(np.linalg.norm(corners - c, axis=1).max() for c in corners)

    def outside(f):
        rel = f[:, None, :] - corners[None]  # (P, M, 3)
        inside = np.all(np.cross(edges[None], rel) @ normal >= 0.0, axis=1)
        s = np.clip(np.einsum("pmk,mk->pm", rel, edges) / np.einsum("mk,mk->m", edges, edges), 0.0, 1.0)
        gap = np.linalg.norm(rel - s[..., None] * edges[None], axis=2).min(axis=1)
        return np.where(inside, 0.0, gap)

    sides = []  # per edge: its ends, unit direction, length and the in-plane perpendicular normal x along
    for a, b in zip(corners, np.roll(corners, -1, axis=0)):
        along = (b - a) / np.linalg.norm(b - a)
        sides.append((a, b, along, np.linalg.norm(b - a), np.cross(normal, along)))

    def geometry(f, dirs):
        """Per edge the order-independent part of the rule about the points f: the edge's signed distance h,
        the range of u, its grading toward a grazing ray and the panels."""
        graze = grazing(normal, dirs, len(f))
        out = []
        for a, b, along, length, across in sides:
            foot = a + ((f - a) @ along)[:, None] * along  # f's perpendicular foot on the edge's line
            h = cross(a - f, b - f) @ normal / length  # signed: > 0 on the inner side
            toward = np.where(h[:, None] >= 0.0, -1.0, 1.0) * across  # from f to the edge
            scale = np.maximum(np.abs(h), TINY * length)  # h ~ 0: a triangle of no area
            lo, hi = np.arcsinh((a - foot) @ along / scale), np.arcsinh((b - foot) @ along / scale)
            centre, width, s_lo, s_hi = peaks(graze, toward, along, lo, hi)
            panels = np.maximum(np.ceil((s_hi - s_lo) / SPAN), 1).astype(np.int64)
            out.append((along, h, toward, scale, centre, width, s_lo, s_hi, panels))
        return out

    def nodes(f, edges, order):
        """`rule`'s nodes about the points f from their `geometry`."""
        r, wr = graded(order)
        x, wx = gauss_legendre(order)
        parts = []
        for along, h, toward, scale, centre, width, s_lo, s_hi, panels in edges:
            for p in np.unique(panels):
                at = np.nonzero(panels == p)[0]
                t = ((np.arange(p)[:, None] + x[None]) / p).ravel()  # (p x order,) in [0, 1]
                s = s_lo[at, None] + (s_hi - s_lo)[at, None] * t[None]
                u, du = _ungraded(s, centre[at, None], width[at, None])  # q = |h| sinh(u) along the edge
                arm = scale[at, None, None] * (toward[at, None, :] + np.sinh(u)[..., None] * along)  # f to the edge
                points = f[at, None, None, :] + r[None, :, None, None] * arm[:, None, :, :]
                jac = (h * scale)[at, None] * (s_hi - s_lo)[at, None] * np.tile(wx, p)[None] / p * np.cosh(u) * du
                weights = (r * wr)[None, :, None] * jac[:, None, :]
                parts.append((points.reshape(-1, 3), weights.ravel(), np.repeat(at, weights[0].size)))
        return tuple(np.concatenate(c) for c in zip(*parts))

    def about(f, dirs=None):
        last = {}  # the geometry of the last points asked about (a ladder's first step: two orders of the same)

        def rule_at(at, order):
            if last.get("at") is None or not np.array_equal(last["at"], at):
                last.update(at=at, edges=geometry(f[at], None if dirs is None else dirs[at]))
            return nodes(f[at], last["edges"], order)
        return rule_at

    def rule(f, order, dirs=None):
        return nodes(f, geometry(f, dirs), order)

    fan = np.stack([np.broadcast_to(corners[0], (len(corners) - 2, 3)), corners[1:-1], corners[2:]], axis=1)
    return Planar(corners.mean(axis=0), np.asarray(normal, float), diameter, outside, rule, about,
                  (np.full(len(fan), TRIANGLE), fan),
                  functools.partial(ridge_about, corners, np.asarray(normal, float), diameter))


def disk(centre, normal, t1, t2, radius: float) -> Planar:
    """The `Planar` of the disk of `centre`, unit `normal` and `radius` (t1, t2: its plane's frame)."""
    centre = np.asarray(centre, float)

    def outside(f):
        return np.maximum(np.linalg.norm(f - centre, axis=1) - radius, 0.0)

    def rule(f, order, dirs=None):  # dirs: not used (`Planar`)
        px, py = (f - centre) @ t1, (f - centre) @ t2  # (P,)
        dist = np.hypot(px, py)
        m = 4 * order
        inside = dist < radius
        (rg, wg), (rl, wl) = graded(order), gauss_legendre(order)
        r, wr = np.where(inside[:, None], rg, rl), np.where(inside[:, None], wg, wl)  # (P, order)
        # outside: phi_c + delta sin(theta) over the tangent cone
        theta, wt = np.polynomial.legendre.leggauss(m)
        theta, wt = 0.5 * np.pi * theta, 0.5 * np.pi * wt
        delta = np.arcsin(np.minimum(radius / np.maximum(dist, 1e-300), 1.0))
        phi_c = np.arctan2(-py, -px)
        # inside: psi equally spaced, phi = psi + (a / 2) sin(2 psi) from f's direction off the centre
        psi = 2.0 * np.pi * (np.arange(m) + 0.5) / m
        with np.errstate(divide="ignore"):
            a = np.clip(1.0 - np.sqrt(np.maximum(radius * radius - dist * dist, 0.0)) / dist, 0.0, 1.0)[:, None]
        graded_phi = np.arctan2(py, px)[:, None] + psi[None] + 0.5 * a * np.sin(2.0 * psi)[None]
        phi = np.where(inside[:, None], graded_phi, phi_c[:, None] + delta[:, None] * np.sin(theta)[None])
        dphi = np.where(inside[:, None], 2.0 * np.pi / m * (1.0 + a * np.cos(2.0 * psi)[None]),
                        delta[:, None] * np.cos(theta)[None] * wt[None])
        ux, uy = np.cos(phi), np.sin(phi)  # (P, m)
        along = ux * px[:, None] + uy * py[:, None]
        root = np.sqrt(np.maximum(along * along - (dist * dist - radius * radius)[:, None], 0.0))
        near = np.where(inside[:, None], 0.0, -along - root)
        chord = (-along + root) - near
        rho = near[:, :, None] + r[:, None, :] * chord[:, :, None]  # (P, m, order)
        u = ux[..., None] * t1 + uy[..., None] * t2  # (P, m, 3)
        points = f[:, None, None, :] + rho[..., None] * u[:, :, None, :]
        weights = dphi[:, :, None] * chord[:, :, None] * rho * wr[:, None, :]
        return points.reshape(-1, 3), weights.ravel(), np.repeat(np.arange(len(f)), weights[0].size)

    def about(f, dirs=None):  # nothing to build once: the rule about f[at] at each call
        return lambda at, order: rule(f[at], order)

    round_piece = np.array([[centre, radius * np.asarray(t1, float), radius * np.asarray(t2, float)]])
    return Planar(centre, np.asarray(normal, float), 2.0 * radius, outside, rule, about,
                  (np.array([ROUND]), round_piece))


# --- flat emitters sampled by the stochastic methods: the rows' nodes drawn over the emitter ---------------
FLAT_TOL = 1e-9  # relative to the emitter's extent: how far from one plane an emissive shape's probes may lie


def flat(em) -> bool:
    """Whether an `area.Emitter` is flat, one plane that its every row's half-space is the same for: a quad's, a
    disk's (`planar`), an emissive shape's whose triangles (its corner probes) share one normal and one plane."""
    if em is None or em.ball is not None:
        return False
    if em.planar is not None:
        return True
    if em.probes is None:
        return False
    points, normals = em.probes
    extent = max(float(np.ptp(points, axis=0).max()), 1e-300)
    return bool(np.all(np.abs(normals - normals[0]) <= FLAT_TOL) and
                np.all(np.abs((points - points[0]) @ normals[0]) <= FLAT_TOL * extent))


def flat_rows(lights) -> np.ndarray:
    """(L,) whether each row of `lights` (lights.Lights) is a node of a flat emitter's cubature (`flat`)."""
    ems = lights.emitters
    is_flat = np.array([flat(e) for e in ems] + [False], dtype=bool)
    return is_flat[np.where(lights.cubature & (lights.owner < len(ems)), lights.owner, len(ems))]


TRIANGLE, ROUND = 0, 1  # the kinds of a flat emitter's pieces (`Planar.pieces`, `emitter_point`)


def emitter_pieces(lights):
    """The flat emitters (`flat`) of `lights` (lights.Lights) as pieces that `emitter_point` draws on, uniform in
    area: (kind (P,), frame (P, 3, 3), upper (P,) the cumulative area of its emitter's pieces up to and with
    each, first (E,), last (E,) the pieces of emitter e (none for the rest)). A quad's and a polygon's pieces
    are its fan of triangles, a disk's is itself, a flat emissive shape's its triangles."""
    kinds, frames, areas, first, last = [], [], [], [], []
    for em in lights.emitters:
        first.append(len(kinds))
        if flat(em):
            if em.planar is not None:
                k, f = em.planar.pieces
            else:
                k, f = np.full(len(em.triangles), TRIANGLE), em.triangles
            kinds += list(k)
            frames += list(f)
            areas.append(np.cumsum(_areas(np.asarray(k), np.asarray(f))))
        last.append(len(kinds))
    frames = np.array(frames, float).reshape(-1, 3, 3)
    upper = np.concatenate(areas) if areas else np.zeros(0)
    return (np.array(kinds, np.int64), frames, upper, np.array(first, np.int64), np.array(last, np.int64))


def _areas(kinds, frames):
    """(P,) the area of each piece: a triangle (a, b, c)'s |(b - a) x (c - a)| / 2; a round piece (centre, R t1,
    R t2)'s pi R^2."""
    tri = 0.5 * np.linalg.norm(np.cross(frames[:, 1] - frames[:, 0], frames[:, 2] - frames[:, 0]), axis=1)
    return np.where(kinds == TRIANGLE, tri, math.pi * np.einsum("ij,ij->i", frames[:, 1], frames[:, 1]))


@njit
def emitter_point(kind, frame, upper, first, last, u, v):
    """(x, y, z): the point of the emitter whose pieces are first .. last - 1 (`emitter_pieces`) that the numbers u,
    v in [0, 1) map to, uniform in area (density 1 / A, A = upper[last - 1]): u A picks the piece by area (binary
    search in `upper`) and, rescaled within its share to u', with v the point: a triangle (a, b, c) by the square
    to triangle map (1 - s) a + s (1 - v) b + s v c, s = sqrt(u'); a round piece (centre, R t1, R t2) by radius
    R sqrt(u') at angle 2 pi v."""
    x = u * upper[last - 1]
    lo, hi = first, last - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if x < upper[mid]:
            hi = mid
        else:
            lo = mid + 1
    below = upper[lo - 1] if lo > first else 0.0
    s = math.sqrt(min(max((x - below) / (upper[lo] - below), 0.0), 1.0))
    f = frame[lo]
    if kind[lo] == TRIANGLE:
        a, b, c = 1.0 - s, s * (1.0 - v), s * v
        return (a * f[0, 0] + b * f[1, 0] + c * f[2, 0], a * f[0, 1] + b * f[1, 1] + c * f[2, 1],
                a * f[0, 2] + b * f[1, 2] + c * f[2, 2])
    cp, sp = s * math.cos(2.0 * math.pi * v), s * math.sin(2.0 * math.pi * v)
    return (f[0, 0] + cp * f[1, 0] + sp * f[2, 0], f[0, 1] + cp * f[1, 1] + sp * f[2, 1],
            f[0, 2] + cp * f[1, 2] + sp * f[2, 2])
