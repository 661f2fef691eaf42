"""A sphere emitter about a camera ray's segment: the rule that the segment's air-light needs
(rendering/near_emitters.py, docs/area_lights.md, "Sphere emitters along a ray").

The air-light of one emitter point y = c + R n (LAMBERT falloff max(0, n·(x - y))) integrated along the
segment x = o + t d, 0 <= t <= T, is F(n). The point x sees y where n·(x - c) > R, so F vanishes on the
normals that no point of the segment sees and has kinks where a segment end's horizon (n·(x - c) = R
at t = 0 or T) or the great circle n·d = 0 (the horizon of the far end of an infinite segment) crosses
the sphere. Writing x - c = rho e + s d (e, d orthonormal, rho the distance from c to the ray's line, s
the position along it), the horizon of the point s is the circle where the plane
n·(rho e + s d) = R cuts the unit sphere. These planes are one pencil, all through the line n·e = R /
rho, n·d = 0, so each normal n lies on the horizon of exactly one point s(n) of the line, and the
point s of the line sees n where n_d (s - s(n)) > 0. The rule's coordinates are that pencil's: the
circle's parameter and the angle psi along it, n = kappa m + sigma (cos psi m' + sin psi w)
(m = (rho e + s d) / N the plane's normal, N = |rho e + s d|, kappa = R / N, sigma = sqrt(1 - kappa^2),
m' = (rho d - s e) / N, w = d x e), split where s(n) is a segment end, so F is smooth on each part:
- the line misses the sphere (rho > R): s = rho tan(gamma), gamma in (-pi/2, pi/2); all the circles
  pass through the two corners where n_d = 0 and n·e = R / rho, which cut each circle into the arc
  where n_d > 0 (lit by the points beyond s(n)) and the arc where n_d < 0 (lit by those before); parts
  (gamma in [-pi/2, gamma0], [gamma0, gamma1] on the first arc, [gamma0, gamma1], [gamma1, pi/2] on the
  second; gamma0, gamma1 of the segment's ends), Gauss–Legendre in gamma (`order` nodes) and along each
  half of each arc ((order + 1) // 2 nodes);
- the line meets the sphere (rho <= R): the circles are nested about the points where it enters and
  leaves the sphere (circles of angular radius beta: s = -+sqrt(h^2 + R^2 tan^2 beta), h =
  sqrt(R^2 - rho^2)); the side before the sphere (n_d < 0) is lit by the points of the segment before
  s(n), the side after it (n_d > 0) by those after; each side split at a segment end's beta,
  `planar.graded` in beta from the entry (exit) point, where a segment that ends on the sphere has a
  1 / |n - n_end| singularity (the Jacobian ~ beta cancels it), Gauss–Legendre along each half of each
  circle (`order` nodes: the circles' Jacobian varies faster along them near the silhouette).
Normals on no part are those that no point of the segment sees (F = 0 there). Rays that pass or end
near the silhouette concentrate their light near the normal e of the ray's closest approach, so the
nodes along each circle crowd toward its point nearest e, psi_c: psi = psi_c +- a lam sinh(v asinh(1 /
lam)) on each half (v Gauss–Legendre in [0, 1], a the half's length, lam the circle's distance from e
plus |rho - R| / R, over its radius and a, at most 1).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.vectors import perpendicular
from .area import gauss_legendre
from .planar import graded

PARTS = 4  # a segment's parts at most (module docstring)
FIRST = 4  # the coarsest order a render's ladder takes: below it two orders can agree and both be wrong
TINY = 1e-9  # the narrowest crowding along a circle (of its arc)
RINGS = (0.0, 0.25, 0.5, 0.75, 1.0 - 1e-3)  # the probes' circles of directions about the axis (of the cap's half-angle)
SPOKES = (1, 8, 12, 16, 24)  # ... and their probes along each (the last just inside the outline)
ARC = 16  # circles whose crossings with a horizon (the tangent plane) carry two probes each
ABOVE = 1e-3  # those probes' height above the horizon (a direction's cosine to the normal, of sin alpha)


@dataclass(frozen=True)
class Ball:
    """A sphere emitter as near_emitters.py (the rule) and shading.py (its probes) need it: its `centre`
    (3,) and `radius`."""
    centre: np.ndarray
    radius: float

    def outside(self, origins) -> np.ndarray:
        """(P,) whether each point lies outside the sphere (a segment from it has the rule)."""
        return np.linalg.norm(origins - self.centre, axis=1) > self.radius

    def rule(self, origins, dirs, tmax, order: int):
        """(points (M, 3), unit normals (M, 3), area weights (M,), owner (M,): the segment of each node)
        over the normals seen by the segments o + t d, 0 <= t <= tmax (origins outside the sphere,
        unit dirs), of `order` (module docstring)."""
        R = self.radius
        q = origins - self.centre
        s0 = np.einsum("ij,ij->i", q, dirs)
        perp = q - s0[:, None] * dirs
        rho = np.linalg.norm(perp, axis=1)
        e = perp / np.maximum(rho, 1e-300)[:, None]
        for i in np.nonzero(rho <= 1e-12 * R)[0]:  # a ray through the centre: any e across it
            e[i] = -perpendicular(dirs[i])
        w = np.cross(dirs, e)
        s1 = s0 + tmax
        parts = _pencil_parts(R, rho, s0, s1)  # (P, PARTS) each: kind, lo, hi, side
        normals, weights, owner = [], [], []
        for k in range(PARTS):
            kind, lo, hi, side = (a[:, k] for a in parts)
            at = np.nonzero(hi > lo)[0]
            for elliptic in (True, False):
                sel = at[(kind[at] == 0) == elliptic]
                if len(sel):
                    n, wt = _nodes(R, rho[sel], lo[sel], hi[sel], side[sel], elliptic, order,
                                   dirs[sel], e[sel], w[sel])
                    normals.append(n.reshape(-1, 3))
                    weights.append(wt.ravel())
                    owner.append(np.repeat(sel, wt.shape[1]))
        if not normals:
            return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int64)
        normals, weights, owner = np.concatenate(normals), np.concatenate(weights), np.concatenate(owner)
        keep = weights > 0.0
        normals, weights, owner = normals[keep], weights[keep], owner[keep]
        return self.centre + R * normals, normals, weights, owner

    def seen_cap(self, origins, dirs, tmax):
        """(axis (P, 3), h (P,)): a cap of the unit normals, those n with 1 - n·axis <= h, that holds all
        that the segments o + t d, 0 <= t <= tmax (outside the sphere, unit dirs) see; h >= 2 (the whole
        sphere) where a segment has no end. With q(t) = o + t d - c: the point q(t) sees the normals
        within acos(R / |q|) of q / |q|, which runs along the great arc from q(0) / |q(0)| to q(T) / |q(T)|
        (angle 2 g), and |q(t)| is convex, so every normal seen lies within g + acos(R / max |q| at the
        ends) of the arc's middle (plus 1e-9: the cap's outline, where the light vanishes, is no sample's
        concern)."""
        q0 = origins - self.centre
        tmax = np.asarray(tmax, float)
        finite = np.isfinite(tmax)
        q1 = q0 + np.where(finite, tmax, 0.0)[:, None] * dirs
        n0, n1 = np.linalg.norm(q0, axis=1), np.linalg.norm(q1, axis=1)
        u0, u1 = q0 / n0[:, None], q1 / n1[:, None]
        mid = u0 + u1
        axis = mid / np.maximum(np.linalg.norm(mid, axis=1), 1e-300)[:, None]
        half = np.arctan2(np.linalg.norm(u0 - u1, axis=1), np.linalg.norm(mid, axis=1))
        angle = half + np.arccos(np.minimum(self.radius / np.maximum(n0, n1), 1.0)) + 1e-9
        h = np.where(finite & (angle < np.pi), 2.0 * np.sin(0.5 * np.minimum(angle, np.pi)) ** 2, 2.0)
        return axis, h

    def sample_cap(self, axis, h, u, v):
        """(points (P K, 3), unit normals (P K, 3), area density (P K,)): (u, v) (P, K) in [0, 1) mapped
        uniformly in area onto the caps 1 - n·axis <= h (`seen_cap`): n·axis = 1 - u h, azimuth 2 pi v
        about the axis (Archimedes), the density 1 / (2 pi R^2 h); row by row as u.ravel()."""
        z = 1.0 - u * h[:, None]
        s = np.sqrt(np.maximum(0.0, 1.0 - z * z))
        e1, e2 = _across(axis)
        phi = 2.0 * np.pi * v
        normals = (z[..., None] * axis[:, None, :] + (s * np.cos(phi))[..., None] * e1[:, None, :]
                   + (s * np.sin(phi))[..., None] * e2[:, None, :])
        density = np.broadcast_to(1.0 / (2.0 * np.pi * self.radius ** 2 * h[:, None]), z.shape).ravel()
        normals = normals.reshape(-1, 3)
        return self.centre + self.radius * normals, normals, density

    def probes(self, points, normals):
        """(M, K) probes of the part of the sphere each of M points outside it sees, the same K for every
        cubature order (shading.py's penumbra test): (points (M, K, 3) on the sphere, NaN where unused),
        along the directions w of the cap of half-angle alpha (sin alpha = R / d) about the axis a toward
        the centre: its centre, circles at RINGS x alpha from a with SPOKES probes each (the last just
        inside the outline), and where each of ARC circles crosses the horizon of the unit `normals`
        (M, 3) or of each of a list of them (the shading normals' terminator too) two probes ABOVE sin
        alpha over it. The point on the sphere along w is x + s w, s = d cos beta - sqrt(R^2 - d^2 sin^2
        beta) (the nearer crossing); all NaN at points on or inside the sphere."""
        R = self.radius
        rel = self.centre - points
        d = np.linalg.norm(rel, axis=1)
        a = rel / d[:, None]
        sin_a = np.minimum(R / d, 1.0)
        alpha = np.arcsin(sin_a)
        beta, phi = [], []
        for ring, spokes in zip(RINGS, SPOKES):
            beta.append(np.repeat(ring * alpha[:, None], spokes, axis=1))
            phi.append(np.broadcast_to(2.0 * np.pi * (np.arange(spokes) + 0.5 * (spokes > 1)) / spokes,
                                       (len(d), spokes)))
        u, v = _across(a)
        arcs = (np.arange(ARC) + 1.0) / ARC * (1.0 - 1e-3)  # of alpha
        for n in normals if isinstance(normals, list) else [normals]:
            # along the circle at beta: n.w = cos beta (n.a) + sin beta (cos phi n.u + sin phi n.v); with
            # n.u = r cos phi0, n.v = r sin phi0: cos(phi - phi0) = (height - cos beta n.a) / (r sin beta)
            na, nu, nv = (np.einsum("ij,ij->i", n, e) for e in (a, u, v))
            r, phi0 = np.hypot(nu, nv), np.arctan2(nv, nu)
            b = arcs[None, :] * alpha[:, None]
            height = ABOVE * sin_a[:, None]
            with np.errstate(divide="ignore", invalid="ignore"):
                c = (height - np.cos(b) * na[:, None]) / (r[:, None] * np.sin(b))
            across = np.arccos(np.where(np.abs(c) < 1.0, c, np.nan))  # NaN: the circle does not cross it
            beta += [b, b]
            phi += [phi0[:, None] + across, phi0[:, None] - across]
        beta, phi = np.concatenate(beta, axis=1), np.concatenate(phi, axis=1)
        w = (np.cos(beta)[..., None] * a[:, None, :] + np.sin(beta)[..., None] *
             (np.cos(phi)[..., None] * u[:, None, :] + np.sin(phi)[..., None] * v[:, None, :]))
        s = d[:, None] * np.cos(beta) - np.sqrt(np.maximum(R * R - (d[:, None] * np.sin(beta)) ** 2, 0.0))
        s[~(d > R)] = np.nan  # on or inside the sphere: nothing seen from outside
        return points[:, None, :] + s[..., None] * w


def _across(a):
    """(u, v) (M, 3) each: unit vectors that make (u, v, a) orthonormal, per unit row of `a` (M, 3)."""
    alt = np.where((np.abs(a[:, 0]) < 0.9)[:, None], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    u = np.cross(a, alt)
    u /= np.linalg.norm(u, axis=1)[:, None]
    return u, np.cross(a, u)


def _pencil_parts(R, rho, s0, s1):
    """Per segment (P,) its PARTS parts (kind (P, PARTS): 0 elliptic (the line misses), 1 hyperbolic;
    lo, hi: the range of gamma or beta, empty where hi <= lo; side: the arc (elliptic: +1 where n_d > 0)
    or the side (hyperbolic: -1 before the sphere, +1 after it))."""
    p = len(rho)
    kind, lo, hi, side = np.zeros((p, PARTS), np.int64), np.zeros((p, PARTS)), np.zeros((p, PARTS)), np.zeros((p, PARTS))
    ell = rho > R
    with np.errstate(divide="ignore", invalid="ignore"):
        g0, g1 = np.arctan2(s0, rho), np.where(np.isinf(s1), 0.5 * np.pi, np.arctan2(s1, rho))
    half = 0.5 * np.pi
    for k, (a, b, sd) in enumerate(((-half, g0, 1.0), (g0, g1, 1.0), (g0, g1, -1.0), (g1, half, -1.0))):
        lo[ell, k], hi[ell, k], side[ell, k] = np.broadcast_to(a, p)[ell], np.broadcast_to(b, p)[ell], sd
    hyp = ~ell
    h = np.sqrt(np.maximum(R * R - rho * rho, 0.0))

    def beta(s):
        with np.errstate(invalid="ignore"):
            return np.where(np.isinf(s), half, np.arctan(np.sqrt(np.maximum(s * s - h * h, 0.0)) / R))

    b0, b1 = beta(s0), beta(s1)
    # before the sphere (s <= -h): lit where s > s0; split at s1
    before = s0 < -h
    cut = np.where(before & (s1 < -h), b1, 0.0)
    top = np.where(before, b0, 0.0)
    # after it (s >= h): lit where s < s1; split at s0
    after = s1 > h
    cut2 = np.where(after & (s0 > h), b0, 0.0)
    top2 = np.where(after, b1, 0.0)
    for k, (a, b, sd) in enumerate(((0.0, cut, -1.0), (cut, top, -1.0), (0.0, cut2, 1.0), (cut2, top2, 1.0))):
        kind[hyp, k] = 1
        lo[hyp, k], hi[hyp, k], side[hyp, k] = np.broadcast_to(a, p)[hyp], np.broadcast_to(b, p)[hyp], sd
    return kind, lo, hi, side


def _nodes(R, rho, lo, hi, side, elliptic: bool, order: int, d, e, w):
    """(normals (P, K, 3), area weights (P, K)) of one part of each of P segments (`_pencil_parts`)."""
    if elliptic:
        x, wx = gauss_legendre(order)
        p = lo[:, None] + (hi - lo)[:, None] * x[None]
        wp = (hi - lo)[:, None] * wx[None]
        kappa = R * np.cos(p) / rho[:, None]
        kappa_p = -R * np.sin(p) / rho[:, None]
        sigma = np.sqrt(np.maximum(1.0 - kappa * kappa, 0.0))
        sigma_p = -kappa * kappa_p / sigma
        omega = np.ones_like(p)  # d(angle of m) / d(gamma)
        cos_k = np.clip(-R * np.sin(p) / (sigma * rho[:, None]), -1.0, 1.0)
        psi_k = np.arccos(cos_k)  # the corners' psi
        m_n = np.cos(p)[..., None] * e[:, None, :] + np.sin(p)[..., None] * d[:, None, :]
        m_t = np.cos(p)[..., None] * d[:, None, :] - np.sin(p)[..., None] * e[:, None, :]
    else:
        h = np.sqrt(np.maximum(R * R - rho * rho, 0.0))
        from_limit = lo <= 0.0  # parts from the entry (exit) point: graded there
        (xg, wg), (xl, wl) = graded(order), gauss_legendre(order)
        x, wx = np.where(from_limit[:, None], xg, xl), np.where(from_limit[:, None], wg, wl)
        p = lo[:, None] + (hi - lo)[:, None] * x
        wp = (hi - lo)[:, None] * wx
        tb = np.tan(p)
        root = np.sqrt(h[:, None] ** 2 + (R * tb) ** 2)
        s = side[:, None] * root
        kappa, kappa_p, sigma, sigma_p = np.cos(p), -np.sin(p), np.sin(p), np.cos(p)
        omega = side[:, None] * rho[:, None] * tb / np.maximum(root, 1e-300)  # d(angle of m) / d(beta)
        big_n = np.hypot(rho[:, None], s)
        m_n = (rho[:, None, None] * e[:, None, :] + s[..., None] * d[:, None, :]) / big_n[..., None]
        m_t = (rho[:, None, None] * d[:, None, :] - s[..., None] * e[:, None, :]) / big_n[..., None]
    # along each circle: crowded toward psi_c, its point nearest the foot normal e (module docstring)
    toward = side[:, None] < 0.0 if not elliptic else side[:, None] > 0.0  # psi_c = 0 there, else pi
    near_e = kappa * np.einsum("pkj,pj->pk", m_n, e) + np.where(toward, sigma, -sigma) * np.einsum("pkj,pj->pk", m_t, e)
    width = (np.sqrt(np.maximum(2.0 - 2.0 * near_e, 0.0)) + abs(rho - R)[:, None] / R) / sigma  # of the peak, in psi
    psi_c = np.where(toward, 0.0, np.pi)[..., None]
    half = np.where(side[:, None] > 0.0, psi_k, np.pi - psi_k) if elliptic else np.full_like(p, np.pi)
    half = half[..., None]  # (P, order, 1): half the arc (of the whole circle)
    lam = np.clip(width[..., None] / half, TINY, 1.0)
    v, wv = gauss_legendre((order + 1) // 2 if elliptic else order)  # per half (module docstring)
    v, wv = np.concatenate([-v[::-1], v]), np.concatenate([wv[::-1], wv])  # the two halves
    stretch = np.arcsinh(1.0 / lam)
    psi = psi_c + np.sign(v) * half * lam * np.sinh(np.abs(v) * stretch)
    wpsi = half * lam * stretch * np.cosh(np.abs(v) * stretch) * wv
    cp, sp = np.cos(psi)[..., None], np.sin(psi)[..., None]
    ww = w[:, None, None, :]
    m_n, m_t = m_n[:, :, None, :], m_t[:, :, None, :]
    k3, kp3, sg3, sgp3, om3 = (a[..., None, None] for a in (kappa, kappa_p, sigma, sigma_p, omega))
    ring = cp * m_t + sp * ww
    normals = k3 * m_n + sg3 * ring
    dn_dp = kp3 * m_n + k3 * om3 * m_t + sgp3 * ring - sg3 * cp * om3 * m_n
    dn_dpsi = sg3 * (-sp * m_t + cp * ww)
    jac = np.linalg.norm(np.cross(dn_dp, dn_dpsi), axis=-1)
    weights = R * R * jac * wp[..., None] * wpsi
    normals = normals / np.linalg.norm(normals, axis=-1, keepdims=True)
    return normals.reshape(len(rho), -1, 3), weights.reshape(len(rho), -1)
