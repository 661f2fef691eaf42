"""A point light inside a refractive convex mesh (a lamp in a glass lantern) with fog outside: the fog is lit by
the light refracted out through every face (interiors/held.py `held_airlight`, media/slab.py `out_of_faces`:
Fermat's path with relative index 1 / eta, Fresnel's T, the ray tube's irradiance, each face over the part of
the segment beyond its plane, its breaks where the refraction point crosses the face's edges isolated with
media/fermat_rounding.py `fermat_pace`, the eta < 1 speed bound).

The twin is tests/test_lamp_in_glass.py's, built from the geometry alone (refraction points where the optical
path is stationary, by Newton's method in 30 digits, checked here against its direct minimisation; the
irradiance by central differences of the path map), here integrated along the camera rays' segments in the fog:
each face's term switches on and off where its refraction point crosses the face's edges (and a spot's falloff
kinks or jumps where the direction the light leaves in crosses its cone's levels), found on 48 samples of the
segment and bisected (the twin's own refraction points), and starts where the segment crosses the face's plane;
scipy quad_vec integrates the
isotropic fog's in-scattering sigma_s / (4 pi) E exp(-sigma_t t) between those breaks. A pixel adds the
air-light of its camera segment (and for a ray that enters the lantern, of its mirrored and its exiting rays,
with Fresnel's weights) to tests/test_lamp_in_glass.py `twin`'s value (the fog's extinction is the twin's
outside one). The air-light of the chosen pixels is stored (tests/make_lantern_fog_twins.py), one recomputed live."""
import json
import math
import pathlib
import types

import mpmath as mp
import numpy as np
import pytest
from scipy import integrate, optimize

from raytrace.errors import UserError
from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text

from . import oracle
from .conftest import to_toml
from .test_bounded_media import box_entry, fresnel_t
from .test_lamp_in_glass import (CAMERA, ETA, FACES, HI, KA, KA_OUT, KS, LAMP, LO, SPOT, dot, exit_point, irradiance,
                                 on_face, refract, scene, twin, unit)
from .test_light_inside import image
from .test_refracted_point_light import spot_terms

KS_OUT = 0.02
FOG = {"sigma_a": KA_OUT - KS_OUT, "sigma_s": KS_OUT}  # extinction KA_OUT, the twin's outside legs'
FLOOR_Y = -1.6
PIXELS = [(2, 1), (3, 5), (3, 2), (2, 3)]  # (row, column): the floor beside the lantern; (2, 3) the lantern's +z face
TWINS = pathlib.Path(__file__).with_name("data") / "lantern_fog_twins.json"  # tests/make_lantern_fog_twins.py writes it


def minimised_exit_point(L, X, n):
    """`exit_point` by direct minimisation, as the twin found it first: the optical path minimised over the plane's
    coordinates (scipy BFGS), then its in-plane gradient's root (mpmath findroot, 30 digits)."""
    a, b = [e for e in np.eye(3) if e @ n == 0.0]
    base = n * max(n @ LO, n @ HI)

    def length(s):
        R = base + s[0] * a + s[1] * b
        return ETA * np.linalg.norm(R - L) + np.linalg.norm(X - R)

    s0 = optimize.minimize(length, np.array([(L + X) @ a, (L + X) @ b]) / 2.0, method="BFGS", options={"gtol": 1e-12}).x
    with mp.workdps(30):
        Lm, Xm = [mp.mpf(float(v)) for v in L], [mp.mpf(float(v)) for v in X]

        def point(s, t):
            return [mp.mpf(float(base[k])) + s * float(a[k]) + t * float(b[k]) for k in range(3)]

        def grad(s, t):
            R = point(s, t)
            to_light, to_x = unit([r - l for r, l in zip(R, Lm)]), unit([r - x for r, x in zip(R, Xm)])
            v = [ETA * p_ + q_ for p_, q_ in zip(to_light, to_x)]
            return [dot(v, [float(c) for c in a]), dot(v, [float(c) for c in b])]

        s = mp.findroot(grad, (mp.mpf(s0[0]), mp.mpf(s0[1])), tol=mp.mpf(10) ** -50)
        return point(s[0], s[1])


