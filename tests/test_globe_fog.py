"""A point light inside a refractive exact sphere (a lamp in a glass globe) with fog outside: the fog is lit by the
light refracted out of the sphere (interiors/held.py `held_airlight`, media/sphere_refraction.py
`out_of_sphere`: at each point of a camera segment its paths out, `surface_out_of_sphere`'s irradiance, Fresnel's T
and the ray tube, times the phase function and the legs' transmittances). Taken where the light is closer to the
centre than radius / ior: there every point outside has one path out, so the integrand is smooth along a segment.

The twin is tests/test_lamp_in_globe.py's, built from the geometry alone (the paths as stationary points of the
optical path on the great circle, bracketed on a grid and refined in 30 digits; the irradiance by central
differences of the 3-D path map), here integrated along the camera rays' segments in the fog: the number of paths
counted by the twin's own bracketing on 48 samples of each segment, a change bisected to 1e-14 of the segment and
cut there (none in these scenes: the one-path claim is checked on the way), scipy quad_vec integrating the HG
fog's in-scattering sigma_s Phi(toward . d) E exp(-sigma_t t) between the cuts. A pixel adds the air-light of
its camera segment (and for a ray that enters the globe, of its mirrored and its exiting rays, with Fresnel's
weights) to tests/test_lamp_in_globe.py `twin`'s value (the fog's extinction is the twin's outside one)."""
import math

import numpy as np
import pytest
from scipy import integrate

from raytrace.errors import UserError
from raytrace.media.globe_shadows import patches, shadow_pieces
from raytrace.media.inside_rule import QUAD, inside_rule
from raytrace.media.slab import GEO_COLUMNS
from raytrace.media.sphere_refraction import UNBOUNDED, out_of_sphere

from . import oracle
from .test_bounded_media import fresnel_t
from .test_lamp_in_glass import CAMERA, ETA, FLOOR_Y, KA, KA_OUT, KS, LAMP, refract
from .test_lamp_in_globe import CENTRE, GRID, NEAR, RADIUS, SPHERE, circle, paths_out, scene, sphere_hits, twin
from .test_lantern_fog import march_and_sample, quadrature_against
from .test_light_inside import image

KS_OUT, G_OUT = 0.02, 0.4
FOG = {"sigma_a": KA_OUT - KS_OUT, "sigma_s": KS_OUT, "phase": {"type": "hg", "g": G_OUT}}
FAR = 745.0 / KA_OUT  # where the renderer cuts a segment that meets nothing (its transmittance underflows)
PIXELS = [(2, 1), (3, 5), (2, 3), (2, 4), (0, 0)]  # (row, column): the floor beside the globe, through the globe
# (mirrored to the sky, out of its far side to the floor), the sky


def path_count(L, X, eta=ETA):
    """The number of paths from L inside to X outside (relative index eta inside) by the twin's bracketing alone
    (`exit_points`' sign changes of the optical path's derivative on GRID angles, kept where X lies outside the
    tangent plane)."""
    e1, e2 = circle(L, X)
    th = np.linspace(-math.pi, math.pi, GRID + 1)
    P = CENTRE + RADIUS * (np.cos(th)[:, None] * e1 + np.sin(th)[:, None] * e2)
    dP = RADIUS * (-np.sin(th)[:, None] * e1 + np.cos(th)[:, None] * e2)
    u, v = P - L, X - P
    slope = eta * np.einsum("ij,ij->i", u, dP) / np.linalg.norm(u, axis=1) - np.einsum("ij,ij->i", v, dP) / \
        np.linalg.norm(v, axis=1)
    j = np.nonzero(np.sign(slope[:-1]) != np.sign(slope[1:]))[0]
    return int(np.count_nonzero(np.einsum("ij,ij->i", v[j], P[j] - CENTRE) > 0.0))


def switches(light, o, d, t0, t1, samples=48):
    """The t in (t0, t1) where the number of paths to o + t d changes (`path_count` on samples, each change
    bisected to 1e-14 of the segment)."""
    L = np.array(light["position"], float)
    ts = t0 + (t1 - t0) * (np.arange(samples) + 0.5) / samples
    counts = [path_count(L, o + t * d) for t in ts]
    out = []
    for a, b, ca, cb in zip(ts[:-1], ts[1:], counts[:-1], counts[1:]):
        if ca == cb:
            continue
        while b - a > 1e-14 * (t1 - t0):
            mid = 0.5 * (a + b)
            a, b = (mid, b) if path_count(L, o + mid * d) == ca else (a, mid)
        out.append(0.5 * (a + b))
    return out, counts


