"""What each method supports (`Supports`, raytrace/methods/__init__.py): the refusals it drives name
the methods that take what one lacks, and nothing outside raytrace/methods/ names a method to branch.
"""
import re
from pathlib import Path

import pytest

import raytrace
from raytrace.errors import UserError
from raytrace.methods import Method, Param, Supports, get_method, registry
from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text

from . import test_bounded_media as bounded_media
from .conftest import to_toml


def test_every_method_declares_what_it_supports():
    methods = registry()
    assert all(isinstance(m.supports, Supports) for m in methods.values())
    inside = {name for name, m in methods.items() if m.supports.interiors is not None}
    assert inside == {"analytic", "quadrature", "raymarch", "montecarlo", "slab_approx"}
    assert {name for name in inside if methods[name].supports.interiors.exact_paths} == {"quadrature", "raymarch",
                                                                                          "montecarlo"}
    # the seed's separable approximation: its own method, analytic outside
    slab, analytic = get_method("slab_approx"), get_method("analytic")
    assert slab.supports.interiors.entry_plane and analytic.supports.interiors.closed_forms
    assert slab.params is analytic.params and slab.airlight is analytic.airlight
    assert slab.supports.lights == analytic.supports.lights and slab.supports.media == analytic.supports.media


def test_a_shadow_test_declared_is_one_the_method_has():
    """`samples` (a shadow ray per medium point) needs the method's `points` and its shadow_test choice."""
    base = get_method("quadrature")
    with pytest.raises(AssertionError):
        Method("x", "", base.params, base.airlight, base.error_law,
               supports=Supports(shadow_tests=("intervals", "samples")))
    with pytest.raises(AssertionError):
        Method("x", "", {"shadow_test": Param("intervals", str, "", choices=("intervals", "samples"))},
               base.airlight, base.error_law, points=lambda *a: None)


def refusal(scene_dict, method, params=None):
    with pytest.raises(UserError) as err:
        render(prepare(scene_from_text(to_toml(scene_dict), "bad.toml")), method, params or {},
               RenderOptions(threads=1))
    msg = str(err.value)
    assert "\n" not in msg
    return msg


def test_refusals_name_the_methods_that_take_it():
    lamp = bounded_media.scene(bounded_media.LAMP)
    assert refusal(lamp, "lecocq").endswith("use --method analytic, quadrature, raymarch, montecarlo, slab_approx")
    assert "point lights into a bounded medium (shape[0].interior): no closed form" in refusal(lamp, "analytic")
    assert refusal(lamp, "analytic").endswith("use --method quadrature, raymarch, montecarlo, slab_approx")
    spot = bounded_media.SPOTS["spot_index_matched"]
    assert refusal(spot, "slab_approx").endswith("not spot lights; use --method quadrature, raymarch, montecarlo")
    refracted = refusal(bounded_media.scene(bounded_media.LAMP, ior=1.5), "slab_approx")
    assert refracted.startswith("render: shape[0].interior.ior: --method slab_approx: point lights through a "
                                "refractive boundary") and refracted.endswith("use ior = 1, or --method quadrature, "
                                                                              "raymarch, montecarlo")
    assert "--step (render.step): not implemented inside bounded media" in refusal(lamp, "raymarch", {"step": 0.1})
    assert "--jitter (render.jitter)" in refusal(lamp, "raymarch", {"jitter": True})
    inside = bounded_media.scene(bounded_media.SUN, ior=1.0)
    inside["camera"]["position"] = [0.0, -0.5, 2.0]
    assert "--method analytic, quadrature, raymarch, montecarlo;" in refusal(inside, "slab_approx")


def test_a_phase_function_a_method_lacks_is_refused():
    sc = bounded_media.scene(bounded_media.LAMP)
    sc.pop("shape")
    sc["medium"] = {"sigma_a": 0.1, "sigma_s": 0.2, "phase": {"type": "hg", "g": 0.5}}
    msg = refusal(sc, "sun")
    assert msg.startswith('render: --method sun: it does not take hg phase functions (medium.phase = "hg"); use '
                          "--method analytic, quadrature, raymarch, lecocq, montecarlo, slab_approx"), msg


def test_nothing_outside_the_methods_branches_on_which_method_runs():
    """No comparison of a name with a registered method's name, and no table keyed by them, outside
    raytrace/methods/ (ARCHITECTURE.md: the core asks a method's `Supports`)."""
    names = "|".join(registry())
    compare = re.compile(rf"""name\s*(==|!=)\s*["']({names})["']|["']({names})["']\s*(==|!=)|\.name\s+(not\s+)?in\b""")
    keyed = re.compile(rf"""\{{\s*["']({names})["']\s*:""")
    root = Path(raytrace.__file__).parent
    found = [f"{p.relative_to(root)}:{i}: {line.strip()}" for p in sorted(root.rglob("*.py"))
             if "methods" not in p.relative_to(root).parts[:1]
             for i, line in enumerate(p.read_text().splitlines(), 1)
             if compare.search(line) or (keyed.search(line) and "experiments" not in p.parts)]
    assert not found, found