def test_the_twins_refraction_point():
    """The twin's `exit_point` (Newton's method) is the direct minimisation's point to 1e-25 (measured 4e-31 on 162
    paths) on every face whose plane points about the lantern lie beyond, some within 1e-9 of the plane (the light
    leaving near the critical angle)."""
    rng = np.random.default_rng(1)
    points = rng.uniform(-3.0, 3.0, (12, 3))
    near = [[0.5, 0.3, 1.0 + 1e-9], [2.9, -2.0, 1.0 + 1e-6]]
    points = np.vstack([points[np.max(np.abs(points), axis=1) > 1.02], near])
    count = 0
    for X in points:
        for light in (LAMP, SPOT):
            L = np.array(light["position"], float)
            for n in FACES:
                if n @ X > 1.0:
                    with mp.workdps(30):
                        assert max(abs(p - q) for p, q in zip(exit_point(L, X, n), minimised_exit_point(L, X, n))) \
                            <= mp.mpf(10) ** -25
                    count += 1
    assert count >= 20, count


def switches(light, o, d, t0, t1, n, samples=48):
    """The t in (t0, t1) where face n's refraction point (the twin's `exit_point`) of the light's path crosses
    the face's edges, and for a spot where the direction the light leaves in crosses its cone's levels (the
    falloff's kinks): their indicators on samples, each change bisected to 1e-14 of the segment."""
    L = np.array(light["position"], float)
    spot = spot_terms(light)

    def on(t):
        R = np.array([float(v) for v in exit_point(L, o + t * d, n)])
        if spot is None:
            return on_face(R, n)
        c = float((R - L) @ spot[0]) / np.linalg.norm(R - L)
        return on_face(R, n), c > spot[1], c > spot[2]

    ts = t0 + (t1 - t0) * (np.arange(samples) + 0.5) / samples
    states = [on(t) for t in ts]
    out = []
    for a, b, sa, sb in zip(ts[:-1], ts[1:], states[:-1], states[1:]):
        if sa == sb:
            continue
        while b - a > 1e-14 * (t1 - t0):
            mid = 0.5 * (a + b)
            a, b = (mid, b) if on(mid) == sa else (a, mid)
        out.append(0.5 * (a + b))
    return out


def airlight(light, o, d, tmax, epsrel):
    """The isotropic fog's single scattering (3,) along o + t d, t in [0, tmax], lit from inside the box, with the
    fog's transmittance from o: scipy quad_vec between the faces' planes and their `switches` (epsabs 1e-300:
    its test of convergence is strict, a piece the spot leaves dark would never end)."""
    cuts = {0.0, tmax}
    for n in FACES:
        rate, depth = float(n @ d), float(n @ o) - 1.0
        lo, hi = 0.0, tmax
        if rate > 0.0:
            lo = max(lo, -depth / rate)
        elif rate < 0.0:
            hi = min(hi, depth / -rate)
        elif depth <= 0.0:
            continue
        if hi > lo:
            cuts |= {lo, hi, *switches(light, o, d, lo, hi, n)}
    cuts = sorted(cuts)

    def f(t):
        return KS_OUT / (4.0 * math.pi) * irradiance(light, o + t * d) * math.exp(-KA_OUT * t)

    return sum(integrate.quad_vec(f, a, b, epsrel=epsrel, epsabs=1e-300, norm="max")[0]
               for a, b in zip(cuts, cuts[1:]) if b > a)


def floor_t(o, d):
    return (FLOOR_Y - o[1]) / d[1]


