"""Shared helpers: writing scene dicts as TOML files, running the CLI in-process."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

# property tests draw the same examples on every run, so CI results are reproducible
settings.register_profile("reproducible", derandomize=True, deadline=None)
settings.load_profile("reproducible")

ROOT = Path(__file__).resolve().parents[1]
SHARED_SCENES = ROOT.parent / "shared" / "scenes"


def _value(v):
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, float):
        return repr(v) if np.isfinite(v) else ("nan" if np.isnan(v) else ("inf" if v > 0 else "-inf"))
    return str(v)


def to_toml(scene: dict) -> str:
    """Serialise a scene dict: plain tables, arrays of tables ([[shape]], [[light]]), inline phase tables."""
    lines = []
    for k, v in scene.items():
        if not isinstance(v, (dict, list)) or (isinstance(v, list) and v and not isinstance(v[0], dict)):
            lines.append(f"{k} = {_value(v)}")
    for k, v in scene.items():
        if isinstance(v, dict):
            lines.append(f"\n[{k}]")
            lines += [f"{a} = {_value(b)}" for a, b in v.items()]
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            for item in v:
                lines.append(f"\n[[{k}]]")
                lines += [f"{a} = {_value(b)}" for a, b in item.items()]
    return "\n".join(lines) + "\n"


@pytest.fixture
def write_scene(tmp_path):
    def write(scene: dict, name: str = "scene.toml") -> Path:
        p = tmp_path / name
        p.write_text(to_toml(scene))
        return p
    return write


def box_room(**over) -> dict:
    """A 6 x 4 x 8 box room, camera inside looking down -z, one light: the base of many tests."""
    scene = {
        "camera": {"type": "perspective", "position": [0.3, 0.2, 3.0], "look_at": [0.0, 0.0, -1.0],
                   "fov": 70.0, "width": 8, "height": 6, "spp": 1},
        "shape": [{"primitive": "box", "min": [-3.0, -2.0, -4.0], "max": [3.0, 2.0, 4.0],
                   "reflectance": [0.6, 0.5, 0.4]}],
        "light": [{"position": [0.5, 1.0, -1.0], "intensity": [10.0, 8.0, 6.0]}],
        "medium": {"sigma_a": 0.05, "sigma_s": 0.15, "phase": "isotropic"},
    }
    for k, v in over.items():
        scene[k] = v
    return scene


PLATE_LIGHT = [0.0, 1.5, -1.0]
PLATE = {"primitive": "quad", "corners": [[-1.0, 1.2, -2.0], [1.0, 1.2, -2.0], [1.0, 1.2, 0.0], [-1.0, 1.2, 0.0]],
         "reflectance": 0.0}


def plate_room(phase, plate=True, width=16, height=12):
    """A prepared box room with black walls (the image is the air-light) and, if `plate`, a black
    plate just below its one light."""
    import raytrace
    from raytrace.rendering.renderer import prepare

    s = box_room(camera={"position": [0.0, 0.0, 3.5], "look_at": [0.0, 0.0, -1.0], "fov": 80.0, "width": width,
                         "height": height, "spp": 1},
                 medium={"sigma_a": 0.05, "sigma_s": [0.2, 0.3, 0.5], "phase": phase},
                 light=[{"position": PLATE_LIGHT, "intensity": 20.0}])
    s["shape"][0]["reflectance"] = 0.0
    if plate:
        s["shape"].append(dict(PLATE))
    return prepare(raytrace.load(s))
