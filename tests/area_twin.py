"""A brute-force twin of the single scattering from an area light in a homogeneous isotropic medium
with nothing else in the scene, built from the geometry alone (numpy and scipy, no project code):

    L(ray) = int_0^T e^{-kt t} ks / (4 pi) E(o + t w) dt + [front hit] L e^{-kt T},
    E(x) = int_emitter L max(0, n(y)·(x - y)) e^{-kt r} / r^3 dA(y),   r = |x - y|,

T the distance to the emitter (inf if the ray misses it). E of a planar emitter (`exact=True`) in polar coordinates
about x's foot point p on its plane (h the distance to the plane, r^2 = h^2 + rho^2, rho d rho = r dr):
the integral in rho is closed, int_h^R h e^{-kt r} / r^2 dr = E2(kt h) - h E2(kt R) / R (E2 the
exponential integral), which leaves a 1-D integral (scipy quad) over the emitter's outline seen from p:
no 1/r singularity about the foot point, so rays that pass near or end on the emitter are as exact as
the rest (about a second a ray); else (faster, exact to rounding away from the emitter, to about 1e-4
on rays that end on it) and in `box_radiance` (media inside a box) by a composite Gauss–Legendre rule
over the emitter's parameter domain (`panels` x `panels` cells of NODES x NODES nodes). The sphere by
its visible cap, a 1-D integral in the angle from the cap's axis. The distance integral by scipy quad.
Camera rays per SCENE_FORMAT.md's convention.
"""
from __future__ import annotations

import math

import numpy as np
from scipy import integrate, special

NODES = 16


def camera_rays(position, look_at, up, fov, width, height):
    """(H, W, 3) unit directions through the pixel centres (SCENE_FORMAT.md)."""
    f = np.asarray(look_at, float) - position
    f /= np.linalg.norm(f)
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    tan = math.tan(math.radians(fov) / 2)
    i, j = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    d = f + ((2 * i / width - 1) * tan * width / height)[..., None] * r + ((1 - 2 * j / height) * tan)[..., None] * u
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def _composite(panels):
    x, w = np.polynomial.legendre.leggauss(NODES)
    edges = np.linspace(0.0, 1.0, panels + 1)
    h = np.diff(edges)
    nodes = (edges[:-1, None] + 0.5 * h[:, None] * (x[None, :] + 1.0)).ravel()
    return nodes, (0.5 * h[:, None] * w[None, :]).ravel()


class Quad:
    """c0 + u e1 + v e3, normal e1 x e3 normalised; one-sided unless two_sided."""

    def __init__(self, corners, radiance, two_sided=False, panels=4, exact=False):
        self.exact = exact
        c = np.asarray(corners, float)
        self.c0, self.e1, self.e3 = c[0], c[1] - c[0], c[3] - c[0]
        cross = np.cross(self.e1, self.e3)
        self.area, self.n = np.linalg.norm(cross), cross / np.linalg.norm(cross)
        self.L, self.two = radiance, two_sided
        s, ws = _composite(panels)
        uu, vv = np.meshgrid(s, s, indexing="ij")
        self.y = self.c0 + uu.reshape(-1, 1) * self.e1 + vv.reshape(-1, 1) * self.e3
        self.w = np.outer(ws, ws).ravel() * self.area

    def centre(self):
        return self.c0 + 0.5 * (self.e1 + self.e3)

    def hit(self, o, w):
        """(T, front): distance along the ray to the quad (inf if missed) and whether it is the emitting side."""
        den = w @ self.n
        if den == 0.0:
            return math.inf, False
        t = (self.c0 - o) @ self.n / den
        if t <= 0.0:
            return math.inf, False
        p = o + t * w - self.c0
        g = np.array([[self.e1 @ self.e1, self.e1 @ self.e3], [self.e1 @ self.e3, self.e3 @ self.e3]])
        a, b = np.linalg.solve(g, [p @ self.e1, p @ self.e3])
        if not (0.0 <= a <= 1.0 and 0.0 <= b <= 1.0):
            return math.inf, False
        return t, den < 0.0 or self.two

    def corners(self):
        return [self.c0, self.c0 + self.e1, self.c0 + self.e1 + self.e3, self.c0 + self.e3]

    def polar(self, p, h, kt):
        """int over the emitter of G(rho) d phi about p in its plane: the convex polygon's edges (a, b),
        each the signed triangle (p, a, b), parametrised along the edge."""
        total = 0.0
        cs = self.corners()
        for a, b in zip(cs, cs[1:] + cs[:1]):
            e = b - a
            s0 = (p - a) @ e / (e @ e)

            def f(s):
                q = a + s * e - p
                return _G(math.sqrt(q @ q), h, kt) * (np.cross(q, e) @ self.n) / (q @ q)

            pts = [s0] if 0.0 < s0 < 1.0 else None
            total += integrate.quad(f, 0.0, 1.0, points=pts, epsabs=0.0, epsrel=1e-12, limit=200)[0]
        return total

    def irradiance(self, x, kt, box=None):
        """At x: the emitter's light attenuated over its whole path (`polar` where exact, else the
        composite rule), or (`box` = (lo, hi): x inside an axis-aligned box holding the medium, vacuum
        outside) over the part of its path inside the box (the composite rule)."""
        if box is None and self.exact:
            h = (x - self.centre()) @ self.n
            h = abs(h) if self.two else h
            return 0.0 if h <= 0.0 else self.L * self.polar(x - h * np.sign((x - self.centre()) @ self.n) * self.n,
                                                            h, kt)
        d = x[None, :] - self.y
        r = np.linalg.norm(d, axis=1)
        c = d @ self.n
        c = np.abs(c) if self.two else np.maximum(c, 0.0)
        depth = r if box is None else r * np.minimum(1.0, _exit_fraction(x, self.y, *box))
        return self.L * np.sum(self.w * c * np.exp(-kt * depth) / r**3)


