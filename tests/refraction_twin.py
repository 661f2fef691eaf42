"""A twin, from the geometry alone, of a lamp's light refracted into a closed glass mesh that holds a fog and is seen
through its surface (no renderer code: its own float64 ray-triangle tests, tests/oracle.py).

At each point X inside, for every triangle whose plane separates X from the lamp L, the refraction point R of the
path L -> R -> X by Fermat's principle (Snell's law in the plane of incidence, sin1 = eta sin2, bisected to the
last bit for all triangles at once), kept when R lies inside the triangle and neither leg (X to R, R to L) meets
another triangle; Fresnel's unpolarised transmittance in its angle form; the ray tube's irradiance across the
refracted beam at distance k beyond R in closed form (`tube_irradiance`, checked against the U twin's central
differences of the map R' -> R' + k t(R') in tests/test_torus_glass_twin.py; its Fresnel T and refraction are the
U twin's, tests/test_nonconvex_refraction.py). A camera ray's value is its first stretch inside the mesh:
exp(-kt_out t0) T(cos_i) / eta^2 times the integral of ks p(mu) E exp(-kt x) over the stretch, split where the set
of lit faces changes (`changes`) and integrated by scipy quad_vec between the cuts.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import integrate

from . import oracle
from .test_nonconvex_refraction import refract, transmittance


def obj_triangles(text: str) -> np.ndarray:
    """The triangles (T, 3, 3) of an OBJ's text (its v and f lines)."""
    lines = text.splitlines()
    v = [list(map(float, line.split()[1:4])) for line in lines if line.startswith("v ")]
    return np.array([[v[int(k.split("/")[0]) - 1] for k in line.split()[1:]] for line in lines if line.startswith("f ")])


def tube_irradiance(o, hl, k, eta):
    """Irradiance per unit intensity, before Fresnel, across the refracted beam at distance k beyond R, the lamp at
    distance o from R and height hl over the face's plane: cos1 / o^2 per unit area of the plane, over the beam's
    cross-section there per unit area of the plane. By the symmetry about the lamp's normal to the plane the map
    R -> R + k t(R) stretches the circle of radius r about the lamp's foot by 1 + k sin2 / r = 1 + k / (eta o) and
    the radial direction, across the beam, by cos2 + k d(theta2)/dr = cos2 + k hl^2 / (eta o^3 cos2)
    (eta sin2 = r / o)."""
    cos1 = hl / o
    sin2 = math.sqrt(max(o * o - hl * hl, 0.0)) / (eta * o)
    cos2 = math.sqrt(1.0 - sin2 * sin2)
    return cos1 / o ** 2 / ((1.0 + k / (eta * o)) * (cos2 + k * hl * hl / (eta * o ** 3 * cos2)))


def changes(signature, ell, n=401, tol=1e-15):
    """[0, ..., ell]: the points of (0, ell) where `signature(x)` (the set of faces lighting x) changes, found on a
    grid of n points (its ends 1e-9 of ell inside) and bisected to tol x ell; a set met halfway that differs from
    both ends' splits the search in two, so that a face lit on a sliver between two changes (a path leaving one
    face at its edge and the next face's appearing a few 1e-8 further) gives both."""
    grid = np.linspace(0.0, ell, n)
    grid[0], grid[-1] = 1e-9 * ell, ell * (1 - 1e-9)
    sig = [signature(x) for x in grid]
    stack = [(a, b, sa, sb) for a, b, sa, sb in zip(grid, grid[1:], sig, sig[1:]) if sa != sb]
    cuts = []
    while stack:
        a, b, sa, sb = stack.pop()
        if b - a <= tol * ell:
            cuts.append(0.5 * (a + b))
            continue
        m = 0.5 * (a + b)
        sm = signature(m)
        stack += [(a, m, sa, sm)] * (sm != sa) + [(m, b, sm, sb)] * (sm != sb)
    return [0.0, *sorted(cuts), ell]


