"""The statistics of the air-light of lights inside refractive shapes (interiors/held.py `held_airlight`) reach the
render's: the exact sphere's kernel counts the fog segments on which it found a number of paths out other than one
(media/sphere_refraction.py `out_of_sphere`, stats[UNBOUNDED]; tests/test_globe_fog.py checks the count itself), and
quadrature's summary shows them."""
from raytrace.interiors import held, support
from raytrace.options import RenderOptions
from raytrace.rendering import renderer
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text

from .conftest import to_toml
from .test_globe_fog import FOG
from .test_lamp_in_globe import NEAR, scene


def test_the_globes_unbounded_fog_segments_are_counted(monkeypatch):
    """A lamp at 0.95 radius in the globe (beyond radius / ior, where some fog points have other than one path out:
    refused by `check`, taken here with that refusal switched off), the camera looking past the globe (no inside
    row counts anything): the render's count of unbounded segments is the kernel's own, summed over its calls (the
    warm-up's rays, whose statistics are not the render's, left out), and not zero."""
    monkeypatch.setattr(support, "_globe_fog", lambda prep, sid, li: None)
    monkeypatch.setattr(renderer, "warm_up", lambda *args, **kw: 0.0)
    original, counted = held.out_of_sphere, []

    def counting(*args):  # the kernel, its count of this call noted (its argument `stats`, after out, var, err)
        stats = args[16]
        before = stats[support.SPHERE_UNBOUNDED]
        original(*args)
        counted.append(stats[support.SPHERE_UNBOUNDED] - before)

    monkeypatch.setattr(held, "out_of_sphere", counting)
    sc = scene(NEAR, FOG)
    sc["camera"] = dict(sc["camera"], look_at=[3.0, -1.0, 1.5], width=4, height=3)
    res = render(prepare(scene_from_text(to_toml(sc), "globe")), "quadrature", {"rtol": 1e-4},
                 RenderOptions(threads=1, volumetric_shadows=False))
    assert sum(counted) > 0, counted
    assert res.stats["inside: refracted sphere segments unbounded"] == sum(counted)
