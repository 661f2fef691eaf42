"""A camera inside a convex refractive shape (an underwater camera; crossing.start_inside): the
camera rays' inside rows take the light's refracted paths through every face (as rows entering from
outside do), and the rays leave through the boundary refracted (Snell, Fresnel's T, radiance x eta^2;
total internal reflection ends them). A water box (ior 1.33, HG medium) with the camera inside,
looking down through its bottom at a floor, a lamp above; the twin from the geometry alone
(tests/test_refracted_point_light.py's Fermat paths and ray tube for the inside, Snell and Fresnel
by angles for the exit, the lamp's shadow ray on the floor by the slab test).
"""
import math

import numpy as np
import pytest
from scipy import integrate

from raytrace.errors import UserError
from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import load_scene

from . import oracle
from .conftest import to_toml
from .test_bounded_media import fresnel_t, slab, snell
from .test_refracted_point_light import HI, LO, _from_light, image, switches

FLOOR_Y, FLOOR_HALF, RHO = -1.6, 4.0, 0.6
LAMP = {"position": [1.5, 2.2, 0.3], "intensity": [5.0, 4.0, 3.0]}
SUN = {"type": "directional", "direction": [0.4, -1.0, -0.3], "irradiance": 2.0}
INSIDE = {"sigma_a": [0.3, 0.1, 0.05], "sigma_s": [0.4, 0.5, 0.7], "phase": {"type": "hg", "g": 0.4}, "ior": 1.33}
SCENE = {"name": "underwater", "camera": {"position": [0.3, -0.2, 0.4], "look_at": [-0.2, -1.5, -0.5], "fov": 70.0,
                                          "width": 8, "height": 6, "spp": 1},
         "shape": [{"primitive": "box", "min": LO.tolist(), "max": HI.tolist(), "interior": INSIDE},
                   {"primitive": "quad", "corners": [[-FLOOR_HALF, FLOOR_Y, FLOOR_HALF], [FLOOR_HALF, FLOOR_Y, FLOOR_HALF],
                                                     [FLOOR_HALF, FLOOR_Y, -FLOOR_HALF], [-FLOOR_HALF, FLOOR_Y, -FLOOR_HALF]], "reflectance": RHO}],
         "light": [LAMP], "medium": {"sigma_a": 0.0, "sigma_s": 0.0}}


def floor_seen(E, d, m, eta, light=LAMP):
    """(radiance (3,), how) of what the ray leaving the box at E along d (outward face normal m) sees:
    refracted out by angles (eta = n_inside), T eta^2 times the floor's radiance lit by `light`, whose
    path must not cross the box (a refracted shadow path is a caustic)."""
    ti = math.acos(float(d @ m))
    if math.sin(ti) * eta >= 1.0:
        return np.zeros(3), "total reflection"
    out, _, tt = snell(d, -m, 1.0 / eta)
    if out[1] >= 0.0:
        return np.zeros(3), "misses the floor"
    F = E + (FLOOR_Y - E[1]) / out[1] * out
    if max(abs(F[0]), abs(F[2])) > FLOOR_HALF:
        return np.zeros(3), "misses the floor"
    if light.get("type") == "directional":
        u, dist = -np.array(light["direction"], float) / np.linalg.norm(light["direction"]), math.inf
        e = np.full(3, light["irradiance"]) * u[1]
    else:
        L = np.array(light["position"])
        u, dist = (L - F) / np.linalg.norm(L - F), np.linalg.norm(L - F)
        e = np.array(light["intensity"]) * u[1] / dist**2
    hit = slab(F, u, LO, HI)
    if hit is not None and hit[1] > 0.0 and hit[0] < dist:
        return np.zeros(3), "floor in the box's shadow"
    return fresnel_t(ti, tt, 1.0 / eta) * eta**2 * RHO / math.pi * e, "floor"


