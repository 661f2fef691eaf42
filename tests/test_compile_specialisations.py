"""What keeps the first render's compile short: `jit.exact_jitable` helpers compile once whatever
constants their callers pass, and stay exact inside fastmath callers; a record's integrand
(media/integrand.py) is compiled once, called by its caller without a forwarding function."""
import re
from typing import NamedTuple

import numpy as np
import pytest
from numba.core import event

from raytrace.jit import exact_jitable, njit
from raytrace.media.integrand import integrand, integrand_of
from raytrace.media.phase import HG
from raytrace.methods import analytic

FLAGGED = re.compile(r"=\s*(fadd|fsub|fmul|fdiv|frem|fneg|fcmp)\s+(fast|nnan|ninf|nsz|arcp|contract|afn|reassoc)\b")
FUSED = re.compile(r"@llvm\.(fma|fmuladd)\.")


@exact_jitable
def _row_dot(a, i, b, j):
    return (a[i, 0] * b[j, 0] + a[i, 2] * b[j, 2]) + a[i, 1] * b[j, 1]


@njit(cache=False)
def _fast_caller(e):
    return _row_dot(e, 0, e, 1) * _row_dot(e, 2, e, 0) + _row_dot(e, 1, e, 1)


class _Count(event.Listener):
    def __init__(self, name="_row_dot"):
        self.name, self.args, self.names = name, [], []

    def on_start(self, ev):
        self.names.append(ev.data["dispatcher"].py_func.__qualname__)
        if ev.data["dispatcher"].py_func.__name__ == self.name:
            self.args.append(ev.data["args"])

    def on_end(self, ev):
        pass


def test_an_exact_jitable_helper_compiles_once_and_without_fastmath():
    e = np.arange(9.0).reshape(3, 3) / 7.0
    count = _Count()
    with event.install_listener("numba:compile", count):
        got = _fast_caller(e)
    assert len(count.args) == 1 and "Literal" not in str(count.args[0])  # not once per constant row
    ir = _fast_caller.inspect_llvm(_fast_caller.signatures[0])
    ops = re.findall(r"=\s*(fmul|fadd)\s+(\w+)", ir)
    plain = [op for op, flag in ops if flag == "double"]
    assert plain.count("fmul") == 9 and plain.count("fadd") == 6  # the helper's, inlined, without flags
    assert len(FLAGGED.findall(ir)) == 2 and not FUSED.search(ir)  # the caller's own two operations
    rows = [(e[i, 0] * e[j, 0] + e[i, 2] * e[j, 2]) + e[i, 1] * e[j, 1] for i, j in ((0, 1), (2, 0), (1, 1))]
    assert abs(got - (rows[0] * rows[1] + rows[2])) <= 1e-12 * abs(got)


class _Cubic(NamedTuple):
    a: float
    b: float


@integrand_of(_Cubic)
@njit(cache=False)
def _cubic(x, r):
    return r.a * x * x * x + r.b


@njit(cache=False)
def _two_calls(x, r):
    return integrand(x, r) + integrand(2.0 * x, r)


def test_a_records_integrand_compiles_once_and_is_called_directly():
    count = _Count("_cubic")
    with event.install_listener("numba:compile", count):
        got = _two_calls(0.5, _Cubic(3.0, 0.25))
    assert got == (3.0 * 0.125 + 0.25) + (3.0 + 0.25)
    assert len(count.args) == 1  # two call sites, one compilation
    assert count.names == ["_two_calls", "_cubic"]  # no forwarding function between them
    with pytest.raises(AssertionError, match="flags"):  # an implementation must have jit.njit's flags
        class _Other(NamedTuple):
            a: float
        integrand_of(_Other)(njit(fastmath=False)(lambda x, r: r.a))


def _soup(rng, n=300):
    return rng.uniform(-3, 3, (n, 1, 3)) + rng.normal(size=(n, 3, 3)) * 0.4


