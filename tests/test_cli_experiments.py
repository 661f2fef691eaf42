"""`compare` and `sweep` on the command line: `--volumetric-shadows` / `--no-volumetric-shadows` as
`render` takes them (the default stays the scene's `[render] volumetric_shadows`, else off), and
`sweep`'s PNG previews, plain CSV and per-point options."""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from PIL import Image

import raytrace
from raytrace.cli import main
from raytrace.output import film

from .conftest import PLATE, PLATE_LIGHT, box_room, to_toml


def _plate_scene(**render):
    """The box room with a plate just below its light: the plate's shadow is a cone of dark fog."""
    s = box_room(camera={"position": [0.0, 0.0, 3.5], "look_at": [0.0, 0.0, -1.0], "fov": 80.0, "width": 12,
                         "height": 9, "spp": 1},
                 light=[{"position": PLATE_LIGHT, "intensity": 20.0}])
    s["shape"].append(dict(PLATE))
    if render:
        s["render"] = render
    return s


@pytest.fixture
def write(tmp_path):
    def write(scene, name="s.toml"):
        path = tmp_path / name
        path.write_text(to_toml(scene))
        return str(path)
    return write


def _api(scene, shadows, method="analytic"):
    return raytrace.render(scene, method=method, volumetric_shadows=shadows, threads=1).array.astype(np.float32)


@pytest.mark.parametrize("command", ["compare", "sweep"])
def test_the_shadow_flags_of_compare_and_sweep(tmp_path, write, capsys, command):
    """Each flag gives the API's image with that setting, whatever the scene's key; without a flag
    the scene's key decides (absent: off)."""
    grid = ["--grid", "medium.sigma_s=0.15"] if command == "sweep" else []
    name = "p000_analytic.exr" if command == "sweep" else "analytic.exr"
    images = {}
    for key in (None, True, False):
        path = write(_plate_scene(**({} if key is None else {"volumetric_shadows": key})), f"s{key}.toml")
        for flag in (None, "--volumetric-shadows", "--no-volumetric-shadows"):
            out = tmp_path / f"{key}{flag}"
            args = [command, path, *grid, "--methods", "analytic", "--reference", "analytic", "--threads", "1",
                    "--out", str(out)]
            assert main(args + ([flag] if flag else [])) == 0
            images[key, flag] = film.read_exr(out / name)[0].astype(np.float32)
    capsys.readouterr()
    shadowed, plain = _api(_plate_scene(), True), _api(_plate_scene(), False)
    assert not np.allclose(shadowed, plain, rtol=1e-3)  # the plate's shadow shows
    for key in (None, True, False):
        np.testing.assert_array_equal(images[key, "--volumetric-shadows"], shadowed)
        np.testing.assert_array_equal(images[key, "--no-volumetric-shadows"], plain)
        np.testing.assert_array_equal(images[key, None], shadowed if key else plain)


def test_sweep_renders_each_point_with_its_own_options(tmp_path, write, capsys):
    """A grid over `render.volumetric_shadows`: each point is rendered with its own value."""
    out = tmp_path / "sw"
    assert main(["sweep", write(_plate_scene()), "--grid", "render.volumetric_shadows=true,false", "--methods",
                 "analytic", "--reference", "analytic", "--threads", "1", "--out", str(out)]) == 0
    capsys.readouterr()
    np.testing.assert_array_equal(film.read_exr(out / "p000_analytic.exr")[0].astype(np.float32),
                                  _api(_plate_scene(), True))
    np.testing.assert_array_equal(film.read_exr(out / "p001_analytic.exr")[0].astype(np.float32),
                                  _api(_plate_scene(), False))


@pytest.fixture(scope="module")
def swept(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sweep")
    path = folder / "box.toml"
    path.write_text(to_toml(box_room()))
    out = folder / "out"
    assert main(["sweep", str(path), "--grid", 'medium.phase="isotropic",{type="hg",g=0.5}', "--grid",
                 "medium.sigma_s=0.1,2e-1", "--grid", "render.volumetric_shadows=false", "--methods",
                 "raymarch:steps=8,montecarlo", "--threads", "1", "--exposure", "1.5", "--out", str(out)]) == 0
    return out


def test_sweep_writes_a_png_preview_beside_every_exr(swept):
    exrs = sorted(swept.glob("*.exr"))
    assert len(exrs) == 4 * 3 and sorted(swept.glob("*.png")) == [p.with_suffix(".png") for p in exrs]
    for exr in exrs:
        image, _ = film.read_exr(exr)
        with Image.open(exr.with_suffix(".png")) as png:
            assert png.mode == "RGB" and png.size == (image.shape[1], image.shape[0])
            preview = np.asarray(png).astype(int)
        # the preview of the float64 image, here from its float32 EXR: at most one level apart
        assert np.abs(preview - film.tonemap(image, 1.5).astype(int)).max() <= 1, exr


def test_sweep_csv_is_plain_and_json_has_the_parsed_values(swept):
    text = (swept / "sweep.csv").read_text()
    rows = list(csv.DictReader(text.splitlines()))
    assert len(rows) == 8 and '"""' not in text
    assert [r["medium.phase"] for r in rows[::4]] == ["isotropic", '{type="hg",g=0.5}']
    assert {r["medium.sigma_s"] for r in rows} == {"0.1", "0.2"} and {r["render.volumetric_shadows"] for r in rows} \
        == {"false"}
    for r in rows:
        for key in ("seconds", "compile_seconds", "mean_abs", "mean_rel", "max_rel", "rms"):
            mantissa = r[key].lower().split("e")[0].lstrip("-").replace(".", "").lstrip("0")
            assert float(r[key]) >= 0 and len(mantissa) <= 6, (key, r[key])  # 6 significant digits at most
    table = json.loads((swept / "sweep.json").read_text())["rows"]
    assert [r["medium.phase"] for r in table[::4]] == ["isotropic", {"type": "hg", "g": 0.5}]
    assert {r["medium.sigma_s"] for r in table} == {0.1, 0.2} and {r["render.volumetric_shadows"] for r in table} \
        == {False}
    for line, full in zip(rows, table):
        assert float(line["mean_rel"]) == pytest.approx(full["mean_rel"], rel=1e-5)
