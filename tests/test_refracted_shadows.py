"""Volumetric shadows of point and spot light refracted into a convex shape (shadows/fermat_legs.py):
a water box (ior 1.33) under a lamp above its top and beyond one side, and a glass block (ior 1.5)
under a spot from the side, each with a black plate outside between the light and part of a face
the light enters by (shadowing the outside leg of the light's path) and a small black plate inside
(shadowing its inside leg), seen through a face the light is behind.

The twin uses the geometry alone: for each face whose plane the light is outside of, Fermat's path
to an inside point by its own 1-D minimisation of the optical length |L - R| + eta |R - X| over R on
the segment between the feet of the light and the point in the face's plane (scipy
`minimize_scalar`, polished by Newton's method on the derivative), the refraction point tested on
the face by the box's coordinates, both legs tested against the plates by ray-plane tests, the
points where the lit indicator or the spot's cone changes found by bisection on the indicator, and
scipy `quad_vec` between them; the ray tube's irradiance is test_refracted_point_light.py's (checked
there against finite differences). Unshadowed (as every method rendered these shapes' insides
before) the pixels are far off, so the test fails without the shadows.
"""
import math

import numpy as np
import pytest
from scipy import integrate, optimize

from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text

from . import oracle
from .conftest import to_toml
from .test_bounded_media import fresnel_t
from .test_refracted_beams import plate_hit, plate_shape
from .test_refracted_point_light import CAMERA, FACES, GLASS, WATER, camera_entry, smoothstep, spot_terms, switches, tube

BOX = 1.0  # the box is [-1, 1]^3
# (axis, value, (lo, hi) of the other two axes in order): the lamp is at (1.5, 2.2, 0.3), the spot at
# (-2.6, 1.3, 0.1)
PLATES = {"water_box": ((1, 1.5, (-0.2, -1.3), (0.9, 0.1)), (1, 0.45, (-0.3, -0.6), (0.6, 0.2))),
          "glass_block": ((0, -1.8, (0.2, -1.2), (1.6, 0.25)), (1, 0.35, (-0.7, -0.4), (0.1, 0.6)))}
CAM = {**CAMERA, "width": 7, "height": 6}


def shadowed_scene(scene):
    outer, inner = PLATES[scene["name"]]
    return {**scene, "camera": CAM,
            "shape": scene["shape"] + [plate_shape(outer), plate_shape(inner)]}


def fermat(X, L, n, c, eta):
    """(R, o, k, cos1, cos2, rho, z): Fermat's path from L (outside the plane n.q = c) to X (inside)
    by minimising the optical length over the refraction point's distance r from X's foot toward
    L's foot (scipy minimize_scalar), polished by Newton's method on its derivative."""
    z, hl = c - n @ X, n @ L - c
    Xf, Lf = X + z * n, L - hl * n
    rho = float(np.linalg.norm(Lf - Xf))
    if rho < 1e-13:
        return Xf, hl, z, 1.0, 1.0, 0.0, z

    def length(r):
        return math.hypot(rho - r, hl) + eta * math.hypot(r, z)

    r = optimize.minimize_scalar(length, bounds=(0.0, rho), method="bounded", options={"xatol": 1e-10 * rho}).x
    for _ in range(8):
        o, k = math.hypot(rho - r, hl), math.hypot(r, z)
        step = (-(rho - r) / o + eta * r / k) / (hl * hl / o**3 + eta * z * z / k**3)
        r = min(max(r - step, 0.0), rho)
        if abs(step) <= 1e-16 * rho:
            break
    o, k = math.hypot(rho - r, hl), math.hypot(r, z)
    return Xf + r * (Lf - Xf) / rho, o, k, hl / o, z / k, rho, z


def on_face(R, n):
    return all(-BOX - 1e-12 <= R[a] <= BOX + 1e-12 for a in range(3) if n[a] == 0.0)


def clear(a, b, plates):
    """Whether the segment from a to b crosses none of the plates."""
    d = b - a
    length = float(np.linalg.norm(d))
    return all(plate_hit(a, d / length, q) >= length * (1.0 - 1e-12) for q in plates)


