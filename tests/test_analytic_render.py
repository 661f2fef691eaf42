"""`analytic` against `quadrature`, pixel by pixel, for precisions 1e-3 ... 1e-8 (issue: 10·P).

Box rooms with isotropic, Rayleigh and Henyey-Greenstein media (g = -0.5, 0.5, 0.9, 0.95), thin and
thick (optical depth above 15 along the view), a light near the view axis and one behind the
camera. Images are compared in float64 through the renderer API (no EXR rounding).
"""
import numpy as np
import pytest

from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text

from .conftest import box_room, to_toml

LIGHTS = [{"position": [0.31, 0.2, 0.5], "intensity": [10.0, 8.0, 6.0]},   # near the view axis
          {"position": [1.0, -0.5, 3.9], "intensity": 5.0},                # behind the camera
          {"position": [-2.0, 1.5, -3.0], "intensity": [2.0, 4.0, 6.0]}]

MEDIA = {
    "isotropic thin": {"sigma_a": 0.01, "sigma_s": [0.05, 0.1, 0.2], "phase": "isotropic"},
    "isotropic thick": {"sigma_a": 0.5, "sigma_s": 2.5, "phase": "isotropic"},
    "rayleigh thin": {"sigma_a": 0.02, "sigma_s": 0.2, "phase": "rayleigh"},
    "rayleigh thick": {"sigma_a": 1.0, "sigma_s": [2.0, 2.5, 3.0], "phase": "rayleigh"},
    "hg -0.5": {"sigma_a": 0.05, "sigma_s": 0.3, "phase": {"type": "hg", "g": -0.5}},
    "hg 0.5 thick": {"sigma_a": 0.5, "sigma_s": 2.5, "phase": {"type": "hg", "g": 0.5}},
    "hg 0.9": {"sigma_a": 0.02, "sigma_s": [0.1, 0.2, 0.4], "phase": {"type": "hg", "g": 0.9}},
    "hg 0.95": {"sigma_a": 0.02, "sigma_s": [0.1, 0.2, 0.4], "phase": {"type": "hg", "g": 0.95}},
}
CAMERA = {"position": [0.3, 0.2, 3.0], "look_at": [0.3, 0.2, -1.0], "fov": 80.0, "width": 12, "height": 9}


def prepared(medium):
    scene = box_room(camera=dict(CAMERA), medium=medium, light=LIGHTS)
    return prepare(scene_from_text(to_toml(scene), "test"))


_REFERENCE = {}


def reference(name):
    if name not in _REFERENCE:
        _REFERENCE[name] = render(prepared(MEDIA[name]), "quadrature", {"rtol": 1e-12}, RenderOptions(threads=1)).image
    return _REFERENCE[name]


PRECISIONS = [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8]
# `analytic` hands rays it cannot serve to its fallback, the `quadrature` kernel, which is also the
# reference here: a change sending every ray there would pass the accuracy check. Fallback fraction
# of the air-light evaluations (result.stats["fallback_fraction"]) measured per medium at each of
# PRECISIONS; HG media fall back where H = kt h exceeds the cosine-moment recurrence's limit, and
# below 1e-7 the kernels work to 1e-3 P (`working_precision`), where that limit is small.
FALLBACK_MEASURED = {
    "hg -0.5": (0.0, 0.0, 0.0, 0.0, 0.0, 0.216),
    "hg 0.5 thick": (0.0, 0.077, 0.185, 0.238, 0.281, 0.963),
    "hg 0.9": (0.0, 0.0, 0.0, 0.0, 0.02, 0.904),
    "hg 0.95": (0.0, 0.0, 0.001, 0.008, 0.041, 0.921),
    "isotropic thick": (0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    "isotropic thin": (0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    "rayleigh thick": (0.0, 0.0, 0.0, 0.0, 0.0, 0.561),
    "rayleigh thin": (0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
}


def fallback_bound(measured):
    """Twice the measured fraction, at least 2 % (6 of the 324 evaluations of a grey medium: a few
    rays that flip path on another CPU), at most halfway to 1 (so that "every ray falls back" fails
    wherever the analytic path serves any ray at all). hg 0.9 and 0.95 at 1e-8 send 90 % of the
    evaluations to the fallback: there the comparison is mostly quadrature with quadrature."""
    return max(0.02, min(2.0 * measured, 0.5 * (1.0 + measured)))


@pytest.mark.parametrize("precision", PRECISIONS)
@pytest.mark.parametrize("name", sorted(MEDIA))
def test_analytic_meets_its_precision_in_every_pixel(name, precision):
    result = render(prepared(MEDIA[name]), "analytic", {"precision": precision}, RenderOptions(threads=1))
    img = result.image
    ref = reference(name)
    rel = np.abs(img - ref) / ref
    assert np.all(np.isfinite(img))
    assert rel.max() <= 10 * precision, f"max rel {rel.max():.2e} at {np.unravel_index(rel.argmax(), rel.shape)}"
    frac = result.stats["fallback_fraction"]
    bound = fallback_bound(FALLBACK_MEASURED[name][PRECISIONS.index(precision)])
    assert result.stats["evaluations"] > 0
    assert frac <= bound, f"{frac:.1%} of the air-light evaluations went to the quadrature fallback (bound {bound:.1%})"


@pytest.mark.parametrize("name", sorted(MEDIA))
def test_thick_media_are_optically_deep_along_the_view(name):
    """The central camera ray, traced through the prepared scene, crosses an optical depth
    sigma_t * t_hit of the parsed medium above 15 in the thick media (every channel) and below 2
    in the thin ones; the others (HG g = -0.5, 0.9 and 0.95, at most 2.94) are moderate, below 5."""
    prep = prepared(MEDIA[name])
    cam = prep.scene.camera
    forward = (cam.look_at - cam.position) / np.linalg.norm(cam.look_at - cam.position)
    t, prim = prep.accel.first_hit(cam.position[None, :], forward[None, :])
    assert prim[0] >= 0 and np.isfinite(t[0])
    depth = np.asarray(prep.scene.medium.sigma_t) * t[0]
    if "thick" in name:
        assert depth.min() > 15.0, depth
    elif "thin" in name:
        assert depth.max() < 2.0, depth
    else:
        assert depth.max() < 5.0, depth


@pytest.mark.parametrize("name", ["isotropic thin", "hg 0.5 thick"])
def test_float32_images_agree_at_precision_1e_8(name, tmp_path):
    """Through the command line and float32 EXR files: at precision 1e-8, 10·P = 1e-7 is below one
    float32 ulp (1.2e-7 near 1), so the two renders must round to the same float32 values; the
    analytic kernels work 1000 times finer than requested there (`working_precision`)."""
    from raytrace.cli import main
    from raytrace.output.film import read_exr

    scene = box_room(camera={**CAMERA, "width": 64, "height": 48}, medium=MEDIA[name], light=LIGHTS)
    path = tmp_path / "s.toml"
    path.write_text(to_toml(scene))
    assert main(["render", str(path), "--method", "quadrature", "--out", str(tmp_path / "q.exr"), "--quiet"]) == 0
    assert main(["render", str(path), "--method", "analytic", "--precision", "1e-8", "--out", str(tmp_path / "a.exr"),
                 "--quiet"]) == 0
    q, a = read_exr(tmp_path / "q.exr")[0], read_exr(tmp_path / "a.exr")[0]
    assert (np.abs(a - q) / q).max() <= 1e-7