def sun_inside(p, d, ell, sun, eta, g, ks, kt):
    """The inside single scattering (3,) over [0, ell] of the ray p + x d from the sun refracted through
    every face it meets: face f's beam (Snell, Fresnel by angles, E T cos_i / cos_t) where the path
    back along it leaves through f (switches bisected), scipy quad between them."""
    s_dir = np.array(sun["direction"], float) / np.linalg.norm(sun["direction"])
    faces = [np.eye(3)[a] * sign for a in range(3) for sign in (1.0, -1.0)]
    out = np.zeros(3)
    for nf in faces:
        if s_dir @ nf >= 0.0:
            continue
        ts, si, st = snell(s_dir, nf, eta)
        e = sun["irradiance"] * fresnel_t(si, st, eta) * math.cos(si) / math.cos(st)

        def back(x):  # (distance, face index) of the exit along -ts from p + x d
            X = p + x * d
            return min(((1.0 - f @ X) / (f @ -ts), i) for i, f in enumerate(faces) if f @ -ts > 0.0)

        mine = next(i for i, f in enumerate(faces) if f @ nf == 1.0)
        cuts = switches(p, d, ell, lambda x: back(x)[1] == mine)
        for c in range(3):
            def f(x):
                k, leaves = back(x)
                return ks[c] * oracle.phase("hg", g, float(ts @ -d)) * e * math.exp(-kt[c] * (x + k)) \
                    if leaves == mine else 0.0
            out[c] += integrate.quad(f, 0.0, ell, points=cuts or None, epsabs=0.0, epsrel=1e-12, limit=400)[0]
    return out


def twin_image(light):
    """The twin's image (H, W, 3) of SCENE lit by `light` and what each pixel's ray sees beyond the box."""
    cam, eta = SCENE["camera"], INSIDE["ior"]
    ks = np.array(INSIDE["sigma_s"])
    kt = np.array(INSIDE["sigma_a"]) + ks
    img, seen = np.zeros((cam["height"], cam["width"], 3)), []
    for j in range(cam["height"]):
        for i in range(cam["width"]):
            p, d = oracle.camera_ray(cam, i, j)
            ell, _ = oracle.box_exit(p, d, LO, HI)
            if light.get("type") == "directional":
                inside = sun_inside(p, d, ell, light, eta, INSIDE["phase"]["g"], ks, kt)
            else:
                inside = _from_light(np.array(light["position"]), np.array(light["intensity"], float), None, None, p, d,
                                     ell, eta, INSIDE["phase"]["g"], ks, kt, 0.0, None)
            E = p + ell * d
            m = np.where(np.abs(np.abs(E) - 1.0) < 1e-12, np.sign(E), 0.0)
            beyond, how = floor_seen(E, d, m / np.linalg.norm(m), eta, light)
            img[j, i] = inside + np.exp(-kt * ell) * beyond
            seen.append(how)
    return img, seen


@pytest.fixture(scope="module")
def twin():
    return twin_image(LAMP)


def test_an_underwater_camera_sees_the_lit_water_and_the_floor_through_the_bottom(twin):
    """quadrature (rtol 1e-11) within 1e-8 of the twin on every pixel; the image holds rays that see
    the floor lit, the floor in the box's shadow, rays totally reflected at the bottom and rays that
    leave it too flat to meet the floor."""
    ref, seen = twin
    assert {"floor", "floor in the box's shadow", "total reflection", "misses the floor"} <= set(seen), set(seen)
    res = image(SCENE, "quadrature", {"rtol": 1e-11})
    assert np.all(ref[..., 1] > 0.0)
    assert np.max(np.abs(res.image - ref) / ref) < 1e-8
    assert res.stats["inside: integrals not converged"] == 0


def test_raymarch_and_montecarlo_from_inside(twin):
    """The midpoint rule within 5e-3 at 512 steps; free-path samples unbiased (mean squared z-score
    about 1) with the floor's term exact."""
    ref, _ = twin
    rm = image(SCENE, "raymarch", {"steps": 512}).image
    assert np.max(np.abs(rm - ref) / ref) < 5e-3
    mc = image(SCENE, "montecarlo", {"samples": 64}, seed=2)
    z2 = np.mean((mc.image - ref) ** 2 / mc.variance)
    assert 0.3 < z2 < 3.5, z2


def test_an_underwater_camera_under_the_sun():
    """The sun's beams through the top and two sides light the water the camera looks through, and
    the floor beside the box's shadow: quadrature (rtol 1e-11) within 1e-8 of the twin."""
    sc = {**SCENE, "light": [SUN]}
    ref, seen = twin_image(SUN)
    assert "floor" in seen
    res = image(sc, "quadrature", {"rtol": 1e-11})
    assert np.all(ref[..., 1] > 0.0)
    assert np.max(np.abs(res.image - ref) / ref) < 1e-8


