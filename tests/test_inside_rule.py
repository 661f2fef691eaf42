"""The inside rule a method hands the kernels of media inside shapes (raytrace/media/inside_rule.py): one record
type for every method (numba compiles each driver once), its values the method's own, and the capabilities that
are not a rule (closed forms, the entry plane's model) declared on `Interiors`, never read from a method's name."""
import re
from pathlib import Path

import numba
import numpy as np
import pytest

import raytrace
from raytrace.media.inside_rule import MARCH, QUAD, SAMPLE, UNDERFLOW, InsideRule, cut_length, inside_rule
from raytrace.methods import INSIDE_RTOL, registry

INSIDE = {name: m for name, m in registry().items() if m.supports.interiors is not None}


def defaults(method):
    return {k: p.default for k, p in method.params.items()}


def test_every_method_hands_one_record_type():
    """Each method's rule from its default parameters, and from others, is an `InsideRule` of one numba type."""
    types = set()
    for name, m in INSIDE.items():
        for params in (defaults(m), defaults(m) | {k: v for k, v in (("rtol", 1e-6), ("steps", np.int64(7)),
                                                                      ("samples", 3), ("tau_max", 20))
                                                  if k in m.params}):
            rule = m.supports.interiors.rule(params)
            assert type(rule) is InsideRule and rule.kind in (QUAD, MARCH, SAMPLE), name
            types.add(numba.typeof(rule))
    assert len(types) == 1, types


def test_rules_carry_the_methods_settings():
    """quadrature's rtol, raymarch's steps and tau_max, Monte Carlo's samples cut where exp underflows;
    analytic's and slab_approx's rule (where their closed forms have none) the adaptive quadrature."""
    rule = lambda name, **p: INSIDE[name].supports.interiors.rule(defaults(INSIDE[name]) | p)
    assert rule("quadrature", rtol=1e-7) == (QUAD, 1e-7, 1, UNDERFLOW)
    assert rule("raymarch", steps=33, tau_max=12.5) == (MARCH, INSIDE_RTOL, 33, 12.5)
    assert rule("montecarlo", samples=5) == (SAMPLE, INSIDE_RTOL, 5, UNDERFLOW)
    assert rule("analytic").kind == rule("slab_approx").kind == QUAD


def test_one_model_of_the_light_path_per_method():
    """exact paths (quadrature, raymarch, montecarlo), closed forms (analytic) or the entry plane (slab_approx):
    exactly one each, and a record declaring two is refused."""
    model = {name: [f for f in ("exact_paths", "closed_forms", "entry_plane") if getattr(m.supports.interiors, f)]
             for name, m in INSIDE.items()}
    assert model == {"quadrature": ["exact_paths"], "raymarch": ["exact_paths"], "montecarlo": ["exact_paths"],
                     "analytic": ["closed_forms"], "slab_approx": ["entry_plane"]}
    from dataclasses import replace
    with pytest.raises(AssertionError):
        replace(INSIDE["analytic"].supports.interiors, entry_plane=True)


@pytest.mark.parametrize("kind, tau_max, ell, kt, want", [
    (MARCH, 4.0, 10.0, 2.0, 2.0),  # cut at tau_max / kt
    (MARCH, 4.0, 1.0, 2.0, 1.0),  # the whole segment
    (SAMPLE, UNDERFLOW, 1e9, 1.0, UNDERFLOW),
    (SAMPLE, UNDERFLOW, 3.0, 0.5, 3.0),
])
def test_cut_length(kind, tau_max, ell, kt, want):
    assert cut_length(inside_rule(kind, 1e-10, 8, tau_max), ell, kt) == want


def test_no_rule_or_method_integers_outside_methods():
    """The interior modules read the rule's kind and the declared capabilities, never the retired integers."""
    root = Path(raytrace.__file__).parent
    interiors = sorted(str(p.relative_to(root)) for p in (root / "interiors").glob("*.py"))
    for rel in interiors + ["shadows/through_others.py", "media/slab.py", "media/sphere_refraction.py"]:
        text = (root / rel).read_text()
        assert not re.search(r"\b(CLOSED|APPROX)\b|(?<!\.)\bmode\s*[!=]=|interiors\.mode|\.settings\(", text), rel
