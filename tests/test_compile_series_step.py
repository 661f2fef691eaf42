"""`expint.i01_series_lanes` calls its pass over the lanes (`_series_pass`, numba's inline="always") at one site,
two iterations a pass and one the last where max_iter is odd, so numba types the pass once and the lane's step
(`_series_iteration`) twice, not twice and four times as with a second call site for the odd iteration; the
results against the scalar loop at odd and even max_iter are tests/test_series_lanes.py's."""
import numpy as np
import pytest
from numba import types
from numba.core import inline_closurecall

from raytrace import jit
from raytrace.media import expint

pytestmark = pytest.mark.skipif(not jit.CUTS, reason="this numba's internals differ from 0.68's: plain numba.njit")

SIGNATURE = (types.float64[:, ::1], types.int64[::1], types.int64, types.int64, types.float64[:, ::1])


def test_the_lanes_step_is_typed_twice(monkeypatch):
    inlined = []
    inline_ir = inline_closurecall.InlineWorker.inline_ir

    def spy(self, caller_ir, block, i, callee_ir, *args, **kwargs):
        inlined.append(callee_ir.func_id.func_name)
        return inline_ir(self, caller_ir, block, i, callee_ir, *args, **kwargs)
    monkeypatch.setattr(inline_closurecall.InlineWorker, "inline_ir", spy)
    fresh = jit.exact_njit(cache=False)(expint.i01_series_lanes.py_func)  # (compiled here, not loaded)
    fresh.compile(SIGNATURE)
    assert inlined.count("_series_pass") == 1
    assert inlined.count("_series_iteration") == 2
    args = np.array([[-0.3, 0.5, 4.0, 1e-9], [-2.0, 1.0, np.inf, 1e-6]])
    for max_iter in (7, 8):  # odd (a last pass of one iteration) and even: the module's kernel's values
        out, ref = np.empty((2, 4)), np.empty((2, 4))
        fresh(args, np.arange(2), 3, max_iter, out)
        expint.i01_series_lanes(args, np.arange(2), 3, max_iter, ref)
        assert np.array_equal(out, ref)
