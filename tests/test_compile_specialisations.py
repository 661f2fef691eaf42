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