def test_the_suns_shadow_kernels_without_the_cube_maps_code_give_the_same_pieces():
    """shadows/frusta.py `_kernels`: the variant for a scene whose lights are all suns (SUNS: the cube
    map's code pruned) gives the same texel lists and lit pieces, bit for bit, as the variant with both
    kinds' code (BOTH, `sun` true at run time), on a random triangle soup under a sun, for segments from
    random points in random directions (some unbounded); and it calls none of the cube map's helpers,
    as the point lights' variant calls none of the ortho grid's."""
    from raytrace.methods import Segments
    from raytrace.shadows import frusta

    rng = np.random.default_rng(5)
    tris = _soup(rng)
    sun = frusta.sun_bins(tris, np.array([0.3, -1.0, 0.2]), 1e-6, 10.0, 16)  # a scene of suns only
    both = frusta.sun_bins(tris, np.array([0.3, -1.0, 0.2]), 1e-6, 10.0, 16, points=True)
    assert (sun.kinds, both.kinds) == (frusta.SUNS, frusta.BOTH)
    for name in ("planes", "signs", "start", "tri", "lb", "cover", "cover_depth", "grid", "frame"):
        assert np.array_equal(getattr(sun, name), getattr(both, name)), name
    n = 2000
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    length = rng.uniform(0.0, 8.0, n)
    length[::7] = np.inf
    zeros = np.zeros(n, np.int64)
    segs = Segments(rng.uniform(-5, 5, (n, 3)), dirs, length, zeros, np.arange(n), np.zeros(n), zeros, zeros)
    stats_sun, stats_both = np.zeros(len(frusta.STATS_NAMES)), np.zeros(len(frusta.STATS_NAMES))
    got_sun = frusta.lit_pieces(segs, [sun], 10.0, stats_sun)
    got_both = frusta.lit_pieces(segs, [both], 10.0, stats_both)
    assert 0 < stats_sun[frusta.ST_FRUSTA] and 0 < stats_sun[frusta.ST_DARK]  # shadows were found
    assert len(got_sun[0]) > n // 2
    for x, y in zip(got_sun, got_both):
        assert np.array_equal(x, y)
    assert np.array_equal(stats_sun, stats_both)
    # the helpers each variant's module calls (its LLVM IR names them): recompiled here without the cache
    from raytrace.jit import OPTIONS
    import numba

    def called(kinds, which, *args):
        fresh = numba.njit(**OPTIONS)(frusta._kernels(kinds)[which].py_func)
        fresh(*args)
        names = r"frusta\d+_?(ortho_part|cube_parts|face_bbox|point_triangle_distance)"
        return set(re.findall(names, fresh.inspect_llvm(fresh.signatures[0])))

    frame = np.array([[0.3, 0.2, 0.1], [1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]])
    point = frusta._light_bins(tris, frame, False, 16, 1e-6, frusta.REL * 10, suns=False)

    def lit_args(b):
        return (segs.origins[:50], segs.dirs[:50], segs.length[:50], b.grid, b.frame, b.start, b.tri, b.lb, b.cover,
                b.cover_depth, b.planes, b.signs, b.slack, 1e-12, np.zeros(len(frusta.STATS_NAMES)))
    assert called(frusta.SUNS, 2, *lit_args(sun), True) == {"ortho_part"}
    assert called(frusta.POINTS, 2, *lit_args(point), False) == {"cube_parts"}
    keep = np.zeros(len(tris), bool)
    frusta_args = (tris, np.zeros(3), sun.frame[3], 1e-6, np.zeros((len(tris), 4, 4)), np.zeros((len(tris), 4)),
                   np.zeros(len(tris)), keep)
    assert called(frusta.SUNS, 0, *frusta_args, True) == set()
    assert called(frusta.POINTS, 0, *frusta_args, False) == {"point_triangle_distance"}


@pytest.mark.parametrize("which", ["atmosphere", pytest.param("fog", marks=pytest.mark.slow)])
def test_quadratures_kernels_without_the_lights_a_scene_lacks_give_the_same_image(which, monkeypatch):
    """methods/quadrature.py `_kinds`: a scene with no point or spot light (the atmosphere under the
    sun) or no spot light (height fog under a sun and a lamp) compiles its kernels without their code
    (None arguments, pruned before typing) and renders the same image, bit for bit, as the kernels
    with every kind's code. The fog's case is slow (two compilations of the fog's chain, ~40 s):
    `pytest -m slow tests/test_compile_specialisations.py`."""
    import raytrace
    from raytrace.api import load
    from raytrace.lights import Lights
    from raytrace.methods import quadrature

    if which == "atmosphere":
        from .test_atmosphere import SPACE as scene
        assert quadrature._kinds(Lights.of(load(scene).lights)) == (None, None)
    else:
        from .test_height_fog import VALLEY as scene
        assert quadrature._kinds(Lights.of(load(scene).lights)) == (True, None)
    pruned = raytrace.render(scene, method="quadrature", threads=1).array
    monkeypatch.setattr(quadrature, "_kinds", lambda lights: (True, True))
    full = raytrace.render(scene, method="quadrature", threads=1).array
    assert np.array_equal(pruned, full)


@njit(cache=False)
def _taylor_piece(coeffs, taylor_mode):
    """analytic's `_piece` (inlined) of a piece in the Taylor mode of an HG medium: (S, ok)."""
    res = analytic._piece(0.5, 0.1, 1.0, 0.2, 0.8, 1.0, 2.0, HG, 0.5, analytic.ANISO_TAYLOR, 6, coeffs, 1e-3, 1000,
                          True, False, taylor_mode)
    return res[0], res[1]


def test_analytic_compiles_the_taylor_mode_only_in_that_mode():
    """methods/analytic.py `_piece`: with `taylor_mode` None (the exact mode's kernels, a spot's pieces) the Taylor
    mode's series is not compiled (no `_taylor_poly_part` in the kernel's code), and such a piece is not ok (the
    quadrature takes it); with it, the PP-19 sum is compiled and taken."""
    coeffs = analytic.make_coeffs(HG, 0.5, analytic.ANISO_TAYLOR, 6, 1e-3)
    assert _taylor_piece(coeffs, None) == (0.0, False)
    value, ok = _taylor_piece(coeffs, True)
    assert ok and np.isfinite(value) and value != 0.0
    pruned, full = (_taylor_piece.inspect_llvm(sig) for sig in _taylor_piece.signatures)
    assert "_taylor_poly_part" not in pruned and "_taylor_poly_part" in full
