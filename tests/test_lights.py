"""The light kinds behind one interface (raytrace/lights/, ARCHITECTURE.md): the registry, what each
kind declares, the kernels' one entry to the kinds' samples, and a scene parser that names no kind."""
import math
import re
from pathlib import Path

import numpy as np
import pytest

from raytrace.cli import main
from raytrace.errors import UserError
from raytrace.lights import AREA, ENVIRONMENT, EXPANDED, KINDS, Light, Lights, describe, light_sample, point, spot
from raytrace.scene.format import (CAMERA_KEYS, CAMERA_TYPES, PRIMITIVE_KEYS, SHAPE_COMMON, TRANSFORM_KEYS, load_scene,
                                   scene_from_text)

from .conftest import to_toml

ROOT = Path(__file__).resolve().parents[1]
CAMERA = {"position": [0.0, 1.0, 5.0], "look_at": [0.0, 1.0, 0.0], "width": 4, "height": 3}
LIGHTS = [{"position": [1.0, 2.0, 3.0], "intensity": [1.0, 2.0, 3.0]},
          {"type": "spot", "position": [0.0, 3.0, 0.0], "direction": [0.0, -1.0, 0.0], "intensity": 5.0,
           "cone_angle": 30.0, "falloff_start": 10.0, "falloff": "mitsuba"},
          {"type": "directional", "direction": [0.6, -0.8, 0.0], "irradiance": 2.0}]


def test_every_kind_declares_the_interface():
    """lights/light.py's list: a name, a code, its keys, parse, describe and rows; the kinds that are
    their own rows irradiance and the numba sample, the area kinds their emitter's shape, the
    environment its radiance and importance sampling."""
    assert list(KINDS) == ["point", "spot", "directional", "quad", "disk", "sphere", "environment"]
    for name, kind in KINDS.items():
        assert kind.NAME == name and "type" in kind.KEYS
        hooks = (("shape",) if name in AREA else ("radiance", "pdf", "directions") if name == ENVIRONMENT
                 else ("irradiance", "sample"))
        assert all(callable(getattr(kind, hook)) for hook in ("parse", "describe", "rows") + hooks)
    assert len({kind.CODE for kind in KINDS.values()}) == len(KINDS)
    default = Light(np.zeros(3), np.ones(3))  # a light of no kind is a point light; a spot's default curve
    assert default.kind == point.CODE and default.curve == spot.CURVES["smoothstep"]


def test_an_unknown_kind_is_refused_naming_the_kinds():
    with pytest.raises(UserError) as err:
        scene_from_text(to_toml({"camera": CAMERA, "light": [{"type": "area", "position": [0.0, 0.0, 0.0]}]}), "bad.toml")
    assert str(err.value).startswith("bad.toml: light[0].type: 'area' is not one of point, spot, directional, quad, "
                                     "disk, sphere, environment; ")


def test_each_kind_parses_its_own_table():
    """The scene file's numbers, as each kind reads them: the spot's axis and cone from degrees."""
    scene = scene_from_text(to_toml({"camera": CAMERA, "light": LIGHTS}), "lights.toml")
    p, s, d = scene.lights
    assert (p.kind, s.kind, d.kind) == tuple(KINDS[k].CODE for k in ("point", "spot", "directional"))
    np.testing.assert_array_equal(p.intensity, [1.0, 2.0, 3.0])
    assert p.axis is None and (p.cos_end, p.cos_start) == (-3.0, -2.0)  # no cone
    np.testing.assert_array_equal(s.axis, [0.0, -1.0, 0.0])
    assert (s.cos_end, s.cos_start, s.curve) == (math.cos(math.radians(30.0)), math.cos(math.radians(10.0)),
                                                 spot.MITSUBA)
    np.testing.assert_array_equal(d.axis, [0.6, -0.8, 0.0])
    np.testing.assert_array_equal(d.intensity, [2.0, 2.0, 2.0])
    with pytest.raises(UserError, match=r"^lights.toml: light\[2\].cone_angle: unknown key; allowed keys: "
                                        r"direction, irradiance, type$"):
        scene_from_text(to_toml({"camera": CAMERA, "light": [LIGHTS[0], LIGHTS[1],
                                                              {**LIGHTS[2], "cone_angle": 3.0}]}), "lights.toml")


def test_describe_says_what_the_command_prints(tmp_path, capsys):
    """Each kind's `describe` against `render.py describe`'s lines, and against the numbers written."""
    path = tmp_path / "lights.toml"
    path.write_text(to_toml({"camera": CAMERA, "light": LIGHTS}))
    assert main(["describe", str(path)]) == 0
    printed = [line for line in capsys.readouterr().out.splitlines() if line.startswith("light[")]
    scene = load_scene(path)
    assert printed == [f"light[{i}]: {describe(light)}" for i, light in enumerate(scene.lights)]
    assert printed == ["light[0]: point at [1.0, 2.0, 3.0], intensity [1.0, 2.0, 3.0]",
                       "light[1]: spot at [0.0, 3.0, 0.0], intensity [5.0, 5.0, 5.0], axis [0.0, -1.0, 0.0], cone "
                       "30 deg, falloff from 10 deg",
                       "light[2]: directional, travelling along [0.6, -0.8, 0.0], irradiance [2.0, 2.0, 2.0]"]


def test_light_sample_is_each_kinds_sample():
    """The kernels' entry gives each kind's own sample; the point light's is one deterministic sample
    of weight 1 at the light's position (ux, uy, uz) dist = position - p; only the directional light's
    is distant (dist = inf, its direction against its travel)."""
    lights = Lights.of(scene_from_text(to_toml({"camera": CAMERA, "light": LIGHTS}), "lights.toml").lights)
    args = lights.position, lights.axis, lights.cone
    for p in np.random.default_rng(3).uniform(-2.0, 2.0, (100, 3)):
        for li, kind in enumerate(k for k in KINDS.values() if k.NAME not in EXPANDED):  # spot, directional rows
            got = light_sample(lights.kind, *args, li, *p)
            assert got == kind.sample(*args, li, *p)
            ux, uy, uz, dist, weight = got
            if kind is point:
                assert weight == 1.0
                np.testing.assert_allclose(np.array([ux, uy, uz]) * dist, lights.position[li] - p, rtol=0, atol=1e-14)
            assert (dist == math.inf) == (kind.NAME == "directional")
    assert light_sample(lights.kind, *args, 1, 0.0, 3.0, 0.0) == (0.0, 0.0, 0.0, 0.0, 0.0)  # at the spot itself


def test_the_scene_parser_names_no_light_kind():
    """scene/format.py asks the registry (ARCHITECTURE.md: "it names no medium kind itself"), so a new
    kind lands in raytrace/lights/ alone."""
    text = (ROOT / "raytrace" / "scene" / "format.py").read_text(encoding="utf-8")
    # the words other tables share with light kinds: primitives (quad, sphere, corners, ...), shapes' two_sided,
    # [background] radiance, a transform's scale and rotate, the environment camera
    shapes = set(PRIMITIVE_KEYS).union(*PRIMITIVE_KEYS.values(), SHAPE_COMMON, {"radiance"}, TRANSFORM_KEYS, CAMERA_TYPES)
    named = [name for name in set(KINDS) - shapes if re.search(rf'["\']{name}["\']', text)]
    named += [key for kind in KINDS.values() for key in kind.KEYS - CAMERA_KEYS - shapes
              if re.search(rf'["\']{key}["\']', text)]
    assert not named, f"scene/format.py names light kinds or their keys: {named}"
