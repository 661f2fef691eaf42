"""A scene fuzzer (issue 15, first part): random box-room scenes across magnitudes, phase functions,
point and spot lights (anywhere: inside, on walls, outside, on the camera), media from vacuum to
1e300, every deterministic and stochastic method, with and without volumetric shadows. Each scene
either renders an image of finite, non-negative pixels, or is refused with one line (UserError);
never another exception. Fixed seed; 40 scenes by default, `-m slow` runs 1000.
"""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

import raytrace
from raytrace.errors import UserError
from raytrace.methods import registry

METHODS_BY_NAME = registry()

from .conftest import box_room

MAGNITUDES = st.sampled_from([0.0, 1e-300, 1e-30, 1e-6, 0.01, 0.1, 1.0, 10.0, 1e6, 1e30, 1e150, 1e300])
# mostly inside the room ([-3, 3] x [-2, 2] x [-4, 4]), sometimes on or beyond its walls
coord = st.one_of(st.floats(-1.875, 1.875, width=32), st.floats(-5.0, 5.0, width=32), st.sampled_from([-3.0, 2.0, 4.0]))
vec = st.tuples(coord, coord, coord).map(list)
phase = st.one_of(st.sampled_from(["isotropic", "rayleigh"]),
                  st.floats(-0.999, 0.999, allow_nan=False).map(lambda g: {"type": "hg", "g": g}))


@st.composite
def light(draw):
    out = {"position": draw(vec), "intensity": draw(st.one_of(MAGNITUDES, st.tuples(MAGNITUDES, MAGNITUDES,
                                                                                    MAGNITUDES).map(list)))}
    if draw(st.booleans()):
        cone = draw(st.one_of(st.sampled_from([1e-3, 0.5, 1.0, 30.0, 90.0, 179.0, 179.999]),
                              st.floats(1e-3, 179.999)))
        out.update(type="spot", direction=draw(vec), cone_angle=cone,
                   falloff_start=draw(st.floats(0.0, 1.0)) * cone)
    return out


@st.composite
def scene(draw):
    cam = {"type": draw(st.sampled_from(["perspective", "environment"])), "position": draw(vec),
           "look_at": draw(vec), "width": 4, "height": 3, "spp": 1}
    lights = draw(st.lists(light(), min_size=0, max_size=3))
    if lights and draw(st.booleans()):
        lights[0]["position"] = list(cam["position"])  # a camera on a light
    medium = {"sigma_a": draw(MAGNITUDES), "sigma_s": draw(MAGNITUDES), "phase": draw(phase)}
    return box_room(camera=cam, light=lights, medium=medium)


METHODS = [("analytic", {"precision": 1e-4}), ("quadrature", {"rtol": 1e-6}), ("raymarch", {"steps": 8}),
           ("montecarlo", {"samples": 2}), ("lecocq", {}), ("sun", {})]


def check(sc, method, params, shadows):
    try:
        img = raytrace.render(sc, method=method, threads=1, volumetric_shadows=shadows, **params)
    except UserError as exc:
        msg = str(exc)
        assert msg and "\n" not in msg and "this is a bug" not in msg, msg
        return
    assert np.all(np.isfinite(img.array)) and np.all(img.array >= 0.0), (sc, method)
    if img.variance is not None:
        assert np.all(np.isfinite(img.variance)) and np.all(img.variance >= 0.0)


def _fuzz(examples):
    # no shrinking: it renders thousands of scenes in one process, and after ~2000 Embree scenes the
    # process crashed in embreex's scene construction (a leak to look into); failures print unshrunk
    @settings(max_examples=examples, derandomize=True, deadline=None, database=None,
              suppress_health_check=list(HealthCheck), phases=(Phase.explicit, Phase.generate))
    @given(scene(), st.sampled_from(METHODS), st.booleans())
    def run(sc, method, shadows):
        check(sc, method[0], method[1], shadows)

    run()


def test_fuzzed_scenes_render_or_refuse():
    with np.errstate(over="raise", invalid="raise", divide="raise"):  # a numpy warning fails the scene too
        _fuzz(40)


@pytest.mark.slow
def test_fuzzed_scenes_render_or_refuse_many():
    with np.errstate(over="raise", invalid="raise", divide="raise"):
        _fuzz(1000)


CAMERA_ON_SPOT_IN_ULTRA_DENSE_MEDIUM = box_room(
    camera={"type": "perspective", "position": [0.6147737503051758, -1.8686078786849976, 0.0],
            "look_at": [0.0, 0.15902665257453918, 0.4994328022003174], "width": 4, "height": 3, "spp": 1},
    light=[{"position": [0.6147737503051758, -1.8686078786849976, 0.0], "intensity": [1e150, 1e30, 1e6],
            "type": "spot", "direction": [1.1749484539031982, 1e-07, 0.0], "cone_angle": 97.44712180942933,
            "falloff_start": 94.07409015299417}],
    medium={"sigma_a": 1.0, "sigma_s": 1e300, "phase": "isotropic"})


def test_regression_camera_on_a_spot_light_in_an_ultra_dense_medium():
    """Was NaN: the segments start at the light, whose distance to the ray line is clamped to the
    regularisation radius h (methods/geometry.py) while d_a stayed 0, so analytic's optical path
    started at 0 instead of h (e^0 against e^{-kt h} = 0). Every exp(-1e300 x) is 0 here: so is the image."""
    img = raytrace.render(CAMERA_ON_SPOT_IN_ULTRA_DENSE_MEDIUM, method="analytic", threads=1,
                          volumetric_shadows=True, precision=1e-4)
    assert np.array_equal(img.array, np.zeros_like(img.array))


@pytest.mark.parametrize("light", [{}, {"type": "spot", "direction": [0.0, 0.0, -1.0], "cone_angle": 60.0,
                                        "falloff_start": 40.0}], ids=["point", "spot"])
@pytest.mark.parametrize("sigma_s", [1e6, 1e8, 1e10])
def test_regression_camera_on_a_light_analytic_meets_its_law(light, sigma_s):
    """The same cause away from underflow: a camera on a light in a medium with kt h from 5e-3 to 50
    (h the 5e-9 m regularisation radius). Before the fix analytic was 0.4 % (1e6), 49 % (1e8) and
    2e17 times (1e10) off quadrature; now within its declared law (methods/__init__.py ErrorLaw)."""
    law = METHODS_BY_NAME["analytic"].error_law
    sc = box_room(light=[{"position": [0.3, 0.2, 3.0], "intensity": 10.0, **light}],
                  medium={"sigma_a": 0.0, "sigma_s": sigma_s, "phase": "isotropic"},
                  camera={"type": "perspective", "position": [0.3, 0.2, 3.0], "look_at": [0.0, 0.0, -1.0],
                          "fov": 70.0, "width": 4, "height": 3, "spp": 1})
    ref = raytrace.render(sc, method="quadrature", threads=1, **METHODS_BY_NAME["quadrature"].error_law.params).array
    img = raytrace.render(sc, method="analytic", threads=1, **law.params).array
    assert np.all(ref > 0)
    assert np.max(np.abs(img - ref) / ref) <= law.tolerance
