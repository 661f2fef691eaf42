"""Seed 002's mathematics (raytrace/media/slab.py) against independent twins written from the paper.

* eq. 5 (distant light through a refractive plane): the twin refracts with Snell's law in angles,
  takes the Fresnel reflectance in its angle form, finds k(x) by intersecting the refracted light
  ray with the plane and integrates eq. 3 with scipy `quad`: agreement to 1e-10.
* eq. 7 (point light, index-matched plane): scipy `quad` of the integrand in the depth x, k(x) from
  the segment-plane intersection: agreement to 1e-9.
* eq. 8: a light in the boundary plane gives the project's exact air-light (quadrature's kernel
  and the analytic method's closed form).
* the separable approximation against the seed's own arctan formula in (l, g).
"""
import math

import numpy as np
import pytest
from scipy import integrate

from raytrace.lights import Light, Lights
from raytrace.media import slab
from raytrace.media import Homogeneous as Medium
from raytrace.media.phase import HG, ISOTROPIC, RAYLEIGH
from raytrace.methods import Segments, registry, resolve_params
from raytrace.methods import quadrature as q
from raytrace.methods.geometry import POINT_ROW

from . import oracle

N = np.array([0.0, 0.0, 1.0])  # the boundary plane z = 0, medium below, outward normal +z


def unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def twin_refract(d, eta):
    """d (travelling down, d_z < 0) refracted into z < 0 by Snell's law in angles: (t, theta_i, theta_t)."""
    ti = math.acos(-d[2])
    tt = math.asin(math.sin(ti) / eta)
    horiz = np.array([d[0], d[1], 0.0])
    hn = np.linalg.norm(horiz)
    horiz = horiz / hn if hn > 0 else np.zeros(3)
    return np.array([*(math.sin(tt) * horiz[:2]), -math.cos(tt)]), ti, tt


def twin_fresnel(ti, tt):
    """Unpolarised Fresnel reflectance in the angle form (Born & Wolf)."""
    if ti == 0.0:
        return None
    rs = math.sin(ti - tt) / math.sin(ti + tt)
    rp = math.tan(ti - tt) / math.tan(ti + tt)
    return 0.5 * (rs * rs + rp * rp)


DISTANT = [  # (camera ray, sun direction of travel, eta, kt, ks, phase, g, ell)
    ([0.3, 0.1, -1.0], [0.5, -0.2, -1.0], 1.0, 0.7, 0.3, "isotropic", 0.0, 3.0),
    ([0.3, 0.1, -1.0], [0.5, -0.2, -1.0], 1.33, 0.7, 0.3, "isotropic", 0.0, 3.0),
    ([-0.8, 0.0, -0.4], [0.9, 0.3, -0.2], 1.5, 2.0, 1.1, "hg", 0.6, 0.4),
    ([0.1, 0.05, -1.0], [-0.2, 0.1, -1.0], 1.33, 0.05, 0.01, "rayleigh", 0.0, 40.0),
    ([0.6, 0.6, -0.3], [0.2, 0.1, -1.0], 2.4, 10.0, 9.0, "hg", -0.3, 0.05),
]
CODES = {"isotropic": ISOTROPIC, "rayleigh": RAYLEIGH, "hg": HG}


@pytest.mark.parametrize("cam,sun,eta,kt,ks,name,g,ell", DISTANT)
def test_eq5_against_quadrature_of_eq3(cam, sun, eta, kt, ks, name, g, ell):
    d, s = unit(cam), unit(sun)
    # the code's path: refract both, c = a / b, eq. 5 times the refracted beam's irradiance
    wx, wy, wz, a = slab.refract(*d, *N, eta)
    lx, ly, lz, b = slab.refract(*s, *N, eta)
    mu = -(lx * wx + ly * wy + lz * wz)  # cosine between the light's travel and the way back to the eye
    from raytrace.media.phase import phase_value

    got = slab.slab_distant(kt, ks, phase_value(CODES[name], g, mu), a / b, ell) * slab.beam_irradiance(-s[2], eta)
    # the twin: refraction by angles, Fresnel in its angle form, k(x) by intersecting the plane
    w, _, _ = twin_refract(d, eta)
    t_sun, ti, tt = twin_refract(s, eta)
    e_in = 1.0 if eta == 1.0 else (1.0 - twin_fresnel(ti, tt)) * math.cos(ti) / math.cos(tt)
    phase = oracle.phase(name, g, float(-(t_sun @ w)))

    def integrand(x):
        depth = -(x * w)[2]
        k = depth / -t_sun[2]  # back along the light's refracted ray to z = 0
        return ks * phase * e_in * math.exp(-kt * (x + k))

    ref = integrate.quad(integrand, 0.0, ell, epsabs=0.0, epsrel=1e-13)[0]
    assert got == pytest.approx(ref, rel=1e-10, abs=0.0)