def twin_pixel(scene, i, j):
    """The pixel's inside single scattering (3,), shadowed by the plates."""
    outer, inner_plate = PLATES[scene["name"]]
    inner, light = scene["shape"][0]["interior"], scene["light"][0]
    eta, g = inner["ior"], inner["phase"]["g"]
    ks = np.array(inner["sigma_s"], float)
    kt = np.array(inner["sigma_a"], float) + ks
    kt_out = scene["medium"]["sigma_a"] + scene["medium"]["sigma_s"]
    L = np.array(light["position"], float)
    inten = np.broadcast_to(np.array(light["intensity"], float), (3,))
    spot = spot_terms(light)
    entry = camera_entry({**scene, "camera": CAM}, i, j, eta)
    if entry is None:
        return np.zeros(3)
    t0, p, w, ti, tt = entry
    ell = min(oracle.box_exit(p, w, -BOX * np.ones(3), BOX * np.ones(3))[0], plate_hit(p, w, inner_plate))
    out = np.zeros(3)
    for n in FACES:
        if n @ L <= BOX:
            continue

        def lit(x):
            X = p + x * w
            R = fermat(X, L, n, BOX, eta)[0]
            return on_face(R, n) and clear(L, R, (outer,)) and clear(R, X, (inner_plate,))

        def cone(x):
            R = fermat(p + x * w, L, n, BOX, eta)[0]
            u = (R - L) / np.linalg.norm(R - L)
            return (u @ spot[0] > spot[1], u @ spot[0] > spot[2])

        def f(x):
            X = p + x * w
            R, o, k, cos1, cos2, rho, z = fermat(X, L, n, BOX, eta)
            hl = n @ L - BOX
            e = fresnel_t(math.acos(cos1), math.asin(math.sqrt(1 - cos1**2) / eta), eta) * tube(hl, z, cos1, cos2,
                                                                                                 rho, eta)
            mu = float((X - R) / k @ -w)
            fall = smoothstep(float((R - L) @ spot[0]) / o, spot[1], spot[2]) if spot else 1.0
            return inten * ks * oracle.phase("hg", g, mu) * fall * e * np.exp(-kt * (x + k) - kt_out * o)

        cuts = switches(p, w, ell, lit, samples=300) + (switches(p, w, ell, cone, samples=300) if spot else [])
        edges = [0.0, *sorted(cuts), ell]
        def dark(x):  # outside the spot's cone (its falloff 0 on the whole piece)
            return bool(spot) and not cone(x)[0]

        for a, b in zip(edges, edges[1:]):
            if b > a and lit(0.5 * (a + b)) and not dark(0.5 * (a + b)):  # lit on the whole piece
                out += integrate.quad_vec(f, a, b, epsabs=0.0, epsrel=1e-12, norm="max", limit=400)[0]
    return math.exp(-kt_out * t0) * fresnel_t(ti, tt, eta) / eta**2 * out


@pytest.fixture(scope="module", params=[WATER, GLASS], ids=["water_lamp_above", "glass_spot_beside"])
def case(request):
    scene = shadowed_scene(request.param)
    twin = np.array([[twin_pixel(scene, i, j) for i in range(CAM["width"])] for j in range(CAM["height"])])
    return scene, twin


def image(scene, method, params=None, seed=0, shadows=True):
    prep = prepare(scene_from_text(to_toml(scene), scene["name"]))
    return render(prep, method, params or {}, RenderOptions(threads=1, seed=seed, volumetric_shadows=shadows))


def test_the_plates_shadow_both_legs(case):
    """Not vacuous: each plate shadows some camera segments' light (the outer one the outside leg,
    the inner one the inside leg), through two faces of the box."""
    scene, _ = case
    outer, inner_plate = PLATES[scene["name"]]
    light, eta = scene["light"][0], scene["shape"][0]["interior"]["ior"]
    L = np.array(light["position"], float)
    faces = [n for n in FACES if n @ L > BOX]
    assert len(faces) == 2
    legs = {"outside": 0, "inside": 0}
    for j in range(CAM["height"]):
        for i in range(CAM["width"]):
            t0, p, w, _, _ = camera_entry({**scene, "camera": CAM}, i, j, eta)
            ell = min(oracle.box_exit(p, w, -np.ones(3), np.ones(3))[0], plate_hit(p, w, inner_plate))
            for x in np.linspace(0.0, ell, 9)[1:-1]:
                X = p + x * w
                for n in faces:
                    R = fermat(X, L, n, BOX, eta)[0]
                    if on_face(R, n):
                        legs["outside"] += not clear(L, R, (outer,))
                        legs["inside"] += not clear(R, X, (inner_plate,))
    assert legs["outside"] >= 10 and legs["inside"] >= 10, legs


