"""What numba builds per compilation, cut without changing any kernel: `jit.Kernel` compiles a
function that only other compiled code calls without numba's Python wrapper (its callers link its own
code), and compiles it again with the wrapper when Python calls it; the compile flags' `values()`
(hashed and compared at every overload numba tries while typing) is the dict numba's own gives."""
import numpy as np
import pytest
from numba.core import compiler, targetconfig
from numba.core.registry import cpu_target

from raytrace import jit
from raytrace.jit import njit

pytestmark = pytest.mark.skipif(not jit.CUTS, reason="this numba's internals differ from 0.68's: plain numba.njit")


@njit(cache=False)
def _helper(x, k):
    return x * x + k


@njit(cache=False)
def _caller(a, k):
    out = np.empty_like(a)
    for i in range(a.size):
        out[i] = _helper(a[i], k)
    return out


@njit
def _cached_helper(x):
    return 2.0 * x + 1.0


@njit
def _cached_caller(x):
    return _cached_helper(x) - 1.0


def test_a_helper_compiled_for_a_kernel_has_no_python_wrapper_until_python_calls_it():
    a = np.linspace(-2.0, 2.0, 7)
    np.testing.assert_array_equal(_caller(a, 3), a * a + 3)
    (nested,) = _helper.overloads.values()
    assert not jit._has_python_wrapper(nested)  # built for the kernel only
    (kernel,) = _caller.overloads.values()
    assert jit._has_python_wrapper(kernel)
    assert _helper(1.5, 3) == 1.5 * 1.5 + 3  # a Python call: compiled again, with its wrapper
    (again,) = _helper.overloads.values()
    assert again is not nested and jit._has_python_wrapper(again)
    assert _helper(0.5, 3) == 3.25  # the wrapper now found by numba's own dispatch table
    np.testing.assert_array_equal(_caller(a, 3), a * a + 3)


def test_a_compilation_without_its_wrapper_is_not_written_to_the_disk_cache(monkeypatch):
    saved = []
    monkeypatch.setattr(type(_cached_helper._cache._cache), "save_overload",
                        lambda self, sig, cres: saved.append(self._py_func.__name__))
    monkeypatch.setattr(type(_cached_caller._cache._cache), "load_overload", lambda self, sig, ctx: None)
    assert _cached_caller(2.0) == 4.0
    assert saved == ["_cached_caller"]  # the helper's code lives in its caller's
    assert _cached_helper(2.0) == 5.0
    assert saved == ["_cached_caller", "_cached_helper"]


def test_the_flags_values_are_numbas():
    flags = compiler.Flags()
    cpu_target.options.parse_as_flags(flags, dict(nogil=True, fastmath=set(jit.FASTMATH), no_cfunc_wrapper=True))
    other = compiler.Flags(flags)
    other.no_cpython_wrapper = True
    for f in (compiler.Flags(), flags, other, compiler.DEFAULT_FLAGS):
        original = {k: getattr(f, k) for k in f.options}  # numba's own: a property call per option
        assert f.values() == original and list(f.values()) == list(original)
    assert flags != other and flags == compiler.Flags(flags) and hash(flags) == hash(other)
    assert targetconfig.TargetConfig.values is jit._config_values