def fog_pixel(light, j, i, epsrel):
    """The twin's air-light (3,) of pixel (j, i): its camera segment to the floor, or to the box and then its
    mirrored and exiting rays' segments to the floor, with Fresnel's weights (as tests/test_lamp_in_glass.py
    `twin`)."""
    o, d = oracle.camera_ray(CAMERA, i, j)
    t0, n_in = box_entry(o, d, LO, HI)
    if n_in is None:
        return airlight(light, o, d, floor_t(o, d), epsrel)
    p = o + t0 * d
    cos_i = -float(d @ n_in)
    w = refract(d, n_in, ETA)
    t_in = fresnel_t(math.acos(cos_i), math.acos(-float(w @ n_in)), ETA)
    mirrored = d + 2.0 * cos_i * n_in
    total = airlight(light, o, d, t0, epsrel) + math.exp(-KA_OUT * t0) * (1.0 - t_in) * airlight(
        light, p, mirrored, floor_t(p, mirrored), epsrel)
    ell, m = oracle.box_exit(p, w, LO, HI)
    out = refract(w, np.array(m, float), 1.0 / ETA)
    if out is not None:
        t_out = fresnel_t(math.acos(abs(float(w @ m))), math.acos(abs(float(out @ m))), 1.0 / ETA)
        q = p + ell * w
        total += math.exp(-KA_OUT * t0) * t_in * t_out * np.exp(-(KS + KA) * ell) * airlight(
            light, q, out, floor_t(q, out), epsrel)
    return total


def stored_air(name, pixels):
    """The twin's air-light (n, 3) of `pixels` under the light `name` (quad_vec at epsrel 1e-10), as
    tests/make_lantern_fog_twins.py stored it (tests/data/lantern_fog_twins.json)."""
    twins = json.loads(TWINS.read_text())[name]
    assert [tuple(p) for p in twins["pixels"]] == list(pixels), "run python -m tests.make_lantern_fog_twins"
    return np.array(twins["air"])


def test_the_stored_twin_is_the_twin():
    """The stored twin's air-light of the lamp's first pixel (the floor beside the lantern) recomputed live: the same
    to 1e-12 (quad_vec's result, the same on every run)."""
    j, i = PIXELS[0]
    assert np.allclose(fog_pixel(LAMP, j, i, 1e-10), stored_air("lamp", PIXELS)[0], rtol=1e-12, atol=0.0)


def block(sc, method, params, pixels, seed=0):
    """tests/test_light_inside.py `image` without volumetric shadows, rendered on the block of pixels holding
    `pixels` alone (RenderOptions.crop: the same samples and random numbers as in the whole image): its image,
    variance and error bound placed in the whole image's frame (NaN elsewhere)."""
    rows, cols = zip(*pixels)
    box = (min(cols), min(rows), max(cols) + 1, max(rows) + 1)
    res = render(prepare(scene_from_text(to_toml(sc), sc["name"])), method, params,
                 RenderOptions(threads=1, volumetric_shadows=False, seed=seed, crop=box))

    def placed(layer):
        whole = np.full((sc["camera"]["height"], sc["camera"]["width"], 3), np.nan)
        whole[box[1]:box[3], box[0]:box[2]] = layer
        return whole

    return types.SimpleNamespace(image=placed(res.image), error_bound=placed(res.error_bound),
                                 variance=None if res.variance is None else placed(res.variance))


@pytest.fixture(scope="module")
def reference():
    """The twin's pixels (quad_vec at epsrel 1e-10, stored: `stored_air`) and the quadrature's image (rtol 1e-10) of
    their `block`."""
    base = twin(LAMP)
    air = stored_air("lamp", PIXELS)
    return air + np.array([base[j, i] for j, i in PIXELS]), air, block(scene(LAMP, FOG), "quadrature", {"rtol": 1e-10},
                                                                        PIXELS)


def test_the_pixels_are_lit_through_the_faces(reference):
    """Every chosen pixel's fog is lit (the air-light at least 2 % of the pixel: 2.1 % to 39 %), so the comparisons
    below test it."""
    ref, air, _ = reference
    assert np.all(air > 0.02 * ref), air / ref


