"""method = "auto" (SCENE_FORMAT.md, api.choose_method): analytic where the checks renderer.render
makes accept the scene, else quadrature, with the requested accuracy under the picked method's key
(precision <-> rtol) and the choice in the summary line; a named method still forces itself; and the
share of pixels without a finite error bound on `Image`, its repr, the EXR header and the summary line."""
from __future__ import annotations

import numpy as np
import pytest

import raytrace
from raytrace.cli import main
from raytrace.output.film import read_exr, read_exr_channels

from .conftest import box_room

TINY = {"width": 16, "height": 12, "spp": 1}
AUTO = ['render.method="auto"']  # the bundled scenes name their method; this puts them back on the default


def test_box_room_picks_analytic_with_the_precision_asked():
    img = raytrace.render("box_room", "auto", precision=1e-5, **TINY)
    assert img.method == "analytic" and img.auto == "analytic" and img.params["precision"] == 1e-5
    assert img.method_label == "auto → analytic"


def test_rtol_given_to_auto_becomes_analytics_precision():
    img = raytrace.render("box_room", "auto", rtol=1e-6, **TINY)
    assert img.method == "analytic" and img.params["precision"] == 1e-6 and "rtol" not in img.params


def test_a_scene_without_a_method_renders_with_auto():
    img = raytrace.render(box_room(), width=4, height=3)  # conftest's room has no [render] table
    assert img.auto == "analytic"


def test_a_sun_in_height_fog_falls_back_to_quadrature_with_the_reason_and_the_accuracy():
    # valley_fog: exponential height fog under a directional sun, which analytic does not take
    img = raytrace.render("valley_fog", overrides=AUTO, precision=1e-4, **TINY)
    assert img.method == "quadrature" and img.params == {"rtol": 1e-4}
    assert img.auto.startswith("quadrature (analytic: does not take height_fog media")
    # the same pixels as quadrature named with that rtol: auto adds nothing to the render
    named = raytrace.render("valley_fog", "quadrature", rtol=1e-4, **TINY)
    assert (img.array == named.array).all()


def test_without_an_accuracy_auto_passes_analytics_default_precision_to_quadrature():
    img = raytrace.render("valley_fog", overrides=AUTO, **TINY)
    assert img.params == {"rtol": raytrace.api.get_method("analytic", "x").params["precision"].default}


def test_precision_and_rtol_together_are_refused():
    says = r"given precision and rtol: with method auto each names the accuracy \(for analytic precision, quadrature rtol\)"
    with pytest.raises(raytrace.UserError, match=says):
        raytrace.render("box_room", "auto", precision=1e-4, rtol=1e-4, **TINY)


def test_a_parameter_analytic_refuses_is_an_error_not_a_switch():
    with pytest.raises(raytrace.UserError, match=r"--precision \(render.precision\): must be"):
        raytrace.render("valley_fog", overrides=AUTO, precision=5.0, **TINY)
    with pytest.raises(raytrace.UserError, match="method analytic does not read this parameter"):
        raytrace.render("box_room", "auto", steps=8, **TINY)


def test_a_named_method_still_forces_itself_and_refuses_clearly():
    with pytest.raises(raytrace.UserError, match=r"--method analytic: it does not take height_fog media"):
        raytrace.render("valley_fog", "analytic", **TINY)


def test_the_summary_line_names_the_choice_and_the_unbounded_share(tmp_path, capsys):
    out = tmp_path / "v.exr"
    assert main(["render", "valley_fog", "--set", *AUTO, "--width", "16", "--height", "12", "--spp", "1",
                 "--out", str(out)]) == 0
    line = capsys.readouterr().out
    assert line.count("\n") == 1
    assert 'method auto → quadrature (analytic: does not take height_fog media (medium.type = "height_fog"))' in line
    # quadrature bounds its fog integrals (docs/error_bounds.md): every pixel of the EXR's bound is finite
    bound = read_exr_channels(out, "error_bound")
    assert np.isfinite(bound).all() and "unbounded" not in line
    header = read_exr(out)[1]
    assert header["unbounded_pixels"] == "0" and header["method_choice"].startswith("auto → quadrature")
    # area lights' emitter points are a cubature without a bound: every pixel the haze glows in is unbounded
    assert main(["render", "studio", "--width", "16", "--height", "10", "--spp", "1", "--out", str(out)]) == 0
    line = capsys.readouterr().out
    assert line.rstrip().endswith("; 100 % of pixels unbounded: area lights' cubature")
    assert read_exr(out)[1]["unbounded_pixels"] == "1"


def test_a_partly_unbounded_render_counts_the_pixels_of_its_bound_channels(tmp_path):
    out = tmp_path / "w.exr"
    # the glints of the particle layer have no bound, the rest of the shaft has (the wax block was the
    # example until quadrature bounded its inside integrals)
    img = raytrace.render("particles_shaft", "auto", **TINY)
    img.save(out)
    share = float(np.isinf(read_exr_channels(out, "error_bound")).any(axis=-1).mean())
    assert 0.0 < share < 1.0 and img.unbounded == share
    assert float(read_exr(out)[1]["unbounded_pixels"]) == pytest.approx(share, rel=1e-6)
    assert img.unbounded_reason == "particle glints"
    assert img.bound_note() == f"{100 * share:.1f} % of pixels unbounded: particle glints"


def test_a_fully_bounded_render_says_nothing_on_its_line(tmp_path, capsys):
    assert main(["render", "box_room", "--width", "16", "--height", "12", "--spp", "1",
                 "--out", str(tmp_path / "b.exr")]) == 0
    line = capsys.readouterr().out
    assert "unbounded" not in line and "method analytic in" in line


def test_repr_is_one_line_with_size_method_time_and_bound_share():
    img = raytrace.render("box_room", **TINY)
    text = repr(img)
    assert "\n" not in text and len(text) < 200
    assert text.startswith("Image(box_room: 16x12, method analytic, ") and text.endswith(" s, every pixel bounded)")
    studio = raytrace.render("studio", **TINY)
    assert repr(studio).endswith("100 % of pixels unbounded: area lights' cubature)")


@pytest.mark.parametrize(("share", "text"), [(0.0148, "1.5 %"), (1e-5, "< 0.1 %"), (0.99999, "> 99.9 %"),
                                             (1.0, "100 %"), (0.5, "50.0 %")])
def test_percent(share, text):
    assert raytrace.api._percent(share) == text
