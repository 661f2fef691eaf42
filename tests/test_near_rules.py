"""What the renderer asks of an emitter, whatever its kind (raytrace/lights/near_rules.py): the answers of a
quad, a sphere and an emissive shape against independent computations, and no code outside raytrace/lights/
that asks which kind an emitter is (its `ball` or `planar`)."""
import re
from pathlib import Path

import numpy as np

from raytrace.lights import Lights, emissive, near_rules
from raytrace.lights.cubature import NEAR_FRACTION, PASSING
from raytrace.scene.format import scene_from_text

from .conftest import to_toml

ROOT = Path(__file__).resolve().parents[1]
CAMERA = {"position": [0.0, 1.0, 5.0], "look_at": [0.0, 1.0, 0.0], "width": 4, "height": 3}
QUAD = {"type": "quad", "corners": [[-0.5, 2.0, -0.5], [0.5, 2.0, -0.5], [0.5, 2.0, 0.5], [-0.5, 2.0, 0.5]],
        "radiance": 10.0}
SPHERE = {"type": "sphere", "center": [0.0, 1.0, 0.0], "radius": 0.5, "radiance": 10.0}
TRIANGLE = np.array([[[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])


def emitters():
    """The `area.Emitter`s of a quad and a sphere light and of an emissive triangle."""
    scene = scene_from_text(to_toml({"camera": CAMERA, "light": [QUAD, SPHERE]}), "lights.toml")
    return list(Lights.of(scene.lights).emitters) + [emissive.emitter(TRIANGLE, [1.0, 1.0, 1.0], False)]


def test_nothing_outside_lights_asks_an_emitters_kind():
    """No module of raytrace/ outside raytrace/lights/ reads an emitter's `ball` or `planar`: they ask
    near_rules (ARCHITECTURE.md: nothing outside raytrace/lights/ branches on a light's kind); importing the module
    lights/planar.py is not reading an attribute."""
    found = [f"{path.relative_to(ROOT)}:{i}" for path in sorted((ROOT / "raytrace").rglob("*.py"))
             if "lights" not in path.relative_to(ROOT / "raytrace").parts[:1]
             for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
             if re.search(r"(?<!lights)\.(ball|planar)\b", line)]
    assert not found, found


def test_what_each_kind_answers():
    """A quad: rows that decide, a rule about the foot point of the rays that cross its plane within
    NEAR_FRACTION of its diameter (the whole ladder), rays passing within PASSING of it, no sampler of its
    own for a stochastic method; a sphere: rows that decide nothing, a rule about every ray from outside
    it (its ladder from sphere_rule.FIRST), no passing rays, a stochastic method's own estimate bound
    to it; an emissive shape: its rows alone."""
    quad, ball, shape = emitters()
    diameter = np.sqrt(2.0)
    # rays straight up through the plane y = 2 at x = 0.5 + gap (the quad's edge at x = 0.5), and one
    # running away from the plane below it (its foot: the origin's projection, 1.9 under it)
    gaps = np.array([-0.3, 0.0, 0.1, 0.17, 0.18, 0.5])
    origins = np.concatenate([np.stack([0.5 + gaps, np.zeros_like(gaps), np.zeros_like(gaps)], axis=1),
                              [[0.0, 0.1, 0.0]]])
    dirs = np.concatenate([np.tile([0.0, 1.0, 0.0], (len(gaps), 1)), [[0.0, -1.0, 0.0]]])
    tmax = np.full(len(origins), np.inf)
    near = near_rules.near(quad, origins, dirs, tmax)
    expect = np.concatenate([np.maximum(gaps, 0.0) < NEAR_FRACTION * diameter, [False]])
    assert np.array_equal(near.rays, expect) and near.orders == near_rules.ORDERS
    assert near_rules.rows_decide(quad) and near_rules.replaces_rows(quad, False)
    assert not near_rules.replaces_rows(quad, True) and near_rules.own_estimate(quad, print) is None
    # the passing rays: distance to the quad's 17 x 17 probe points (its outline included), upward rays
    # through the plane: their distance is the gap itself
    assert np.array_equal(near_rules.passing(quad, origins, dirs)[:-1], np.maximum(gaps, 0.0) < PASSING * diameter)
    points, normals, weights, owner = near.rule((origins, dirs, tmax), np.array([1, 2]))(np.array([0, 1]), 4)
    assert np.allclose(np.bincount(owner, weights), 1.0) and np.allclose(normals, [0.0, -1.0, 0.0])

    inside = np.array([[0.0, 1.2, 0.0], [0.0, 1.0, 3.0], [2.0, 1.0, 0.0]])  # the first in the sphere
    near = near_rules.near(ball, inside, np.tile([1.0, 0.0, 0.0], (3, 1)), np.full(3, 4.0))
    assert np.array_equal(near.rays, [False, True, True]) and near.orders[0] == 4
    assert not near_rules.rows_decide(ball) and near_rules.replaces_rows(ball, True)
    assert not near_rules.passing(ball, inside, np.tile([1.0, 0.0, 0.0], (3, 1))).any()
    assert near_rules.own_estimate(ball, None) is None
    bound = near_rules.own_estimate(ball, lambda b, radiance, *rest: (b.radius, radiance.tolist(), rest))
    assert bound(7) == (0.5, [10.0, 10.0, 10.0], (7,))
    probes, outward = near_rules.seen_probes(ball, inside[1:], np.tile([0.0, 1.0, 0.0], (2, 1)))
    seen = np.isfinite(probes[..., 0])
    assert seen.any() and np.allclose(np.linalg.norm(outward[seen], axis=1), 0.5)

    assert near_rules.near(shape, origins, dirs, tmax) is None and near_rules.rows_decide(shape)
    assert not near_rules.replaces_rows(shape, False) and not near_rules.passing(shape, origins, dirs).any()
