"""Every method of the registry against the independent oracle (tests/oracle.py) on the box-room
scenes of tests/test_render_reference.py, judged by the method's own declared error law
(`Method.error_law`, raytrace/methods/__init__.py).

A (method, scene) pair the method refuses (`check` raises UserError, e.g. Sun's table on an
anisotropic medium) is skipped with the method's reason. Deterministic methods: the "max" or
"median" of the per-pixel relative error |img - ref| / ref (pixel-channels with ref > 0) is at
most the tolerance. Stochastic methods ("sigma"): the mean over pixel-channels of the squared
z-score (img - ref)^2 / variance, with the variance the render's own estimate, is at most the
tolerance (about 1 for an unbiased estimate with a fair variance); where the variance is 0 (no
scattering, the estimate is the deterministic surface term) the pixel must match the oracle to
1e-6. No law is vacuous: each must fail for an all-zero image.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from raytrace.errors import UserError
from raytrace.methods import ErrorLaw, registry, resolve_params
from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text

from . import oracle
from .conftest import to_toml
from .test_render_reference import CASES

METHODS = registry()
SEED = 1234
# the agreement the quadrature render reaches with the oracle (test_render_reference.py): pixels a
# stochastic method computes without noise (variance 0) must meet it too
DETERMINISTIC_RTOL = 1e-6

_ORACLE: dict = {}
_RENDERS: dict = {}


def oracle_image(name: str) -> np.ndarray:
    if name not in _ORACLE:
        scene = CASES[name]
        cam = scene["camera"]
        _ORACLE[name] = np.array([[oracle.box_room_pixel(scene, i, j) for i in range(cam["width"])]
                                  for j in range(cam["height"])])
    return _ORACLE[name]


def rendered(method_name: str, name: str):
    """The method's render of scene `name` with its error law's parameters (cached), or the
    method's refusal (UserError) if it does not support the scene."""
    key = (method_name, name)
    if key not in _RENDERS:
        method = METHODS[method_name]
        prep = prepare(scene_from_text(to_toml(CASES[name]), name))
        try:
            method.check(prep.scene.medium, resolve_params(method, method.error_law.params, "test"))
            method.check_lights(prep.lights, "test")
        except UserError as exc:
            _RENDERS[key] = exc
        else:
            _RENDERS[key] = render(prep, method_name, method.error_law.params, RenderOptions(seed=SEED, threads=1))
    return _RENDERS[key]


def statistic(law: ErrorLaw, img: np.ndarray, ref: np.ndarray, variance: np.ndarray | None) -> float:
    """The value of the law's statistic for image `img` against the oracle `ref` (see the module
    docstring); +inf where a stochastic method's noise-free pixels miss the oracle."""
    lit = ref > 0
    if law.statistic in ("max", "median"):
        rel = np.abs(img - ref)[lit] / ref[lit]
        return float(rel.max() if law.statistic == "max" else np.median(rel))
    assert law.statistic == "sigma", law.statistic
    noisy = variance > 0
    exact = lit & ~noisy
    if exact.any() and np.max(np.abs(img - ref)[exact] / ref[exact]) > DETERMINISTIC_RTOL:
        return math.inf
    if not noisy.any():
        return 0.0
    return float(np.mean((img - ref)[noisy] ** 2 / variance[noisy]))


PAIRS = [(m, s) for m in METHODS for s in sorted(CASES)]


def test_every_method_declares_an_error_law():
    for name, method in METHODS.items():
        law = method.error_law
        assert isinstance(law, ErrorLaw), name
        assert law.statistic in ("max", "median", "sigma"), (name, law.statistic)
        assert math.isfinite(law.tolerance) and law.tolerance > 0, (name, law.tolerance)
        assert (law.statistic == "sigma") == method.stochastic, name
        resolve_params(method, law.params, f"{name}.error_law")  # the parameters exist and are valid


def supported(method_name, name):
    """The method's render of the oracle scene, its error law and the oracle's image; skips the
    combinations the method refuses."""
    res = rendered(method_name, name)
    if isinstance(res, UserError):
        pytest.skip(f"{method_name} does not support {name}: {res}")
    return res, METHODS[method_name].error_law, oracle_image(name)


@pytest.mark.parametrize("method_name,name", PAIRS)
def test_method_meets_its_error_law(method_name, name):
    res, law, ref = supported(method_name, name)
    assert np.all(np.isfinite(res.image))
    if law.statistic == "sigma":
        assert res.variance is not None and np.all(res.variance >= 0)
        if np.any(np.asarray(CASES[name]["medium"]["sigma_s"]) > 0):  # scattering: every lit pixel carries noise
            assert np.all(res.variance[ref > 0] > 0)
    value = statistic(law, res.image, ref, res.variance)
    assert value <= law.tolerance, f"{method_name} on {name}: {law.statistic} {value:.3g} > {law.tolerance:g}"


@pytest.mark.parametrize("method_name,name", PAIRS)
def test_error_law_fails_for_an_all_zero_image(method_name, name):
    """No law is vacuous: an image of zeros (with the render's own variance) breaks it."""
    res, law, ref = supported(method_name, name)
    assert statistic(law, np.zeros_like(ref), ref, res.variance) > law.tolerance