def test_fresnel_and_refraction_limits():
    eta = 1.5
    assert slab.fresnel(1.0, eta) == pytest.approx(((eta - 1) / (eta + 1)) ** 2, rel=1e-14)
    assert slab.fresnel(0.3, 1.0) == 0.0 and slab.beam_irradiance(0.3, 1.0) == 1.0
    assert slab.fresnel(0.1, 1.0 / 1.5) == 1.0  # beyond the critical angle from inside
    assert slab.refract(0.9, 0.0, -math.sqrt(1 - 0.81), 0.0, 0.0, 1.0, 1.0 / 1.5)[3] == 0.0
    # eq. 5's limits: s -> 0 gives 0, s -> inf gives Lambda p / (1 + c), kt = 0 gives ks p s
    assert slab.slab_distant(1.0, 0.5, 0.1, 2.0, 0.0) == 0.0
    assert slab.slab_distant(2.0, 0.5, 0.1, 3.0, math.inf) == pytest.approx(0.25 * 0.1 / 4.0, rel=1e-15)
    assert slab.slab_distant(0.0, 0.0, 0.1, 3.0, 7.0) == 0.0
    assert slab.slab_distant(1e-320, 1e-320, 0.1, 3.0, 7.0) == pytest.approx(1e-320 * 0.7, rel=1e-6)


def point_geometry(w, p):
    """(x_h, h, H_L) of the light p for a segment from the origin along w (geometry.py's definitions)."""
    return float(p @ w), float(np.linalg.norm(np.cross(p, w))), float(p[2])


def twin_eq7(w, p, ell, kt, ks, name, g, kt_out):
    """scipy quad of eq. 7 in the depth x: k(x) from the point where the segment to the light meets z = 0."""
    def f(x):
        X = x * w
        d = np.linalg.norm(p - X)
        k = d * (-X[2]) / (p[2] - X[2])  # fraction of the path below z = 0
        mu = float((X - p) @ (-w)) / d  # the light travels along X - p; the eye is back along -w
        return ks * oracle.phase(name, g, mu) * math.exp(-kt * (x + k) - kt_out * (d - k)) / d**2
    xh = float(p @ w)
    pts = [min(max(xh, 0.0), ell)] if math.isfinite(ell) else None
    if math.isfinite(ell):
        return integrate.quad(f, 0.0, ell, points=pts, epsabs=0.0, epsrel=1e-13, limit=400)[0]
    return (integrate.quad(f, 0.0, max(xh, 1.0), epsabs=0.0, epsrel=1e-13, limit=400)[0]
            + integrate.quad(f, max(xh, 1.0), math.inf, epsabs=0.0, epsrel=1e-13, limit=400)[0])


POINTS = [  # (eye ray into the medium, light, ell, kt, ks, phase, g, kt_out)
    ([0.7, 0.0, -0.7], [-2.0, 0.5, 1.0], 3.0, 1.0, 0.5, "isotropic", 0.0, 0.0),
    ([0.2, 0.1, -1.0], [0.1, 0.0, 0.02], 10.0, 1.0, 0.3, "isotropic", 0.0, 0.0),  # light close to the surface
    ([0.9, 0.0, -0.2], [5.0, 1.0, 3.0], 0.5, 10.0, 9.0, "hg", 0.7, 0.0),
    ([0.3, -0.4, -1.0], [-0.4, 2.0, 0.6], math.inf, 0.4, 0.1, "rayleigh", 0.0, 0.0),
    ([0.0, 0.0, -1.0], [0.0, 0.0, 2.0], 5.0, 0.1, 0.1, "hg", -0.4, 0.05),  # light on the ray line, outside
    ([0.5, 0.2, -0.6], [30.0, -10.0, 40.0], 100.0, 0.1, 0.05, "isotropic", 0.0, 0.01),
]


@pytest.mark.parametrize("w,p,ell,kt,ks,name,g,kt_out", POINTS)
def test_eq7_against_scipy(w, p, ell, kt, ks, name, g, kt_out):
    w, p = unit(w), np.asarray(p, float)
    xh, h, hl = point_geometry(w, p)
    stats = np.zeros(3)
    got = slab.point_exact(xh, h, ell, kt, ks, CODES[name], g, 0.0, -w[2], hl, kt_out, 1e-11, stats)
    assert stats[q.CAPPED] == 0
    assert got == pytest.approx(twin_eq7(w, p, ell, kt, ks, name, g, kt_out), rel=1e-9, abs=0.0)