def test_quadrature_against_the_twin(reference):
    """quadrature at rtol 1e-10 within 1e-9 of the twin on the chosen pixels (rtol 1e-6: within 1e-5; measured
    1.8e-13 and 3.3e-13, the twin's own accuracy); its bound holding (finite for light leaving the faces:
    tests/test_leaving_bounds.py)."""
    quadrature_against(reference, scene(LAMP, FOG), PIXELS)


def quadrature_against(reference, sc, pixels):
    """The fixture's quadrature render (rtol 1e-10) within 1e-9 of its twin `ref` on `pixels`, its bound holding;
    the scene `sc` at rtol 1e-6 (no volumetric shadows; the pixels' `block`) within 1e-5."""
    ref, _, res = reference
    got = np.array([res.image[j, i] for j, i in pixels])
    err = np.abs(got - ref) / ref
    assert np.all(err <= 1e-9), err.max()
    bounds = np.array([res.error_bound[j, i] for j, i in pixels])
    assert np.all(bounds >= np.abs(got - ref))
    coarse = block(sc, "quadrature", {"rtol": 1e-6}, pixels)
    got = np.array([coarse.image[j, i] for j, i in pixels])
    assert np.all(np.abs(got - ref) <= 1e-5 * ref), (np.abs(got - ref) / ref).max()


def test_raymarch_converges_and_montecarlo_is_unbiased(reference):
    """raymarch's midpoints (each face's term jumps at its edges: first order at least) 4x closer to the twin at
    4096 steps than at 512 and within 1e-5 (measured 3.7e-5 -> 2.4e-7); Monte Carlo's free-path samples: mean
    squared z-score about 1 over four seeds (measured 1.07)."""
    march_and_sample(scene(LAMP, FOG), PIXELS, reference[0])


def march_and_sample(sc, pixels, ref, gain=4.0, within=1e-5):
    """The scene `sc` without volumetric shadows (the pixels' `block`): raymarch `gain` times closer to ref (the
    pixels' values) at 4096 steps than at 512 and within `within`; Monte Carlo with 256 samples: mean squared z-score
    over the pixels' channels and seeds 3 to 6 in (0.3, 3)."""
    errs = []
    for steps in (512, 4096):
        res = block(sc, "raymarch", {"steps": steps}, pixels)
        errs.append(max(np.max(np.abs(res.image[j, i] - r) / r) for (j, i), r in zip(pixels, ref)))
    assert errs[1] < errs[0] / gain and errs[1] < within, errs
    z2 = []
    for seed in (3, 4, 5, 6):
        mc = block(sc, "montecarlo", {"samples": 256}, pixels, seed=seed)
        for (j, i), r in zip(pixels, ref):
            z2 += ((mc.image[j, i] - r) ** 2 / mc.variance[j, i]).tolist()
    assert 0.3 < np.mean(z2) < 3.0, np.mean(z2)


def test_alone_with_shadows_is_the_same():
    """A lantern alone (no floor) with volumetric shadows: nothing else could shadow the light's outside legs, so
    the image equals the unshadowed one bit for bit."""
    sc = scene(LAMP, FOG)
    sc["shape"], sc["camera"] = sc["shape"][:1], dict(CAMERA, width=4, height=3)
    on, off = image(sc, "quadrature", {"rtol": 1e-6}), image(sc, "quadrature", {"rtol": 1e-6}, shadows=False)
    assert np.any(on.image > 0.0)
    assert np.array_equal(on.image, off.image)


def test_what_is_not_implemented_is_refused():
    """The methods without exact paths: refused in one line, naming what to change (a spot light:
    tests/test_lantern_fog_spot.py; volumetric shadows of another shape are rendered:
    tests/test_lamp_in_glass_shadows.py)."""
    for sc, method, shadows, words in ((scene(LAMP, FOG), "analytic", False, "no closed form"),
                                       (scene(LAMP, FOG), "slab_approx", False, "--method quadrature")):
        with pytest.raises(UserError, match=words) as err:
            image(sc, method, {}, shadows=shadows)
        assert "\n" not in str(err.value)