@pytest.mark.parametrize("precision", [1e-3, 1e-9])
def test_analytic_from_inside_under_the_sun(precision):
    """`analytic` with the camera in the water: the sun's refracted beams by their closed forms, within
    its precision of the twin on every pixel, and inside its own error bound."""
    sc = {**SCENE, "light": [SUN]}
    ref, _ = twin_image(SUN)
    res = image(sc, "analytic", {"precision": precision})
    err = np.abs(res.image - ref)
    assert np.max(err / ref) < precision
    assert np.all(err <= res.error_bound)
    assert res.stats.get("inside: segments handed to quadrature", 0) == 0


def test_analytic_from_inside_an_index_matched_box():
    """The camera in a box of fog (ior 1) under the sun: `analytic`'s closed form of the straight path
    (media/convex_directional.py) against the twin: the sun's path back to the boundary by the slab
    test, scipy quad along the ray; within 1e-9 and inside its bound; the floor seen unrefracted, lit through
    the fog's chord."""
    fog = {**INSIDE, "ior": 1.0}
    sc = {**SCENE, "light": [SUN], "shape": [{**SCENE["shape"][0], "interior": fog}, SCENE["shape"][1]]}
    cam, g = SCENE["camera"], INSIDE["phase"]["g"]
    ks = np.array(INSIDE["sigma_s"])
    kt = np.array(INSIDE["sigma_a"]) + ks
    u = -np.array(SUN["direction"], float) / np.linalg.norm(SUN["direction"])
    ref = np.zeros((cam["height"], cam["width"], 3))
    for j in range(cam["height"]):
        for i in range(cam["width"]):
            p, d = oracle.camera_ray(cam, i, j)
            ell, _ = oracle.box_exit(p, d, LO, HI)
            ph = oracle.phase("hg", g, float(u @ d))  # the light travels along -u
            for c in range(3):
                def f(x):
                    return ks[c] * ph * SUN["irradiance"] * math.exp(-kt[c] * (x + oracle.box_exit(p + x * d, u, LO,
                                                                                                     HI)[0]))
                ref[j, i, c] = integrate.quad(f, 0.0, ell, epsabs=0.0, epsrel=1e-12, limit=200)[0]
            E = p + ell * d
            if d[1] < 0.0:  # leaves downward, unrefracted: the floor lit by the sun through the fog's chord
                F = E + (FLOOR_Y - E[1]) / d[1] * d
                hit = slab(F, u, LO, HI)
                chord = 0.0 if hit is None or hit[1] <= 0.0 else hit[1] - max(hit[0], 0.0)
                if max(abs(F[0]), abs(F[2])) <= FLOOR_HALF:
                    ref[j, i] += np.exp(-kt * (ell + chord)) * RHO / math.pi * SUN["irradiance"] * u[1]
    res = image(sc, "analytic", {"precision": 1e-9})
    err = np.abs(res.image - ref)
    assert np.all(ref[..., 1] > 0.0)
    assert np.max(err / ref) < 1e-9
    assert np.all(err <= res.error_bound)


def test_a_camera_inside_a_refractive_shape_that_is_not_convex_is_refused(tmp_path):
    """The rows from the camera have no entry face, and a shape that is not convex has no refracted
    paths of the light but through the entry face's plane: refused in one line."""
    from .test_inside_paths import LAMP as U_LAMP, u_obj, u_scene

    (tmp_path / "u.obj").write_text(u_obj())
    sc = u_scene(U_LAMP)
    sc["shape"][0]["interior"]["ior"] = 1.33
    sc["camera"]["position"] = [-0.7, 0.0, 0.0]  # in the U's left arm
    (tmp_path / "u.toml").write_text(to_toml(sc))
    with pytest.raises(UserError, match=r"camera.position: inside shape\[0\].*convex shape") as err:
        render(prepare(load_scene(tmp_path / "u.toml")), "quadrature", {}, RenderOptions(threads=1))
    assert "\n" not in str(err.value)
