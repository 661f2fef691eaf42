"""A scene's [render] defaults never block another method: the parameters of the scene's own method
that the chosen one does not read are left out with one note (api.scene_defaults), and every bundled
scene renders with every method that supports its medium and lights."""
from __future__ import annotations

import warnings

import pytest

import raytrace
from raytrace.api import SceneDefaultNote
from raytrace.cli import main, one_line_warning
from raytrace.methods import registry
from raytrace.scene.assets import bundled_scenes

from .conftest import box_room


def test_another_methods_parameter_is_ignored_with_one_note():
    scene = box_room(render={"method": "quadrature", "rtol": 1e-6})
    with pytest.warns(SceneDefaultNote, match=r"^scene: \[render\] rtol = 1e-06: not read by method raymarch; "
                                              r"ignored$") as caught:
        img = raytrace.render(scene, method="raymarch", width=4, height=3, threads=1)
    assert len(caught) == 1 and img.method == "raymarch" and "rtol" not in img.params
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert raytrace.render(scene, width=4, height=3, threads=1).params["rtol"] == 1e-6  # its own method reads it


def test_a_keyword_the_method_does_not_read_is_still_refused():
    with pytest.raises(raytrace.UserError, match="method raymarch does not read"):
        raytrace.render(box_room(), method="raymarch", rtol=1e-6)


def test_the_cli_renders_with_the_note(tmp_path):
    out = tmp_path / "a.exr"
    with pytest.warns(SceneDefaultNote, match=r"sunrise\.toml: \[render\] rtol = 1e-06: not read by method raymarch"):
        assert main(["sunrise", "--method", "raymarch", "--width", "4", "--height", "3", "--threads", "1",
                     "--out", str(out), "--quiet"]) == 0
    assert out.is_file()


def test_the_cli_prints_a_warning_on_one_line():
    text = one_line_warning("a.toml: [render] rtol = 1e-06:\n  not read", SceneDefaultNote, "api.py", 1, "source")
    assert text == "warning: a.toml: [render] rtol = 1e-06: not read\n"


def _available(name, path):
    """Bundled scenes whose meshes come from RAYTRACE_ASSETS load only with it."""
    try:
        return raytrace.load(path)
    except raytrace.UserError as exc:
        if "RAYTRACE_ASSETS" in str(exc):
            return None
        raise


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(bundled_scenes()))
def test_every_bundled_scene_renders_with_every_method_that_supports_it(name):
    """8 x 6 pixels, every method: a refusal may name the medium, the lights or the method's limits,
    never a [render] parameter of the scene's own method; the methods that take every medium and
    light (quadrature, raymarch, montecarlo) and the scene's own render it. Needs RAYTRACE_ASSETS for
    the paper's meshes: RAYTRACE_ASSETS=../shared/scenes .venv/bin/python -m pytest -m slow -k bundled_scene"""
    if _available(name, bundled_scenes()[name]) is None:
        pytest.skip(f"{name}: its meshes need RAYTRACE_ASSETS")
    rendered = []
    for method in registry():
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", SceneDefaultNote)
                img = raytrace.render(name, method=method, width=8, height=6, spp=1, threads=1, samples=1
                                      if method == "montecarlo" else None)
        except raytrace.UserError as exc:
            assert "does not read this parameter" not in str(exc), f"{name} with {method}: {exc}"
            continue
        assert img.array.shape == (6, 8, 3)
        rendered.append(method)
    own = raytrace.load(name).render.get("method", "analytic")
    assert own in rendered and {"quadrature", "raymarch", "montecarlo"} <= set(rendered), rendered
