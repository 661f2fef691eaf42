"""The command line's first-day items (issue 39): compare, sweep and gallery write nothing on bad
input (every method and parameter checked before the first render); compare's summary lines give
the maximum and RMS errors beside the means; `--crop` on one pixel prints its value and error bound."""
from __future__ import annotations

import numpy as np
import pytest

import raytrace
from raytrace.cli import main
from raytrace.output.metrics import errors

SIZE = ["--width", "16", "--height", "8", "--spp", "1"]


@pytest.mark.parametrize(("methods", "reference", "says"), [
    ("raymarch:step=abc", "quadrature", "--step (render.step): expected float, got 'abc'"),
    ("raymarch:steps=0", "quadrature", "--steps (render.steps): must be >= 1"),
    ("analytic,sun:table_size=1", "quadrature", "--table-size (render.table_size): must be >= 2"),
    ("analytic", "quadrature:rtol=2", "--rtol (render.rtol): must be >= 1e-14 and <= 0.5"),
    ("analytic", "nosuch", "unknown method"),
])
@pytest.mark.parametrize("command", ["compare", "sweep"])
def test_bad_methods_write_nothing(tmp_path, capsys, command, methods, reference, says):
    out = tmp_path / "d"
    grid = ["--grid", "medium.sigma_s=0.1,0.2"] if command == "sweep" else []
    assert main([command, "box_room", *grid, "--methods", methods, "--reference", reference, "--out", str(out),
                 *SIZE]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and says in err, err
    assert not out.exists()


@pytest.mark.parametrize("command", ["compare", "sweep"])
def test_a_method_that_does_not_take_the_scene_writes_nothing(tmp_path, capsys, command):
    # valley_fog is height fog: the quadrature reference takes it, analytic does not
    out = tmp_path / "d"
    grid = ["--grid", "medium.sigma_s=0.01"] if command == "sweep" else []
    assert main([command, "valley_fog", *grid, "--methods", "raymarch,analytic", "--out", str(out), *SIZE]) == 2
    err = capsys.readouterr().err
    assert "--methods analytic: --method analytic: it does not take height_fog media" in err, err
    assert not out.exists()


def test_a_sweep_point_a_method_refuses_writes_nothing(tmp_path, capsys):
    # the second point makes the phase function Rayleigh, which sun's table does not take
    out = tmp_path / "d"
    assert main(["sweep", "box_room", "--grid", 'medium.phase="isotropic","rayleigh"', "--methods", "sun",
                 "--out", str(out), *SIZE]) == 2
    assert "--methods sun: --method sun: it does not take rayleigh phase functions" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize(("args", "says"), [(["--width", "0"], "width=0"), (["--threads", "-1"], "threads=-1"),
                                            (["nosuch"], "not a bundled scene")])
def test_gallery_bad_input_writes_nothing(tmp_path, capsys, args, says):
    out = tmp_path / "g"
    assert main(["gallery", "box_room", *args, "--out", str(out)]) == 2
    assert says in capsys.readouterr().err
    assert not out.exists()


def test_compare_prints_max_and_rms_beside_the_means(tmp_path, capsys):
    import json

    out = tmp_path / "c"
    assert main(["compare", "box_room", "--methods", "raymarch:steps=4,analytic", "--out", str(out), *SIZE]) == 0
    lines = capsys.readouterr().out.splitlines()
    rows = {r["method"]: r for r in json.loads((out / "compare.json").read_text())["methods"]}
    for label in ("raymarch:steps=4", "analytic"):
        line = next(x for x in lines if x.startswith(label + ":"))
        r = rows[label]
        assert (f"mean abs {r['mean_abs']:.3e}, mean rel {r['mean_rel']:.3e}, max rel {r['max_rel']:.3e}, "
                f"RMS {r['rms']:.3e}") in line, line
    # the figures are metrics.errors of the images written (the march's error is far above float32's rounding)
    from raytrace.output.film import read_exr

    test, ref = read_exr(out / "raymarch_steps_4.exr")[0], read_exr(out / "reference.exr")[0]
    for key in ("rms", "max_rel"):
        assert errors(test, ref)[key] == pytest.approx(rows["raymarch:steps=4"][key], rel=1e-4)


def test_a_one_pixel_crop_prints_its_value_and_a_bound_that_holds(tmp_path, capsys):
    out = tmp_path / "px.exr"
    assert main(["render", "box_room", "--width", "32", "--height", "16", "--crop", "10,5,11,6", "--out",
                 str(out), "--quiet"]) == 0
    line = capsys.readouterr().out
    assert line.count("\n") == 1 and line.startswith("pixel (10, 5): RGB ")
    rgb, bound = line.split("RGB ")[1].split(", error bound ")
    value, bound = np.array(rgb.split(), float), np.array(bound.split(), float)
    # the same pixel of the whole image, and a quadrature reference to 1e-12: within the printed bound
    whole = raytrace.render("box_room", width=32, height=16)
    assert np.allclose(value, whole.array[5, 10], rtol=1e-8, atol=0)
    ref = raytrace.render("box_room", "quadrature", rtol=1e-12, width=32, height=16, crop=(10, 5, 11, 6))
    assert (np.abs(value - ref.array[0, 0]) <= bound).all() and (bound > 0).all()


@pytest.mark.parametrize("method, what", [("quadrature", "error bound"), ("montecarlo", "standard error")])
def test_a_one_pixel_crop_names_a_bound_or_a_standard_error_by_the_method(tmp_path, capsys, method, what):
    """studio's area lights give a deterministic method's render a variance layer (sampled penumbrae);
    its printed figure is still the error bound, a stochastic method's the standard error."""
    assert main(["render", "studio", "--method", method, "--width", "16", "--height", "12", "--crop", "8,6,9,7",
                 "--out", str(tmp_path / "px.exr"), "--quiet"]) == 0
    line = capsys.readouterr().out
    assert line.startswith("pixel (8, 6): RGB ") and f", {what} " in line


def test_a_larger_crop_prints_no_pixel(tmp_path, capsys):
    assert main(["render", "box_room", "--width", "32", "--height", "16", "--crop", "10,5,12,6", "--out",
                 str(tmp_path / "a.exr"), "--quiet"]) == 0
    assert capsys.readouterr().out == ""
