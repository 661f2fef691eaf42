"""`render.py compare`: every method on the same samples, images, error maps and tables; the
behaviours the comparison is meant to show (issue: ray marching O(h^2), Lecocq wrong looking away
from the light, Monte Carlo converging as 1/sqrt(N))."""
import json

import pytest

from raytrace.cli import main
from raytrace.output.film import read_exr

from .conftest import box_room

SCENE = box_room(camera={"type": "environment", "position": [0.0, 0.0, 2.0], "look_at": [0.0, 0.0, -1.0],
                         "width": 24, "height": 12, "spp": 1},
                 medium={"sigma_a": 0.1, "sigma_s": 0.3, "phase": "isotropic"},
                 light=[{"position": [0.5, 0.5, -1.5], "intensity": 10.0}])


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    from .conftest import to_toml

    folder = tmp_path_factory.mktemp("cmp")
    path = folder / "box.toml"
    path.write_text(to_toml(SCENE))
    out = folder / "out"
    methods = ("raymarch:steps=512,raymarch:steps=1024,raymarch:steps=2048,lecocq,sun,analytic,"
               "montecarlo:samples=4,montecarlo:samples=64")
    assert main(["compare", str(path), "--methods", methods, "--out", str(out)]) == 0
    return out, {r["method"]: r for r in json.loads((out / "compare.json").read_text())["methods"]}


def test_writes_images_error_maps_and_tables(table):
    out, rows = table
    assert (out / "reference.exr").is_file() and (out / "compare.md").is_file()
    assert len(rows) == 8
    for label in rows:
        stem = label.replace(":", "_").replace("=", "_")
        for suffix in (".exr", ".png", "_error.png"):
            assert (out / f"{stem}{suffix}").is_file(), stem + suffix
    md = (out / "compare.md").read_text()
    assert all(label in md for label in rows)
    _, header = read_exr(out / "analytic.exr")
    assert header["method"] == "analytic"


def test_ray_marching_error_falls_four_times_per_halving(table):
    _, rows = table
    e = [rows[f"raymarch:steps={n}"]["mean_rel"] for n in (512, 1024, 2048)]
    assert 3.0 < e[0] / e[1] < 5.5 and 3.0 < e[1] / e[2] < 5.5, e


def test_lecocq_goes_wrong_and_analytic_does_not(table):
    _, rows = table
    assert rows["lecocq"]["negative_pixels"] > 0 or rows["lecocq"]["max_rel"] > 1.0
    assert rows["analytic"]["max_rel"] < 1e-2 and rows["analytic"]["negative_pixels"] == 0


def test_monte_carlo_converges_as_one_over_sqrt_n(table):
    _, rows = table
    ratio = rows["montecarlo:samples=4"]["mean_abs"] / rows["montecarlo:samples=64"]["mean_abs"]
    assert 2.5 < ratio < 6.0  # sqrt(16) = 4


def test_bad_method_spec_is_one_line(tmp_path, capsys):
    from .conftest import to_toml

    path = tmp_path / "s.toml"
    path.write_text(to_toml(SCENE))
    assert main(["compare", str(path), "--methods", "raymarch:stepz=3", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "stepz" in err[0] and "steps" in err[0]