def airlight(light, o, d, tmax, epsrel, extra=()):
    """The HG fog's single scattering (3,) along o + t d, t in [0, tmax], lit from inside the globe, with the fog's
    transmittance from o, integrated between the cuts `extra` (a spot's band edges); asserts one path at every
    sample (the claim `out_of_sphere` rests on). epsabs 1e-300, not 0: quad_vec accepts where its error is below
    max(epsabs, epsrel |I|), never on a piece the spot does not reach (I = 0: it subdivided to its limit there)."""
    cuts, counts = switches(light, o, d, 0.0, tmax)
    assert not cuts and set(counts) == {1}, (cuts, set(counts))
    cuts = [0.0, *sorted(extra), tmax]

    def f(t):
        return KS_OUT * sum((e * oracle.phase("hg", G_OUT, float(toward @ d)) for e, toward, _ in
                             paths_out(light, o + t * d)), np.zeros(3)) * math.exp(-KA_OUT * t)

    return sum(integrate.quad_vec(f, a, b, epsrel=epsrel, epsabs=1e-300, norm="max", limit=400)[0]
               for a, b in zip(cuts, cuts[1:]) if b > a)


def floor_t(o, d):
    """Where the ray meets the floor (a 10 x 10 quad), or FAR where it misses it."""
    t = (FLOOR_Y - o[1]) / d[1] if d[1] < 0.0 else FAR
    return t if t < FAR and max(abs(o[0] + t * d[0]), abs(o[2] + t * d[2])) <= 5.0 else FAR


def fog_pixel(light, j, i, epsrel, cuts=lambda o, d, t: ()):
    """The twin's air-light (3,) of pixel (j, i): its camera segment, or the one to the globe and then its mirrored
    and exiting rays' segments, with Fresnel's weights (as tests/test_lamp_in_globe.py `twin`); each segment o + t d,
    t in [0, t_max], cut at cuts(o, d, t_max) (a spot's band edges: tests/test_globe_bounds.py `band_cuts`)."""

    def air(o, d, tmax):
        return airlight(light, o, d, tmax, epsrel, cuts(o, d, tmax))

    o, d = oracle.camera_ray(CAMERA, i, j)
    hits = sphere_hits(o, d)
    if hits is None or hits[0] <= 0.0:
        return air(o, d, floor_t(o, d))
    p = o + hits[0] * d
    n_in = (p - CENTRE) / RADIUS
    cos_i = -float(d @ n_in)
    w = refract(d, n_in, ETA)
    t_in = fresnel_t(math.acos(cos_i), math.acos(-float(w @ n_in)), ETA)
    mirrored = d + 2.0 * cos_i * n_in
    total = air(o, d, hits[0]) + math.exp(-KA_OUT * hits[0]) * (1.0 - t_in) * air(p, mirrored, floor_t(p, mirrored))
    ell = sphere_hits(p, w)[1]
    q = p + ell * w
    m = -(q - CENTRE) / RADIUS
    out = refract(w, m, 1.0 / ETA)
    if out is not None:
        t_out = fresnel_t(math.acos(abs(float(w @ m))), math.acos(abs(float(out @ m))), 1.0 / ETA)
        total += math.exp(-KA_OUT * hits[0]) * t_in * t_out * np.exp(-(KS + KA) * ell) * air(q, out, floor_t(q, out))
    return total


@pytest.fixture(scope="module")
def reference():
    """The twin's pixels (quad_vec at epsrel 1e-10) and the quadrature's image (rtol 1e-10)."""
    base = twin(LAMP)
    air = np.array([fog_pixel(LAMP, j, i, 1e-10) for j, i in PIXELS])
    return air + np.array([base[j, i] for j, i in PIXELS]), air, image(scene(LAMP, FOG), "quadrature", {"rtol": 1e-10},
                                                                        shadows=False)


def test_one_path_within_radius_over_ior():
    """The twin's bracketing finds one path to each of 200 random points outside from lights in random directions
    at 0.3, 0.7 and 0.97 of radius / ior from the centre (`out_of_sphere`'s claim), ior 1.33, 1.5 and 2.4, and from
    a light at 0.95 radius (ior 1.5) points with none and with two."""
    rng = np.random.default_rng(5)
    q = rng.normal(size=(200, 3))
    q *= (rng.uniform(RADIUS * 1.001, 4.0, len(q)) / np.linalg.norm(q, axis=1))[:, None]
    for eta in (1.33, ETA, 2.4):
        for f in (0.3, 0.7, 0.97):
            L = rng.normal(size=3)
            L *= f * RADIUS / eta / np.linalg.norm(L)
            assert {path_count(L, X, eta) for X in q} == {1}, (eta, f)
    assert {0, 2} <= {path_count(np.array(NEAR["position"]), X) for X in q}


def segments(light, rows):
    """media/slab.py GEO_COLUMNS rows (o, d, the light; no cone) of the segments `rows` [(o, d)]."""
    geo = np.zeros((len(rows), GEO_COLUMNS))
    for k, (o, d) in enumerate(rows):
        geo[k, :3], geo[k, 3:6], geo[k, 6:9] = o, d / np.linalg.norm(d), light["position"]
    geo[:, 9:12], geo[:, 12:14], geo[:, 17] = [0.0, 0.0, -1.0], [-2.0, -1.5], 1.0
    return geo