def _G(rho, h, kt):
    """int_0^rho h e^{-kt r} / r^3 rho' d rho' (r^2 = h^2 + rho'^2) = E2(kt h) - h E2(kt r) / r."""
    r = math.hypot(h, rho)
    return special.expn(2, kt * h) - h * special.expn(2, kt * r) / r


def _exit_fraction(x, y, lo, hi):
    """For x inside the box [lo, hi] and points y (n, 3): the fraction of each segment x -> y inside it."""
    step = y - x[None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        ends = np.where(step > 0.0, (np.asarray(hi) - x) / step, np.where(step < 0.0, (np.asarray(lo) - x) / step, np.inf))
    return ends.min(axis=1)


def box_chord(lo, hi, o, w):
    """(t0, t1): the ray o + t w inside the box [lo, hi] (t0 >= t1 where it misses)."""
    with np.errstate(divide="ignore"):
        a, b = (np.asarray(lo) - o) / w, (np.asarray(hi) - o) / w
    return max(0.0, np.minimum(a, b).max()), np.maximum(a, b).min()


def box_radiance(emitter, lo, hi, o, w, kt, ks):
    """The twin's radiance of the camera ray o + t w in vacuum through an index-matched box [lo, hi]
    holding a homogeneous isotropic medium, the emitter outside it (not seen by the ray)."""
    t0, t1 = box_chord(lo, hi, o, w)
    if t1 <= t0:
        return 0.0
    f = lambda t: math.exp(-kt * (t - t0)) * ks / (4 * math.pi) * emitter.irradiance(o + t * w, kt, (lo, hi))  # noqa: E731
    return integrate.quad(f, t0, t1, epsabs=0.0, epsrel=1e-12, limit=400)[0]


class Disk(Quad):
    def __init__(self, center, normal, radius, radiance, two_sided=False, panels=4, exact=False):
        self.exact = exact
        self.c, self.n, self.R = np.asarray(center, float), np.asarray(normal, float) / np.linalg.norm(normal), radius
        self.L, self.two, self.area = radiance, two_sided, math.pi * radius**2
        alt = np.array([1.0, 0, 0]) if abs(self.n[0]) < 0.9 else np.array([0, 1.0, 0])
        t1 = np.cross(alt, self.n)
        t1 /= np.linalg.norm(t1)
        t2 = np.cross(self.n, t1)
        self.t1, self.t2 = t1, t2
        s, ws = _composite(panels)
        rr, pp = np.meshgrid(s * radius, s * 2 * math.pi, indexing="ij")
        self.y = self.c + rr.reshape(-1, 1) * (np.cos(pp).reshape(-1, 1) * t1 + np.sin(pp).reshape(-1, 1) * t2)
        self.w = (np.outer(ws * radius, ws * 2 * math.pi) * rr).ravel()

    def centre(self):
        return self.c

    def polar(self, p, h, kt):
        """int over the disk of G(rho) d phi about p in its plane: the rays from p cross the circle at
        rho1 < rho2 (rho1 = 0 inside)."""
        q = p - self.c
        dq = math.sqrt(q @ q)

        def crossings(phi):
            u = math.cos(phi) * self.t1 + math.sin(phi) * self.t2
            b = q @ u
            disc = math.sqrt(max(0.0, b * b - (dq * dq - self.R * self.R)))
            return max(0.0, -b - disc), -b + disc

        def f(phi):
            r1, r2 = crossings(phi)
            return _G(r2, h, kt) - _G(r1, h, kt)

        if dq < self.R:
            return integrate.quad(f, 0.0, 2 * math.pi, epsabs=0.0, epsrel=1e-12, limit=200)[0]
        toward = math.atan2(-q @ self.t2, -q @ self.t1)
        half = math.asin(self.R / dq)
        return integrate.quad(f, toward - half, toward + half, epsabs=0.0, epsrel=1e-12, limit=200)[0]

    def hit(self, o, w):
        den = w @ self.n
        if den == 0.0:
            return math.inf, False
        t = (self.c - o) @ self.n / den
        if t <= 0.0 or np.linalg.norm(o + t * w - self.c) > self.R:
            return math.inf, False
        return t, den < 0.0 or self.two


class Sphere:
    def __init__(self, center, radius, radiance):
        self.c, self.R, self.L = np.asarray(center, float), radius, radiance

    def centre(self):
        return self.c

    def hit(self, o, w):
        oc = o - self.c
        b = oc @ w
        disc = b * b - (oc @ oc - self.R**2)
        if disc < 0.0 or -b - math.sqrt(disc) <= 0.0:
            return math.inf, False
        return -b - math.sqrt(disc), True

    def irradiance(self, x, kt):
        """The visible cap (cos beta >= R / d about the axis toward x), integrated in beta (the distance
        and the falloff in their forms without cancellation near the surface, the cap split at beta ~
        (d - R) / R where the integrand peaks there; 0 on the sphere and inside it)."""
        d = np.linalg.norm(x - self.c)
        R = self.R
        if d <= R:
            return 0.0

        def f(beta):
            half = math.sin(0.5 * beta) ** 2
            r = math.sqrt((d - R) ** 2 + 4.0 * d * R * half)
            return ((d - R) - 2.0 * d * half) / r * math.exp(-kt * r) / r**2 * 2 * math.pi * R * R * math.sin(beta)

        top = math.acos(R / d)
        cuts = [0.0] + [b for b in (10.0 * (d - R) / R,) if b < top] + [top]
        return self.L * sum(integrate.quad(f, a, b, epsabs=0.0, epsrel=1e-12, limit=200)[0]
                            for a, b in zip(cuts, cuts[1:]))


def radiance(emitter, o, w, kt, ks):
    """The twin's radiance of the camera ray o + t w (isotropic phase 1 / (4 pi))."""
    T, front = emitter.hit(o, w)
    f = lambda t: math.exp(-kt * t) * ks / (4 * math.pi) * emitter.irradiance(o + t * w, kt)  # noqa: E731
    tc = max(0.0, (emitter.centre() - o) @ w)  # split where the ray passes the emitter
    n = getattr(emitter, "n", None)  # and where it crosses a planar emitter's plane
    tp = (emitter.centre() - o) @ n / (w @ n) if n is not None and w @ n != 0.0 else -1.0
    cuts = [0.0] + sorted(c for c in (tc, 2 * tc + 10.0, tp) if 0.0 < c < T) + [T]
    air = sum(integrate.quad(f, a, b, epsabs=0.0, epsrel=1e-11, limit=400)[0] for a, b in zip(cuts, cuts[1:]))
    return air + (emitter.L * math.exp(-kt * T) if front else 0.0)


class PlateShadow:
    """A one-sided quad emitter facing down, [ax0, ax1] x [bz0, bz1] at height `height` (radiance L), over
    an opaque horizontal plate [px0, px1] x [pz0, pz1] at height `plate` < `height`, and a black floor
    [-floor, floor]^2 at y = 0, in a homogeneous isotropic medium everywhere. From x below the plate, the emitter points
    y whose segment to x crosses the plate's height inside it are hidden: with s = (plate - x_y) /
    (height - x_y) the fraction of the way to the emitter where it does, the hidden points form the
    rectangle x + ([px0, px1] - x) / s (in x and z) clipped to the emitter, so the visible part's
    irradiance is the emitter's less that rectangle's, each by a composite Gauss–Legendre rule."""

    def __init__(self, emitter_x, emitter_z, height, radiance, plate_x, plate_z, plate, floor, panels=2):
        self.ex, self.ez, self.H, self.L, self.floor = emitter_x, emitter_z, height, radiance, (-floor, floor)
        self.px, self.pz, self.P = plate_x, plate_z, plate
        self.s, self.ws = _composite(panels)

    def _rect(self, x, a, b, kt):
        """int over [a0, a1] x [b0, b1] at the emitter's height of L h e^{-kt r} / r^3 (h = H - x_y)."""
        if a[1] <= a[0] or b[1] <= b[0]:
            return 0.0
        h = self.H - x[1]
        aa = a[0] + (a[1] - a[0]) * self.s
        bb = b[0] + (b[1] - b[0]) * self.s
        r = np.sqrt((aa[:, None] - x[0]) ** 2 + h * h + (bb[None, :] - x[2]) ** 2)
        w = np.outer(self.ws * (a[1] - a[0]), self.ws * (b[1] - b[0]))
        return self.L * h * np.sum(w * np.exp(-kt * r) / r**3)

    def hidden(self, x):
        """The hidden rectangle ((a0, a1), (b0, b1)) of the emitter seen from x (empty above the plate)."""
        if x[1] >= self.P:
            return (0.0, 0.0), (0.0, 0.0)
        s = (self.P - x[1]) / (self.H - x[1])
        return tuple((max(e[0], c + (p[0] - c) / s), min(e[1], c + (p[1] - c) / s))
                     for e, p, c in ((self.ex, self.px, x[0]), (self.ez, self.pz, x[2])))

    def irradiance(self, x, kt):
        if x[1] >= self.H:
            return 0.0
        return self._rect(x, self.ex, self.ez, kt) - self._rect(x, *self.hidden(x), kt)

    def end(self, o, w):
        """The distance to the floor or the plate along the ray (inf: neither)."""
        ends = [math.inf]
        for y, xs, zs in ((0.0, self.floor, self.floor), (self.P, self.px, self.pz)):
            if w[1] != 0.0 and (y - o[1]) / w[1] > 0.0:
                t = (y - o[1]) / w[1]
                p = o + t * w
                if xs[0] <= p[0] <= xs[1] and zs[0] <= p[2] <= zs[1]:
                    ends.append(t)
        return min(ends)

    def kinks(self, o, w, T):
        """The distances along the ray where the hidden rectangle's edges meet the emitter's edges or
        the ray crosses the plate's height (the integrand's kinks): roots of quadratics in t."""
        out = []
        if w[1] != 0.0:
            out.append((self.P - o[1]) / w[1])
        for k, e, p in ((0, self.ex, self.px), (2, self.ez, self.pz)):
            for c in e:
                for q in p:  # (x_k - c)(P - x_y) + (q - x_k)(H - x_y) = 0, x = o + t w
                    a0, a1 = o[k] - c, w[k]
                    b0, b1 = self.P - o[1], -w[1]
                    c0, c1 = q - o[k], -w[k]
                    d0, d1 = self.H - o[1], -w[1]
                    coeffs = [a1 * b1 + c1 * d1, a0 * b1 + a1 * b0 + c0 * d1 + c1 * d0, a0 * b0 + c0 * d0]
                    out += [r.real for r in np.roots(coeffs) if abs(r.imag) < 1e-12]
        return sorted(t for t in out if 0.0 < t < T)

    def radiance(self, o, w, kt, ks):
        """The air-light of the camera ray o + t w up to the floor or the plate (both black)."""
        T = self.end(o, w)
        f = lambda t: math.exp(-kt * t) * ks / (4 * math.pi) * self.irradiance(o + t * w, kt)  # noqa: E731
        cuts = [0.0] + self.kinks(o, w, T if T < math.inf else 1e3) + [T]
        return sum(integrate.quad(f, a, b, epsabs=0.0, epsrel=1e-10, limit=400)[0] for a, b in zip(cuts, cuts[1:]))