def test_quadrature_matches_the_twin(case):
    scene, twin = case
    res = image(scene, "quadrature", {"rtol": 1e-10})
    lit = twin[..., 1] > 0
    assert np.count_nonzero(lit) >= 30
    rel = np.abs(res.image[lit] - twin[lit]) / twin[lit]
    assert np.max(rel) < 1e-8, np.max(rel)
    assert np.all(res.image[~lit] == 0.0)
    assert res.stats["inside: integrals not converged"] == 0
    assert res.stats["inside: segments unshadowed (refractive or planar model)"] == 0
    assert res.stats["inside: lit pieces"] > 0


def test_unshadowed_is_far_off(case):
    """As before the shadows (the inside air-light of point and spot lights was left unshadowed):
    pixels off by more than 10 %."""
    scene, twin = case
    lit = twin[..., 1] > 0
    bare = image(scene, "quadrature", {"rtol": 1e-10}, shadows=False).image
    off = np.abs(bare[lit] - twin[lit]) / twin[lit]
    assert np.count_nonzero(off > 0.1) >= 5, np.sort(off)[-5:]


def test_raymarch_and_montecarlo_take_the_shadows(case):
    """The midpoint rule converges to the twin (first order at the pieces' ends); free-path samples
    are unbiased with their own variance (mean squared z-score about 1)."""
    scene, twin = case
    lit = twin[..., 1] > 0
    errs = [np.max(np.abs(image(scene, "raymarch", {"steps": n}).image[lit] - twin[lit]) / twin[lit])
            for n in (128, 512)]
    assert errs[1] < 5e-3 and errs[1] < errs[0] / 2.5, errs
    res = image(scene, "montecarlo", {"samples": 64}, seed=5)
    assert res.stats["inside: segments unshadowed (refractive or planar model)"] == 0
    z2 = np.mean((res.image[lit] - twin[lit]) ** 2 / res.variance[lit])
    assert 0.3 < z2 < 3.5, z2


@pytest.mark.parametrize("eta", [1.33, 1.5, 0.75])
def test_the_refraction_points_speed_bound(eta):
    """The Lipschitz bound that lets the break search exclude intervals (fermat_legs `_speed`, derived
    in its docstring) holds: on random faces, lights and segments below the face, the refraction
    point (the twin's own minimisation) moves by at most K_R times the step over sub-intervals, and
    the bound is not loose (somewhere over half of it is reached)."""
    from raytrace.shadows import fermat_legs as fl
    rng = np.random.default_rng(7)
    ratios = []
    for _ in range(30):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        c = rng.uniform(-1.0, 1.0)
        L = rng.normal(size=3)
        L = L + (c + rng.uniform(0.2, 3.0) - n @ L) * n  # above the plane
        p = rng.normal(size=3)
        p = p + (c - rng.uniform(0.05, 2.0) - n @ p) * n  # below it
        w = rng.normal(size=3)
        w /= np.linalg.norm(w)
        a, z0, hl = -(n @ w), c - n @ p, n @ L - c
        end = 3.0 if a >= 0.0 else min(3.0, 0.999 * z0 / -a)
        pf, wh, lf = p + z0 * n, w + a * n, L - hl * n
        xs = np.linspace(0.0, end, 41)
        R = np.array([fermat(p + x * w, L, n, c, eta)[0] for x in xs])
        for i in range(0, 40, 4):
            k = fl._speed(xs[i], xs[i + 4], a, lf, pf, wh, z0, eta)
            for j in range(i, i + 4):
                ratios.append(np.linalg.norm(R[j + 1] - R[j]) / (k * (xs[j + 1] - xs[j])))
    assert max(ratios) <= 1.0 + 1e-9 and max(ratios) > 0.5, max(ratios)
