"""Inputs just outside the tested list (issue 15): meshes with nan or inf vertices and transforms that
overflow are refused with one line naming the file, the count and the first bad vertex line;
nothing is written."""
from __future__ import annotations

import pytest

import raytrace
from raytrace.cli import main
from raytrace.errors import UserError

from .conftest import box_room

TRIANGLE = "v 0 0 -3\nv 1 0 -3\nv 0 1 -3\nf 1 2 3\n"


def mesh_room(tmp_path, obj_text, transform=None):
    (tmp_path / "m.obj").write_text(obj_text)
    shape = {"mesh": "m.obj"}
    if transform:
        shape["transform"] = transform
    return box_room(shape=[box_room()["shape"][0], shape])


@pytest.mark.parametrize("bad", ["nan", "inf", "-inf"])
def test_a_mesh_with_non_finite_vertices_is_refused(write_scene, tmp_path, capsys, bad):
    text = "# a triangle and a broken one\n" + TRIANGLE + f"v 0 0 {bad}\nv 2 0 -3\nv 0 2 -3\nf 4 5 6\n"
    path = write_scene(mesh_room(tmp_path, text))
    out = tmp_path / "x.exr"
    assert main(["render", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "m.obj" in err and "shape[1].mesh" in err, err
    assert "1 vertex is not finite" in err and f"first at line 6: v 0 0 {bad}" in err, err
    assert not out.exists()


def test_a_transform_that_overflows_is_refused(write_scene, tmp_path, capsys):
    path = write_scene(mesh_room(tmp_path, TRIANGLE, {"scale": 1e308}))
    out = tmp_path / "x.exr"
    assert main(["render", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "shape[1].transform" in err and "overflow" in err, err
    assert not out.exists()


def test_an_image_too_large_for_memory_is_refused_up_front(write_scene, tmp_path, capsys):
    path = write_scene(box_room())
    out = tmp_path / "x.exr"
    assert main(["render", str(path), "--width", "100000", "--height", "100000", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "camera 100000x100000" in err and "GiB" in err and "--crop" in err, err
    assert not out.exists()


def test_a_large_legal_image_is_not_refused():
    """A 16k x 8k environment map (Monte Carlo, with variance) fits a 24 GiB machine's budget."""
    from types import SimpleNamespace

    from raytrace import api

    cam = SimpleNamespace(width=16384, height=8192)
    need = 16384 * 8192 * (api.PIXEL_BYTES + api.VARIANCE_BYTES)
    assert need < api.MEMORY_SHARE * 24 * 2**30
    if need < api.MEMORY_SHARE * api.physical_memory():
        api.check_memory(cam, None, True, "test")
    api.check_memory(cam, (0, 0, 64, 64), True, "test")  # a crop of it always


@pytest.mark.parametrize("method", ["analytic", "quadrature", "raymarch", "montecarlo"])
@pytest.mark.parametrize("sigma", [1e150, 1e308, 1.7e308])
def test_extreme_coefficients_render_finite(method, sigma):
    """A medium so dense that kt x overflows (sigma_s up to the largest doubles): every pixel is
    finite and non-negative, no numpy warnings (was: overflow warnings and "non-finite pixels", exit 2)."""
    import warnings

    import numpy as np

    import raytrace

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        img = raytrace.render(box_room(medium={"sigma_a": 0.05, "sigma_s": sigma}), method=method, threads=1)
    assert np.all(np.isfinite(img.array)) and np.all(img.array >= 0.0)


def test_a_huge_scene_in_proportion_renders_as_the_small_one():
    """Lengths x 1e30, coefficients / 1e30, intensities x 1e60: the same radiance (the air-light and
    the surface term are invariant), to the analytic method's precision."""
    import numpy as np

    import raytrace

    s = 1e30
    small = box_room()
    big = box_room(
        camera={**small["camera"], "position": [s * v for v in small["camera"]["position"]],
                "look_at": [s * v for v in small["camera"]["look_at"]]},
        shape=[{**small["shape"][0], "min": [s * v for v in small["shape"][0]["min"]],
                "max": [s * v for v in small["shape"][0]["max"]]}],
        light=[{"position": [s * v for v in small["light"][0]["position"]],
                "intensity": [s * s * v for v in small["light"][0]["intensity"]]}],
        medium={"sigma_a": 0.05 / s, "sigma_s": 0.15 / s})
    a = raytrace.render(small, method="analytic", precision=1e-6, threads=1).array
    b = raytrace.render(big, method="analytic", precision=1e-6, threads=1).array
    assert np.max(np.abs(b - a) / a) < 1e-5


@pytest.mark.parametrize("primitive", ["sphere", "cylinder"])
def test_too_many_segments_refused_before_tessellation(primitive):
    """segments = 1e9 hung tessellating (the fuzzer's 'number out of range'); 2048 is the most."""
    extra = {"center": [0.0, 0.0, 0.0]} if primitive == "sphere" else {"base": [0.0, 0.0, 0.0], "top": [0.0, 1.0, 0.0]}
    sc = box_room()
    sc["shape"].append({"primitive": primitive, "radius": 1.0, "segments": 10**9, **extra})
    with pytest.raises(UserError, match=r"shape\[1\]\.segments: must be at most 2048"):
        raytrace.render(sc, method="analytic", threads=1)


def test_max_memory_sets_the_budget_with_the_figure_and_the_fix(write_scene, tmp_path, capsys):
    """--max-memory GiB: a 1000 x 1000 analytic image needs 1000^2 x 90 B = 0.0838 GiB; with a budget of
    0.01 GiB it is refused before rendering, naming the budget and a --crop band that fits
    (0.01 GiB / (1000 x 90 B) = 119 rows); with 1 GiB the same command renders a small crop."""
    path = write_scene(box_room())
    out = tmp_path / "x.exr"
    args = ["render", str(path), "--width", "1000", "--height", "1000", "--out", str(out), "--quiet"]
    assert main(args + ["--max-memory", "0.01"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "0.0838 GiB" in err and "--max-memory budget of 0.01 GiB" in err, err
    assert "bands of at most 119 rows with --crop (e.g. --crop 0,0,1000,119)" in err, err
    assert not out.exists()
    assert main(args + ["--max-memory", "1", "--crop", "0,0,4,3"]) == 0 and out.exists()


@pytest.mark.parametrize("bad", [0.0, -1.0, float("inf"), float("nan"), True, "8G"])
def test_max_memory_must_be_a_positive_number_of_gib(bad):
    with pytest.raises(UserError, match="--max-memory .*: must be a positive number of GiB"):
        raytrace.render(box_room(), method="analytic", threads=1, max_memory=bad)
