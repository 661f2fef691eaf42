"""The statistics of the integrals inside shapes (interiors/crossing.py) reach the render's, as quadrature's own
do outside.

Before the fix, `single_scattering` (now interiors/rows.py) filled its statistics and dropped them: a render with
media inside shapes never said that inside integrals had stopped short of their tolerance (the U
prism under a directional light, tests/test_inside_paths.py, had 15 such panels at the default
rtol: the kinks of its inside lengths where the light's paths pass the U's edges; since the traced
quadrature starts its panels at them (geometry/sections.py) they converge at once, and the traced path's
count is exercised with its panels not cut there and its halvings capped, paths.MAX_LEVELS = 2).
"""
import raytrace
from raytrace.interiors import paths
from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import load_scene, scene_from_text

from . import test_bounded_media as bounded_media, test_inside_paths as u_prism
from .conftest import to_toml

NOT_CONVERGED = "inside: integrals not converged"


def u_render(tmp_path, light, params, camera=None):
    (tmp_path / "u.obj").write_text(u_prism.u_obj())
    sc = u_prism.u_scene(light)
    sc["camera"].update(camera or {})
    (tmp_path / "u.toml").write_text(to_toml(sc))
    prep = prepare(load_scene(tmp_path / "u.toml"))
    return prep, render(prep, "quadrature", params, RenderOptions(threads=1))


def test_inside_integrals_that_stop_short_are_reported(tmp_path, monkeypatch):
    """The traced path (a non-convex shape, interiors/paths.py, its halvings capped), from outside and
    from a camera inside, and the convex kernel (media/slab.py) at the finest rtol: each counts what did
    not converge, and a lamp whose integrals all converge reports 0."""
    with monkeypatch.context() as m:
        m.setattr(paths, "MAX_LEVELS", 2)
        m.setattr(paths, "section_kinks", lambda *args: None)  # panels not cut at the kinks
        _, res = u_render(tmp_path, u_prism.SUN, {"rtol": 1e-10})
        assert res.stats[NOT_CONVERGED] > 0, res.stats
        assert (res.error_bound == float("inf")).any()  # an integral left open has no bound
        prep, res = u_render(tmp_path, u_prism.SUN, {"rtol": 1e-10},
                             dict(position=[-0.7, 0.1, 0.3], look_at=[1.0, -0.2, -0.2], fov=60.0, width=8, height=5))
        assert prep.camera_inside == 0 and res.stats[NOT_CONVERGED] > 0, res.stats
    _, res = u_render(tmp_path, u_prism.LAMP, {"rtol": 1e-10})
    assert res.stats[NOT_CONVERGED] == 0, res.stats
    sc = dict(bounded_media.SPOTS["spot_beside_cube"])
    sc.pop("any_face", None)
    prep = prepare(scene_from_text(to_toml(sc), "cube"))
    assert len(raytrace.interiors.shapes.convex_planes(prep, 0))  # the kernel's convex path
    res = render(prep, "quadrature", {"rtol": 1e-14}, RenderOptions(threads=1))
    assert res.stats[NOT_CONVERGED] > 0, res.stats
    assert NOT_CONVERGED not in render(prep, "raymarch", {"steps": 4}, RenderOptions(threads=1)).stats


def test_the_count_does_not_depend_on_the_tiles(tmp_path, monkeypatch):
    """The inside statistics travel with each tile's and are reduced like the method's own."""
    monkeypatch.setattr(paths, "MAX_LEVELS", 2)
    monkeypatch.setattr(paths, "section_kinks", lambda *args: None)
    (tmp_path / "u.obj").write_text(u_prism.u_obj())
    (tmp_path / "u.toml").write_text(to_toml(u_prism.u_scene(u_prism.SUN)))
    prep = prepare(load_scene(tmp_path / "u.toml"))
    whole = render(prep, "quadrature", {}, RenderOptions(threads=1)).stats[NOT_CONVERGED]
    parts = sum(render(prep, "quadrature", {}, RenderOptions(threads=2, crop=box)).stats[NOT_CONVERGED]
                for box in ((0, 0, 10, 3), (0, 3, 10, 7)))
    assert whole == parts > 0
