"""Volumetric shadows (light shafts): every method integrates the lit intervals that
raytrace/shadows/frusta.py finds, checked against an independent twin (tests/oracle.py: analytic shadow
boundaries of rectangular plates, scipy quadrature of eq. 4 on each lit piece)."""
import numpy as np
import pytest

import raytrace
from raytrace.methods import registry

from . import oracle
from .conftest import box_room

LIGHT = [0.0, 1.5, -1.0]
# (y0, (xmin, xmax), (zmin, zmax)): a plate just below the light and a bar further down
PLATES = [(1.2, (-1.0, 1.0), (-2.0, 0.0)), (0.4, (-2.5, 2.5), (-1.3, -0.9))]
CAMERA = {"position": [0.0, 0.0, 3.5], "look_at": [0.0, 0.0, -1.0], "fov": 80.0, "width": 12, "height": 9, "spp": 1}
MEDIUM = {"sigma_a": 0.05, "sigma_s": [0.2, 0.3, 0.5], "phase": {"type": "hg", "g": 0.5}}


def quad(plate):
    y, (a, b), (c, e) = plate
    return {"primitive": "quad", "corners": [[a, y, c], [b, y, c], [b, y, e], [a, y, e]], "reflectance": 0.0}


def scene(plates=PLATES, medium=MEDIUM, camera=CAMERA):
    """Black walls and plates: the image is the air-light alone."""
    s = box_room(camera=dict(camera), medium=medium, light=[{"position": LIGHT, "intensity": 20.0}])
    s["shape"][0]["reflectance"] = 0.0
    s["shape"] += [quad(p) for p in plates]
    return s


def twin(s, plates):
    """The oracle's image: per pixel centre, the ray to the nearer of the room's wall and the plates."""
    cam, med = s["camera"], s["medium"]
    lo, hi = np.array(s["shape"][0]["min"], float), np.array(s["shape"][0]["max"], float)
    ks = np.broadcast_to(np.array(med["sigma_s"], float), 3)
    kt = ks + med["sigma_a"]
    ph = med["phase"]
    name, g = (ph, 0.0) if isinstance(ph, str) else (ph["type"], ph["g"])
    img = np.zeros((cam["height"], cam["width"], 3))
    for j in range(cam["height"]):
        for i in range(cam["width"]):
            o, d = oracle.camera_ray(cam, i, j)
            t = min([oracle.box_exit(o, d, lo, hi)[0]] + [oracle.plate_hit(o, d, p) for p in plates])
            for c in range(3):
                img[j, i, c] = oracle.shadowed_airlight(o, d, t, LIGHT, 20.0, kt[c], ks[c], name, g, plates)
    return img


@pytest.fixture(scope="module")
def reference():
    return twin(scene(), PLATES)


def _errors(img, ref):
    scale = ref.max()
    lit = ref > 1e-3 * scale
    rel = np.abs(img - ref)[lit] / ref[lit]
    return rel.max(), (np.abs(img - ref)[~lit].max(initial=0.0) / scale)


def test_the_twin_sees_the_shadows(reference):
    unshadowed = twin(scene(), [])
    assert np.all(reference <= unshadowed * (1 + 1e-9))
    assert (reference < 0.5 * unshadowed).mean() > 0.2  # a large part of the view is in shadow


@pytest.mark.parametrize("method, params, rel_tol", [("analytic", {"precision": 1e-6}, 1e-5),
                                                     ("quadrature", {"rtol": 1e-10}, 1e-5)])
def test_shadowed_air_light_matches_the_twin(reference, method, params, rel_tol):
    """Exact up to the boundary tolerance: 10 x precision in every lit pixel; pixels whose air-light
    is almost all shadowed are compared in absolute terms (a sliver of ~1e-6 of the scene's size
    before a surface is left lit by the float32 shadow-ray margin)."""
    img = raytrace.render(scene(), method=method, volumetric_shadows=True, threads=1, **params)
    rel, absolute = _errors(img.array, reference)
    assert rel <= rel_tol, rel
    assert absolute <= 1e-5, absolute
    assert img.stats["shadows: shadow intervals"] > 0


def test_every_method_integrates_the_lit_intervals(reference):
    """Each method's own error law holds on the shadowed image too (the lit pieces are ordinary segments)."""
    for name, m in registry().items():
        law = m.error_law
        try:
            img = raytrace.render(scene(medium={**MEDIUM, "phase": "isotropic"}), method=name,
                                  volumetric_shadows=True, threads=1, seed=1, **law.params)
        except raytrace.UserError as exc:
            pytest.fail(f"{name} refused volumetric shadows: {exc}")
        unshadowed = raytrace.render(scene(medium={**MEDIUM, "phase": "isotropic"}), method=name, threads=1,
                                     seed=1, volumetric_shadows=False, **law.params)
        assert np.all(np.isfinite(img.array)) and img.array.mean() < 0.8 * unshadowed.array.mean(), name


def test_without_occluders_shadows_change_nothing():
    s = scene(plates=[], medium={**MEDIUM, "phase": "isotropic"})
    for name, m in registry().items():
        a = raytrace.render(s, method=name, threads=1, seed=2, volumetric_shadows=False, **m.error_law.params)
        b = raytrace.render(s, method=name, threads=1, seed=2, volumetric_shadows=True, **m.error_law.params)
        np.testing.assert_allclose(b.array, a.array, rtol=1e-12, err_msg=name)
        assert b.stats["shadows: lit intervals"] == b.stats["shadows: segments searched"] > 0  # every segment whole


def test_the_classic_shadow_rays_per_sample_converge_to_the_same_image(reference):
    img = raytrace.render(scene(), method="raymarch", steps=2048, shadow_test="samples", volumetric_shadows=True,
                          threads=1)
    rel, absolute = _errors(img.array, reference)
    assert rel < 2e-2 and absolute < 1e-2  # only ~1/steps accurate at the shadow boundaries
    exact = raytrace.render(scene(), method="raymarch", steps=2048, volumetric_shadows=True, threads=1)
    assert _errors(exact.array, reference)[0] < 0.1 * rel  # the lit intervals remove the boundary error


def test_the_old_shadow_spacing_is_accepted_and_not_read():
    """`shadow_spacing` set the sampled search's spacing, now gone (the lit intervals are exact):
    older scripts and scenes still run, and the image is the same whatever its value."""
    a = raytrace.render(scene(), method="analytic", volumetric_shadows=True, width=12, height=9, threads=1)
    b = raytrace.render(scene(), method="analytic", volumetric_shadows=True, width=12, height=9, threads=1,
                        shadow_spacing=0.6)
    assert np.array_equal(a.array, b.array)



def test_shadow_test_samples_needs_shadows():
    with pytest.raises(raytrace.UserError, match="only acts with volumetric shadows"):
        raytrace.render(scene(), method="raymarch", shadow_test="samples", volumetric_shadows=False)


def test_a_light_on_a_surface_lights_the_side_it_faces():
    """Shadow rays start the shadow-ray epsilon away from the light: a lamp on the ceiling lights
    the room (it was 0.196 of the unshadowed air-light when the rays started on the ceiling)."""
    room = box_room(camera=dict(CAMERA), light=[{"position": [0.0, 2.0, 0.0], "intensity": 5.0}])
    a = raytrace.render(room, method="analytic", threads=1, volumetric_shadows=False).array
    b = raytrace.render(room, method="analytic", threads=1, volumetric_shadows=True).array
    assert abs(b.mean() / a.mean() - 1.0) < 1e-3
    assert np.all(b <= a * (1 + 1e-9))