@pytest.mark.parametrize("name,g", [("isotropic", 0.0), ("hg", 0.5), ("rayleigh", 0.0)])
def test_eq8_light_in_the_plane_is_the_air_light(name, g):
    """H_L = 0: eq. 7 is the air-light of eq. 4 (seed eq. 8), which quadrature's kernel and the
    analytic method's closed form evaluate exactly."""
    w, p = unit([0.6, 0.2, -0.7]), np.array([-1.5, 0.7, 0.0])
    xh, h, hl = point_geometry(w, p)
    kt, ks, ell = 0.8, 0.5, 4.0
    got = slab.point_exact(xh, h, ell, kt, ks, CODES[name], g, 0.0, -w[2], hl, 0.0, 1e-12, np.zeros(3))
    exact = q.airlight_one(xh, h, ell, kt, ks, CODES[name], g, POINT_ROW, 1e-12, q.N10, q.W10, q.N20, q.W20,
                           np.zeros(3))
    assert got == pytest.approx(exact, rel=1e-11)
    segs = Segments(np.zeros((1, 3)), w[None, :], np.array([ell]), np.zeros(1, np.int64), np.zeros(1, np.int64),
                    np.zeros(1), np.zeros(1, np.uint64), np.zeros(1, np.int64))
    lights = Lights.of([Light(p, np.ones(3))])
    medium = Medium(np.full(3, kt - ks), np.full(3, ks), CODES[name], g)
    method = registry()["analytic"]
    closed = method.airlight(segs, medium, lights, resolve_params(method, {"precision": 1e-10}, "test"))[0]
    assert closed[0, 0] == pytest.approx(got, rel=1e-8)


def twin_approx(w, p, ell, kt, ks):
    """The seed's sec. 4.2 formula in its own variables: l, g = omega . omega_l (omega = -w)."""
    l = float(np.linalg.norm(p))
    gg = float((-w) @ (p / l))
    c = -w[2] / (p[2] / l)
    avg = ks / (4 * math.pi) / (kt * (1 + c)) * (1 - math.exp(-kt * (1 + c) * ell)) / ell
    if gg == 1.0:
        return avg * ell / (l * (ell + l))
    r = math.sqrt(1 - gg * gg)
    return avg / (l * r) * (math.atan((ell + l * gg) / (l * r)) - math.atan(gg / r))


@pytest.mark.parametrize("w,p", [([0.7, 0.0, -0.7], [0.7, 0.0, 0.7]), ([0.2, 0.3, -0.9], [1.0, 2.0, 0.5]),
                                 ([0.0, 0.0, -1.0], [0.0, 0.0, 3.0])])
def test_separable_approximation_matches_the_seed_formula(w, p):
    w, p = unit(w), np.asarray(p, float)
    xh, h, hl = point_geometry(w, p)
    got = slab.point_approx(xh, h, 0.5, 1.0, 0.6, ISOTROPIC, 0.0, -w[2], hl / np.linalg.norm(p))
    assert got == pytest.approx(twin_approx(w, p, 0.5, 1.0, 0.6), rel=1e-12)


def test_inverse_square_integral_near_the_line():
    """The light on the ray line behind the entry point (the seed's g = 1): s / (l (s + l))."""
    for l, s in [(1.0, 10.0), (1e-3, 0.5), (1e5, 1e-3)]:
        assert slab.inverse_square_integral(-l, 1e-300, s) == pytest.approx(s / (l * (s + l)), rel=1e-14)


def test_exponential_part_coincidence_and_airlight_limit():
    """omega_e.n = omega_pl.n = 1 (light on the normal above the entry point): k(x) = x exactly, so
    the exponential part is eq. 5's limit (1 - e^{-2 kt s}) / (2 kt) for every l (the seed's Fig. 2 remark)."""
    kt, s = 1.0, 10.0
    for l in (0.01, 1.0, 100.0):
        got = slab.exponential_part(-l, 1e-300, s, kt, 0.0, 1.0, l, 1e-12, np.zeros(3))
        assert got == pytest.approx(-math.expm1(-2 * kt * s) / (2 * kt), rel=1e-11)


def test_refracted_point_light_reduces_to_the_straight_path():
    """eta = 1: Fermat's path is the straight line and the ray tube's irradiance is I / d^2, so the
    refracted integrand equals eq. 7's; below the light it is I T / (hl + z / eta)^2 (apparent depth)."""
    w, p = unit([0.5, 0.2, -0.6]), np.array([1.5, -0.4, 0.9])
    a = -w[2]
    xh, h, hl = point_geometry(w, p)
    lh = p - hl * N
    wl, ll = float((w + a * N) @ lh), float(lh @ lh)
    for x in (0.01, 0.7, 3.0):
        straight = slab.inside_integrand(False, x, xh, h, hl, a, 0.0, 0.0, 0.8, 0.3, HG, 0.5, 0.1, wl, ll, 1.0,
                                         slab.NO_SPOT)
        bent = slab.refracted_point(x, wl, ll, a, hl, 1.0, 0.8, 0.3, HG, 0.5, 0.1, *slab.NO_SPOT)
        assert bent == pytest.approx(straight, rel=1e-12)
    eta, z = 1.33, 0.8  # a point straight below the light, seen along the normal
    got = slab.refracted_point(z, 0.0, 0.0, 1.0, 2.0, eta, 0.0, 1.0, ISOTROPIC, 0.0, 0.0, *slab.NO_SPOT)
    t = 1.0 - ((eta - 1) / (eta + 1)) ** 2
    assert got == pytest.approx(t / (4 * math.pi) / (2.0 + z / eta) ** 2, rel=1e-12)
