"""The Python API (raytrace/api.py) and the strict separation of method parameters from render
options (issue 8, defect 1: unread parameters were dropped silently)."""
import numpy as np
import pytest

import raytrace
from raytrace.cli import main
from raytrace.errors import UserError
from raytrace.methods import registry
from raytrace.options import RenderOptions
from raytrace.output.film import read_exr
from raytrace.rendering.renderer import prepare, render as render_prepared
from raytrace.scene.format import scene_from_text

from .conftest import box_room, to_toml


def test_render_from_a_dict_returns_the_renderers_image(tmp_path):
    scene = box_room()
    img = raytrace.render(scene, method="analytic", precision=1e-6, spp=4, threads=1, volumetric_shadows=False)
    assert img.array.shape == (6, 8, 3) and img.spp == 4 and img.method == "analytic"
    assert img.params["precision"] == 1e-6 and img.stats["evaluations"] > 0
    s = scene_from_text(to_toml(scene), "t")
    s.camera.spp = 4
    want = render_prepared(prepare(s), "analytic", {"precision": 1e-6}, RenderOptions(threads=1)).image
    np.testing.assert_array_equal(img.array, want)
    img.save(tmp_path / "a.exr")
    img.save(tmp_path / "a.png")
    back, header = read_exr(tmp_path / "a.exr")
    np.testing.assert_allclose(back, img.array, rtol=1e-7)
    assert header["method"] == "analytic" and "precision=1e-06" in header["params"]
    assert (tmp_path / "a.png").stat().st_size > 0
    with pytest.raises(raytrace.UserError, match=r"\.exr.*\.png"):
        img.save(tmp_path / "a.tiff")


