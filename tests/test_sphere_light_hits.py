"""A sphere light seen by the camera: its rays end on the exact sphere (geometry/sphere.py), not on a
tessellation of it, so the emitter's radiance and the air-light in front of it are those of the
sphere. Against tests/area_twin.py's twin (the ray's exact hit, scipy over the visible cap and the
ray, built from the geometry alone). An exact `[[shape]]` sphere that emits is that sphere light."""
import numpy as np
import pytest

from raytrace import api
from raytrace.errors import UserError
from raytrace.geometry.sphere import on_surface

from . import area_twin as twin
from .test_area_lights import KS, KT, SPHERE, scene

# aimed at the lamp: 8 of the 20 rays end on it, the rest pass beside it
CAMERA = {"position": [0.0, 0.0, 4.0], "look_at": SPHERE["center"], "fov": 9.0, "width": 5, "height": 4}


@pytest.fixture(scope="module")
def reference():
    """The twin's radiance per pixel, which rays hit the lamp, and which pass within 1 % of its radius
    outside it (grazing: the rule about the segment converges slowest there, tests/test_sphere_rule.py)."""
    em = twin.Sphere(SPHERE["center"], SPHERE["radius"], SPHERE["radiance"])
    o = np.array(CAMERA["position"])
    dirs = twin.camera_rays(o, CAMERA["look_at"], [0.0, 1.0, 0.0], CAMERA["fov"], CAMERA["width"], CAMERA["height"])
    hits = np.array([[em.hit(o, d)[1] for d in row] for row in dirs])
    f = o - em.c
    offset = np.linalg.norm(f - (dirs @ f)[..., None] * dirs, axis=-1) / em.R
    return np.array([[twin.radiance(em, o, d, KT, KS) for d in row] for row in dirs]), hits, ~hits & (offset < 1.01)


@pytest.mark.parametrize("method, params", [("quadrature", {"rtol": 1e-6, "volumetric_shadows": False}),
                                            ("quadrature", {"rtol": 1e-6, "volumetric_shadows": True}),
                                            ("analytic", {"precision": 1e-6, "volumetric_shadows": False})])
def test_rays_ending_on_a_sphere_light_see_the_exact_sphere(reference, method, params):
    """Within 1e-6 of the twin on every pixel but the 4 grazing ones (0.8 % of the radius outside,
    counted as not converged, within 2e-5): the 8 hits to about 1e-8 (a tessellation of 64 segments
    puts them up to 3.6e-4 nearer: 1.2e-4 off here); every ray by the rule about its segment;
    the lamp does not shadow its own emitter points (with volumetric shadows: the same pixels)."""
    ref, hits, grazing = reference
    assert hits.sum() == 8 and grazing.sum() == 4
    img = api.render(scene([SPHERE], camera=CAMERA), method, **params)
    rel = np.abs(img.array[..., 0] / ref - 1)
    assert rel[hits].max() <= 1e-7, rel[hits].max()
    assert rel[~grazing].max() <= 1e-6 and rel[grazing].max() <= 2e-5, rel
    assert img.stats["cubature: rays near an emitter"] == ref.size, img.stats
    assert img.stats["cubature: rays near an emitter not converged"] == grazing.sum(), img.stats


def test_the_lamps_points_lie_on_its_sphere_to_rounding():
    """`on_surface` holds for the emitter's cubature nodes and its penumbra samples (so the sphere does
    not shadow them, whichever side rounding puts them) and fails a relative 1e-13 off the sphere."""
    from raytrace.lights import sphere

    lamp = scene([SPHERE]).lights[0]
    c, r = np.asarray(SPHERE["center"], float), SPHERE["radius"]
    u = np.random.default_rng(1).random((2, 500))
    points = np.concatenate([sphere.rows(lamp, 12).position, sphere.sample_emitter(lamp, *u)[0]])
    assert all(on_surface(p, c, r) for p in points)
    normals = (points - c) / r
    assert not any(on_surface(c + r * (1.0 + s * 1e-13) * n, c, r) for n in normals[::50] for s in (-1.0, 1.0))


def test_an_exact_sphere_that_emits_is_that_sphere_light():
    """`[[shape]] primitive = "sphere", exact = true, emission = L` (here scaled into place by its
    transform) renders as the `[[light]] type = "sphere"` of its world centre, radius and radiance L, bit
    for bit; two_sided is refused in one line naming the key."""
    shape = {"primitive": "sphere", "center": [0.0, 0.75, 0.0], "radius": 0.15, "exact": True,
             "emission": SPHERE["radiance"], "transform": {"scale": [2.0, 2.0, 2.0]}}
    emitting = scene([], camera=CAMERA, shapes=[shape])
    light, = emitting.lights
    np.testing.assert_array_equal(light.position, SPHERE["center"])
    assert light.emitter["radius"] == SPHERE["radius"] and emitting.shapes[0].light == 0
    for method, params in (("quadrature", {"rtol": 1e-6}), ("montecarlo", {"samples": 4})):
        np.testing.assert_array_equal(api.render(emitting, method, **params).array,
                                      api.render(scene([SPHERE], camera=CAMERA), method, **params).array)
    with pytest.raises(UserError, match=r"shape\[0\]\.two_sided: an exact sphere that emits is a sphere light"):
        scene([], camera=CAMERA, shapes=[{**shape, "two_sided": True}])


@pytest.mark.parametrize("fmt", ["mitsuba", "pbrt"])
def test_an_emitting_exact_sphere_exports_as_an_emitting_sphere(tmp_path, fmt):
    """Mitsuba and pbrt write it as their emitting sphere, which reads back as the same sphere light."""
    from raytrace.io import mitsuba, pbrt
    from raytrace.scene.format import scene_from_dict

    module, out = {"mitsuba": (mitsuba, tmp_path / "s.xml"), "pbrt": (pbrt, tmp_path / "s.pbrt")}[fmt]
    shape = {"primitive": "sphere", "center": [0.0, 1.5, 0.0], "radius": 0.3, "exact": True, "emission": 10.0}
    module.export({"camera": CAMERA, "shape": [shape]}, out, "test", False)
    back = scene_from_dict(module.read_scene(out), str(out))
    light, = back.lights
    assert light.kind == scene([SPHERE]).lights[0].kind and light.emitter["radius"] == SPHERE["radius"]
    np.testing.assert_allclose(light.position, SPHERE["center"], atol=1e-15)
    np.testing.assert_array_equal(light.intensity, [SPHERE["radiance"]] * 3)
