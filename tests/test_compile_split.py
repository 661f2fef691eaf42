"""The air-light's compile split between the render's process and the compile worker (rendering/compile_ahead.py):
analytic's moment recurrences (`_pending_recurrences`) compiled in the render's process by signature before the
worker's gate (`compile_here`), in the types the air-light calls them with, so that neither the first call
compiles them nor the worker (`ahead`: its air-light without them); the values those of the recurrences run
inside the segments' kernel."""
import math

import numba
import numpy as np
import pytest

from raytrace import jit
from raytrace.lights import SPOT, Light, Lights
from raytrace.media.homogeneous import Homogeneous
from raytrace.media.phase import HG, ISOTROPIC
from raytrace.methods import analytic as A
from raytrace.methods import get_method, resolve_params
from raytrace.methods.geometry import POINT_ROW
from raytrace.rendering import compile_ahead

pytestmark = pytest.mark.skipif(not jit.CUTS, reason="this numba's internals differ from 0.68's: plain numba.njit")


def _medium(phase, g):
    return Homogeneous(np.full(3, 0.05), np.full(3, 0.3), phase, g)


def _lights():
    return Lights.of([Light(np.array([0.0, 1.0, 0.0]), np.ones(3))])


def _params(**given):
    return resolve_params(get_method("analytic"), given, "test")


def _calls(monkeypatch) -> list:
    """The numba types of every call of `_pending_recurrences` from Python while the test runs."""
    seen, kernel = [], A._pending_recurrences

    def spy(*args):
        seen.append(tuple(numba.typeof(a) for a in args))
        return kernel(*args)
    monkeypatch.setattr(A, "_pending_recurrences", spy)
    return seen


def _segments(n=24, seed=5):
    """Segments of rays past a point light in HG 0.9 (the series path: loops and recurrences pending)."""
    rng = np.random.default_rng(seed)
    xh, h = rng.uniform(-2.0, 6.0, n), 10.0 ** rng.uniform(-1.5, 0.5, n)
    ell = rng.uniform(0.5, 8.0, n)
    ell[::5] = math.inf
    return xh, h, np.hypot(xh, h), ell


def _deferred(recurrences=True, precision=1e-6):
    wp = A.working_precision(precision)
    coeffs = A.make_coeffs(HG, 0.9, A.ANISO_EXACT, 6, wp)
    segs = _segments()
    out, met, stats = np.full(len(segs[0]), -1.0), np.empty(len(segs[0]), dtype=np.bool_), A.new_stats()
    A.evaluate_deferred(*segs, 0.35, 0.3, HG, 0.9, wp, 1000, A.ANISO_EXACT, 6, coeffs,
                        np.tile(np.array(POINT_ROW), (len(segs[0]), 1)), out, met, stats, recurrences=recurrences)
    return out, met, stats


def test_the_render_process_compiles_the_recurrences_by_signature_in_the_types_they_are_called_with(monkeypatch):
    medium, lights, params = _medium(HG, 0.9), _lights(), _params()
    assert A.uses_recurrences(medium, lights, params)
    compile_ahead.compile_here(get_method("analytic"), medium, lights, params)
    assert A.RECURRENCES in A._pending_recurrences.overloads  # compiled here, by its signature
    seen = _calls(monkeypatch)
    out, met, _ = _deferred()
    assert seen and set(seen) == {A.RECURRENCES}  # every call takes that specialisation: none compiled on call
    assert met.all() and np.all(out > 0.0)


def test_the_workers_airlight_leaves_the_recurrences_out(monkeypatch):
    analytic = get_method("analytic")
    worker = compile_ahead.ahead(analytic)
    assert worker.airlight.func is analytic.airlight and worker.airlight.keywords == {"recurrences": False}
    seen = _calls(monkeypatch)
    _deferred(recurrences=False)
    assert seen == []
    quadrature = get_method("quadrature")  # a method that leaves nothing to the render's process
    assert compile_ahead.ahead(quadrature) is quadrature


def test_no_recurrences_where_no_point_light_or_an_isotropic_medium():
    hg, point, params = _medium(HG, 0.5), _lights(), _params()
    assert A.uses_recurrences(hg, point, params) and not A.uses_recurrences(_medium(ISOTROPIC, 0.0), point, params)
    assert not A.uses_recurrences(hg, point, _params(anisotropic="taylor"))
    spot = Lights.of([Light(np.array([0.0, 3.0, 0.0]), np.ones(3), SPOT, np.array([0.0, -1.0, 0.0]), 0.8, 0.9)])
    assert not A.uses_recurrences(hg, spot, params)