def test_a_scene_file_a_bundled_name_and_the_default_scene(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(to_toml(box_room()))
    a = raytrace.render(str(path), method="quadrature", width=4, height=3)
    b = raytrace.render(box_room(), method="quadrature", width=4, height=3)
    np.testing.assert_array_equal(a.array, b.array)
    assert raytrace.load("box_room").name == "box_room"
    assert raytrace.load(None).name == "default"


def test_stochastic_methods_return_their_variance():
    img = raytrace.render(box_room(), method="montecarlo", samples=2, seed=5)
    assert img.variance.shape == img.array.shape and np.all(img.variance >= 0) and img.variance.max() > 0
    again = raytrace.render(box_room(), method="montecarlo", samples=2, seed=5, threads=1)
    np.testing.assert_array_equal(img.array, again.array)


@pytest.mark.parametrize("method, key, taker", [("analytic", "steps", "raymarch"), ("quadrature", "precision", "analytic"),
                                                 ("montecarlo", "rtol", "quadrature"), ("raymarch", "samples", "montecarlo")])
def test_a_parameter_the_method_does_not_read_is_refused(method, key, taker):
    value = {"steps": 128, "precision": 1e-6, "rtol": 1e-8, "samples": 8}[key]
    with pytest.raises(raytrace.UserError) as e:
        raytrace.render(box_room(), method=method, **{key: value})
    msg = str(e.value)
    assert f"method {method} does not read" in msg and f"--{key}" in msg and taker in msg and "\n" not in msg


def test_an_unknown_keyword_names_no_method():
    with pytest.raises(raytrace.UserError, match="no method takes it"):
        raytrace.render(box_room(), method="analytic", precisoin=1e-6)


def test_the_cli_refuses_unread_flags_and_notes_unread_scene_keys(tmp_path, capsys):
    path = tmp_path / "s.toml"
    out = tmp_path / "o.exr"
    path.write_text(to_toml(box_room()))
    assert main(["render", str(path), "--method", "analytic", "--steps", "128", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--steps" in err and "raymarch" in err and not out.exists()
    # a [render] key that the table's own method does not read is ignored with one warning
    path.write_text(to_toml(box_room(render={"method": "analytic", "steps": 32})))
    with pytest.warns(raytrace.api.SceneDefaultNote, match=r"\[render\] steps = 32: not read by method analytic"):
        assert main(["render", str(path), "--out", str(out), "--quiet"]) == 0
    assert "steps" not in read_exr(out)[1]["params"]
    # the same key is read when the scene's method takes it
    path.write_text(to_toml(box_room(render={"method": "raymarch", "steps": 32})))
    assert main(["render", str(path), "--out", str(out), "--quiet"]) == 0
    assert "steps=32" in read_exr(out)[1]["params"]


def test_render_options_are_not_method_parameters():
    for m in registry().values():
        assert not {"volumetric_shadows", "seed", "spp", "threads"} & set(m.params), m.name
    img = raytrace.render(box_room(render={"volumetric_shadows": True}), method="raymarch", steps=16)
    assert img.volumetric_shadows and "volumetric_shadows" not in img.params


def test_methods_lists_each_methods_own_parameters(capsys):
    assert main(["methods"]) == 0
    text = capsys.readouterr().out
    blocks = {}
    for line in text.splitlines():
        if not line.startswith(" ") and ":" in line and line.split(":")[0] in registry():
            name = line.split(":")[0]
            blocks[name] = []
        elif line.startswith("    --"):
            blocks[name].append(line.split()[0][2:].replace("-", "_"))
    assert set(blocks) == set(registry())
    for name, flags in blocks.items():
        assert flags == list(registry()[name].params), name


def test_methods_says_what_each_method_takes(capsys):
    """`render.py methods` gives each method's lights, media, phases and interiors, as rendering
    accepts or refuses them (a method refuses a light kind it does not list)."""
    assert main(["methods"]) == 0
    lines = capsys.readouterr().out.splitlines()
    for name, m in registry().items():
        takes = lines[lines.index(next(l for l in lines if l.startswith(f"{name}: "))) + 1].strip()
        lights, media, phases, shapes = takes.removeprefix("takes ").split("; ", 3)
        assert set(lights.removesuffix(" lights").split(", ")) == set(m.supports.lights), name
        assert media.removesuffix(" media").split(", ") == [k.type_name for k in m.supports.media], name
        assert len(phases.removesuffix(" phases").split(", ")) == len(m.supports.phases), name
        assert (shapes == "no media inside shapes") == (m.supports.interiors is None), name
    refused = box_room(light=[{"type": "spot", "position": [0.0, 1.0, 0.0], "look_at": [0.0, 0.0, 0.0],
                               "intensity": 1.0, "cone_angle": 30.0}])
    with pytest.raises(UserError, match="does not take spot lights"):
        raytrace.render(refused, method="lecocq", width=4, height=3)


def test_a_scene_dict_takes_numpy_vectors_and_scalars():
    """numpy arrays, numpy scalars and tuples read as the TOML lists and numbers they hold: the same
    image as the plain dict, bit for bit; a numpy vector of the wrong length is refused by key."""
    plain = {"camera": {"position": [0.0, 1.0, 4.0], "look_at": [0.0, 1.0, 0.0], "width": 16, "height": 12},
             "medium": {"sigma_s": 0.05},
             "light": [{"type": "point", "position": [0.0, 2.0, 0.0], "intensity": 5.0}],
             "shape": [{"primitive": "quad", "corners": [[-3, 0, -3], [3, 0, -3], [3, 0, 3], [-3, 0, 3]]}]}
    numpy = {"camera": {"position": np.array([0.0, 1.0, 4.0]), "look_at": (0.0, 1.0, 0.0), "width": np.int64(16),
                        "height": 12},
             "medium": {"sigma_s": np.float64(0.05)},
             "light": [{"type": "point", "position": np.array([0.0, 2.0, 0.0]), "intensity": np.float64(5.0)}],
             "shape": [{"primitive": "quad", "corners": np.array(plain["shape"][0]["corners"], float)}]}
    a, b = raytrace.render(plain), raytrace.render(numpy)
    assert a.array.max() > 0 and np.array_equal(a.array, b.array)
    with pytest.raises(raytrace.UserError, match=r"camera\.position: expected a vector"):
        raytrace.render({**numpy, "camera": {**numpy["camera"], "position": np.zeros(2)}})