def test_the_guard_counts_points_with_other_than_one_path():
    """`out_of_sphere` counts (stats[UNBOUNDED]) the segments where an evaluation found a number of paths other
    than one, their bound inf: none from the lamp within radius / ior (every bound finite), and some of the same
    segments from the light at 0.95 radius (beyond, refused by the renderer)."""
    rng = np.random.default_rng(9)
    rows = []
    while len(rows) < 8:
        o = rng.uniform(-4.0, 4.0, 3)
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        b = float((o - CENTRE) @ d)
        if np.linalg.norm(o - CENTRE) > 1.5 * RADIUS and (b >= 0.0 or np.linalg.norm(o - CENTRE - b * d) > RADIUS):
            rows.append((o, d))  # wholly outside the globe
    counts = []
    for light in (LAMP, NEAR):
        n = len(rows)
        out, var, err, stats = np.zeros((n, 1)), np.zeros((n, 1)), np.zeros((n, 1)), np.zeros(10)
        out_of_sphere(segments(light, rows), SPHERE, np.full(n, 6.0), np.array([KA_OUT]), np.array([KS_OUT]), 2, G_OUT,
                      np.array([KS[0] + KA[0]]), ETA, inside_rule(QUAD, 1e-4), np.zeros(n, np.uint64), np.uint64(0),
                      np.uint64(0), out, var, err, stats,
                      *shadow_pieces(segments(light, rows), SPHERE, np.full(n, 6.0), ETA, *patches(np.zeros((0, 3, 3)), np.zeros(0))))
        assert np.all(out > 0.0) if light is LAMP else np.any(out > 0.0)
        assert np.all(np.isfinite(err)) if light is LAMP else np.any(np.isinf(err))
        counts.append(stats[UNBOUNDED])
    assert counts[0] == 0 and counts[1] > 0, counts


def test_the_pixels_are_lit_through_the_globe(reference):
    """Every chosen pixel's fog is lit (the air-light at least 2 % of the pixel: 3.1 % to all of it), so the
    comparisons below test it."""
    ref, air, _ = reference
    assert np.all(air > 0.02 * ref), air / ref


def test_quadrature_against_the_twin(reference):
    """quadrature at rtol 1e-10 within 1e-9 of the twin on the chosen pixels (rtol 1e-6: within 1e-5; measured
    2.5e-15 and 1.2e-12) and within its bound (finite: tests/test_globe_bounds.py)."""
    quadrature_against(reference, scene(LAMP, FOG), PIXELS)


def test_raymarch_converges_and_montecarlo_is_unbiased(reference):
    """raymarch's midpoints at their order on a smooth integrand (the error falls 64x from 512 to 4096 steps):
    16x closer to the twin at 4096 steps and within 1e-4 (measured 1.7e-3 -> 2.6e-5; the sky pixel's segment runs
    to where the fog's transmittance underflows); Monte Carlo's free-path samples: mean squared z-score about 1
    over four seeds (measured 1.36)."""
    march_and_sample(scene(LAMP, FOG), PIXELS, reference[0], gain=16.0, within=1e-4)


def test_alone_with_shadows_is_the_same():
    """A globe alone (no floor) with volumetric shadows: nothing else could shadow the light's outside legs, so
    the image equals the unshadowed one bit for bit."""
    sc = scene(LAMP, FOG)
    sc["shape"], sc["camera"] = sc["shape"][:1], dict(CAMERA, width=4, height=3)
    on, off = image(sc, "quadrature", {"rtol": 1e-6}), image(sc, "quadrature", {"rtol": 1e-6}, shadows=False)
    assert np.any(on.image > 0.0)
    assert np.array_equal(on.image, off.image)


def test_what_is_not_implemented_is_refused():
    """A light beyond radius / ior (paths out totally reflected, a caustic outside), volumetric shadows of a shape
    reaching into the globe (those of shapes outside it are taken: tests/test_globe_shadow.py), and the methods
    without exact paths: refused in one line, naming what to change (a spot light is taken:
    tests/test_globe_bounds.py)."""
    into = scene(LAMP, FOG)
    into["shape"] = into["shape"] + [{"primitive": "quad", "corners": [[-0.5, 1.0, 0.5], [0.5, 1.0, 0.5],
                                                                       [0.5, 1.0, -0.5], [-0.5, 1.0, -0.5]]}]
    for sc, method, shadows, words in ((scene(NEAR, FOG), "quadrature", False, r"within radius / ior \(0\.8\)"),
                                       (into, "quadrature", True, r"shape\[2\] reaches into it"),
                                       (scene(LAMP, FOG), "analytic", False, "no closed form"),
                                       (scene(LAMP, FOG), "slab_approx", False, "--method quadrature")):
        with pytest.raises(UserError, match=words) as err:
            image(sc, method, {}, shadows=shadows)
        assert "\n" not in str(err.value)