@dataclass
class Glass:
    """A closed mesh (T, 3, 3) of index eta holding a fog (ka, ks (3,), HG g) in an outside of absorption kt_out,
    lit by a point or spot light (a [[light]] table)."""
    tris: np.ndarray
    eta: float
    ka: np.ndarray
    ks: np.ndarray
    g: float
    kt_out: float
    light: dict

    def __post_init__(self):
        cross = np.cross(self.tris[:, 1] - self.tris[:, 0], self.tris[:, 2] - self.tris[:, 0])
        self.normals = cross / np.linalg.norm(cross, axis=1)[:, None]
        self.offsets = np.einsum("ij,ij->i", self.normals, self.tris[:, 0])
        self.lamp = np.array(self.light["position"], float)
        self.spot = oracle.spot_of(self.light)

    def hits(self, o, d):
        """The ray parameter t of o + t d on every triangle (inf where it misses)."""
        t, u, v, det = oracle.triangle_hits(self.tris, o, d)
        with np.errstate(invalid="ignore"):
            ok = (np.abs(det) > 1e-14) & (u >= 0) & (v >= 0) & (u + v <= 1)
        return np.where(ok, t, np.inf)

    def first(self, o, d, tmin=1e-9):
        t = self.hits(o, d)
        t = np.where(t > tmin, t, np.inf)
        k = int(np.argmin(t))
        return t[k], k

    def crosses(self, a, b, skip):
        """Whether the segment a b meets a triangle other than `skip` (away from its ends)."""
        t = self.hits(a, b - a)
        t[skip] = np.inf
        return bool(np.any((t > 1e-9) & (t < 1.0 - 1e-9)))

    def fermat_points(self, X):
        """(faces, R (F, 3), normals toward the lamp (F, 3)): the refraction points inside their triangles of the
        paths from the lamp to X through every face whose plane separates them."""
        n, c, L = self.normals, self.offsets, self.lamp
        hl, z = n @ L - c, c - n @ X
        f = np.nonzero(hl * z > 0)[0]
        sign = np.sign(hl[f])
        n, hl, z = n[f] * sign[:, None], hl[f] * sign, z[f] * sign
        foot = X + z[:, None] * n
        lh = L - hl[:, None] * n - foot
        rho = np.linalg.norm(lh, axis=1)
        lo, hi = np.zeros_like(rho), rho.copy()
        for _ in range(64):  # (rho - r) / |L - R| - eta r / |R - X| falls from > 0 at r = 0 to < 0 at rho
            m = 0.5 * (lo + hi)
            up = (rho - m) / np.hypot(rho - m, hl) - self.eta * m / np.hypot(m, z) > 0
            lo, hi = np.where(up, m, lo), np.where(up, hi, m)
        r = 0.5 * (lo + hi)
        R = foot + np.where(rho > 0, r / np.where(rho > 0, rho, 1.0), 0.0)[:, None] * lh
        a, b, cc = self.tris[f, 0], self.tris[f, 1], self.tris[f, 2]
        v0, v1, v2 = b - a, cc - a, R - a
        d00, d01, d11 = (v0 * v0).sum(1), (v0 * v1).sum(1), (v1 * v1).sum(1)
        d20, d21 = (v2 * v0).sum(1), (v2 * v1).sum(1)
        den = d00 * d11 - d01 * d01
        u, v = (d11 * d20 - d01 * d21) / den, (d00 * d21 - d01 * d20) / den
        inside = (u >= 0) & (v >= 0) & (u + v <= 1)
        return f[inside], R[inside], n[inside]

    def paths_of(self, X):
        """(face, unit direction of travel at X, value per channel) of every path from the light to X: its
        emission, the ray tube's irradiance with Fresnel's T and both legs' transmittance."""
        out = []
        for f, R, n in zip(*self.fermat_points(X)):
            if self.crosses(X, R, f) or self.crosses(R, self.lamp, f):
                continue
            k, o = np.linalg.norm(R - X), np.linalg.norm(self.lamp - R)
            hl = float((self.lamp - R) @ n)
            e = self.light["intensity"] * oracle.emission(self.spot, (R - self.lamp) / o) \
                * transmittance(hl / o, self.eta) * tube_irradiance(o, hl, k, self.eta)
            out.append((int(f), (X - R) / k, e * np.exp(-(self.ka + self.ks) * k - self.kt_out * o)))
        return out

    def entering(self, o, d):
        """(t0, n, P, w): the distance to the entry point, the face's normal against the ray, the entry point and
        the refracted direction of the ray (o, d); None where it misses or its reflection meets the mesh again."""
        t0, f0 = self.first(o, d)
        if not np.isfinite(t0):
            return None
        n = self.normals[f0] * (-1.0 if self.normals[f0] @ d > 0 else 1.0)
        P = o + t0 * d
        if np.isfinite(self.first(P, d - 2 * (d @ n) * n)[0]):
            return None
        return t0, n, P, refract(d, n, self.eta)

    def inside_stretch(self, o, d):
        """(t0, cos_i, P, w, ell): the distance to the entry point, the cosine of incidence there, the entry point,
        the refracted direction and the length of the camera ray (o, d)'s first stretch inside (`entering`); None
        where it misses, or its reflection or its way out meets the mesh again (light the twin does not follow)."""
        hit = self.entering(o, d)
        if hit is None:
            return None
        t0, n, P, w = hit
        ell, f1 = self.first(P, w)
        n1 = self.normals[f1] * (1.0 if self.normals[f1] @ w > 0 else -1.0)
        out_dir = refract(w, -n1, 1.0 / self.eta)
        if out_dir is not None and np.isfinite(self.first(P + ell * w, out_dir)[0]):
            return None
        return t0, -float(d @ n), P, w, ell

    def pixel(self, o, d, epsrel=1e-12):
        """(radiance (3,), cuts along the stretch) of the camera ray (o, d), or None where the twin does not follow
        its light (`inside_stretch`)."""
        if not np.isfinite(self.first(o, d)[0]):
            return np.zeros(3), []
        stretch = self.inside_stretch(o, d)
        if stretch is None:
            return None
        t0, cos_i, P, w, ell = stretch
        kt = self.ka + self.ks

        def value(x):
            paths = self.paths_of(P + x * w)
            return sum((self.ks * oracle.phase("hg", self.g, float(-t @ w)) * v for _, t, v in paths), np.zeros(3)) \
                * np.exp(-kt * x)

        cuts = changes(lambda x: frozenset(f for f, _, _ in self.paths_of(P + x * w)), ell)
        total = sum(integrate.quad_vec(value, a, b, epsabs=0.0, epsrel=epsrel, norm="max", limit=400)[0]
                    for a, b in zip(cuts, cuts[1:]))
        return math.exp(-self.kt_out * t0) * transmittance(cos_i, self.eta) / self.eta ** 2 * total, cuts
