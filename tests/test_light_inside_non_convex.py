"""A point or spot light inside a non-convex index-matched shape holding a medium (the U of
tests/test_inside_paths.py, the lamp in its right arm, fog outside too): the inside rows' light paths
start inside the shape, leave its arm and may enter the other (paths.walk from a far end inside), the
outside air-light is lit through the boundary. The twin knows only the U's three boxes (lengths by the
slab test) and integrates along each camera ray with scipy quad, split at the U's stretches, the
light's foot and the spot's cone."""
import math

import numpy as np
import pytest
from scipy import integrate

from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import load_scene

from . import oracle
from .conftest import to_toml
from .test_inside_paths import G, KA, KS, u_length, u_obj, u_scene, u_stretches
from .test_light_inside import raymarch_and_montecarlo

KS_OUT, KA_OUT = 0.04, 0.03
LAMP = {"type": "point", "position": [0.7, 0.1, 0.05], "intensity": 3.0}  # inside the right arm
SPOT = LAMP | {"type": "spot", "look_at": [-0.7, 0.0, 0.0], "cone_angle": 30.0, "falloff_start": 20.0}  # across


OPTIONS = RenderOptions(threads=1, volumetric_shadows=True)


def scene(light):
    sc = u_scene(light)
    sc["medium"] = {"sigma_a": KA_OUT, "sigma_s": KS_OUT}
    return sc


def twin(sc):
    light = sc["light"][0]
    lp, spot = np.array(light["position"], float), oracle.spot_of(light)
    kt, kt_out = KA + KS, KA_OUT + KS_OUT
    cam = sc["camera"]
    img = np.zeros((cam["height"], cam["width"], 3))
    for j in range(cam["height"]):
        for i in range(cam["width"]):
            o, d = oracle.camera_ray(cam, i, j)
            stretches = u_stretches(o, d)
            cuts = [t for s in stretches for t in s] + [float((lp - o) @ d)]
            cuts += list(oracle.cone_crossings(o, d, 60.0, lp, spot))
            cuts = sorted(t for t in cuts if 0.0 < t < 60.0)

            def f(t, c):
                X = o + t * d
                seen = u_length(o, d, 0.0, t)
                dist = float(np.linalg.norm(lp - X))
                u = (lp - X) / dist
                k = u_length(X, u, 0.0, dist)
                tau = kt[c] * (seen + k) + kt_out * (t - seen + dist - k)
                inside = any(a < t < b for a, b in stretches)
                ks, phase = (KS[c], oracle.phase("hg", G, float(u @ d))) if inside else (KS_OUT, 0.25 / math.pi)
                return ks * phase * light["intensity"] * oracle.emission(spot, -u) / dist**2 * math.exp(-tau)

            for c in range(3):
                edges = [0.0, *cuts, 60.0]
                img[j, i, c] = sum(integrate.quad(f, a, b, args=(c,), epsabs=0.0, epsrel=1e-11, limit=400)[0]
                                   for a, b in zip(edges, edges[1:]))
                img[j, i, c] += integrate.quad(f, 60.0, math.inf, args=(c,), epsabs=0.0, epsrel=1e-11)[0]
    return img


@pytest.fixture(scope="module", params=["lamp", "spot"])
def case(request, tmp_path_factory):
    sc = scene(LAMP if request.param == "lamp" else SPOT)
    path = tmp_path_factory.mktemp(request.param)
    (path / "u.obj").write_text(u_obj())
    (path / "u.toml").write_text(to_toml(sc))
    return prepare(load_scene(path / "u.toml")), twin(sc)


def test_quadrature_from_a_light_inside_a_non_convex_shape(case):
    """quadrature (rtol 1e-10, volumetric shadows: the outside air-light sees the light through the U's
    fog) within 1e-6 of the twin on every pixel (the walks' Embree crossings are float32: lengths good to
    about 1e-7 of the scene's size; measured 1.3e-7 for the lamp), inside its bound where that is finite."""
    prep, ref = case
    res = render(prep, "quadrature", {"rtol": 1e-10}, RenderOptions(threads=1, volumetric_shadows=True))
    err = np.abs(res.image - ref)
    finite = np.isfinite(res.error_bound)
    assert np.all(err <= 1e-6 * ref), np.max(err / ref)
    assert np.all(err[finite] <= res.error_bound[finite])


def test_raymarch_and_montecarlo_from_a_light_inside_a_non_convex_shape(case):
    """Raymarch at its order, Monte Carlo unbiased (test_light_inside's `raymarch_and_montecarlo`)."""
    prep, ref = case
    raymarch_and_montecarlo(lambda method, params, seed: render(
        prep, method, params, RenderOptions(threads=1, seed=seed, volumetric_shadows=True)), ref)
