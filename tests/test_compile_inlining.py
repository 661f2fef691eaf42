"""numba's inliner (`inline="always"`) copies the callee's IR with one deepcopy memo for all its blocks
(`jit._inline_ir`): the blocks share one copy of the callee's scope, where numba's own copy gives every block
a copy of its own (each copying all the function's variables), and the code compiled is the same."""
import re

import pytest
from numba.core import inline_closurecall

from raytrace import jit
from raytrace.jit import njit

pytestmark = pytest.mark.skipif(not jit.CUTS, reason="this numba's internals differ from 0.68's: plain numba.njit")


def _branchy(x, n):
    """Several blocks and variables: a loop and branches."""
    acc = 0.0
    for k in range(n):
        if x > k:
            acc += x - k
        elif x < -k:
            acc -= x + k
        else:
            acc += 0.5 * k
    return acc


def _outer(x, n):
    return _inlined(x, n) + 1.0


_inlined = njit(cache=False, inline="always")(_branchy)


def _reference(x, n):
    return _branchy(x, n) + 1.0


def _scopes(monkeypatch):
    """(blocks, distinct scope objects) of every inlining while the test runs (numba asks for the callee's
    scopes once per inlining, after copying its blocks)."""
    seen = []
    get_all = inline_closurecall._get_all_scopes

    def spy(blocks):
        seen.append((len(blocks), len({id(b.scope) for b in blocks.values()})))
        return get_all(blocks)
    monkeypatch.setattr(inline_closurecall, "_get_all_scopes", spy)
    return seen


def _llvm(kernel) -> str:
    """The kernel's LLVM IR without what names one compilation (mangled names, block labels, the inlined
    variables' unique ids)."""
    (cres,) = kernel.overloads.values()
    return re.sub(r"0x[0-9a-f]+|_ZN\w+|\bB\d+\b|_v\d+_", "", cres.library.get_llvm_str())


def test_the_inlined_blocks_share_one_copy_of_the_scope(monkeypatch):
    seen = _scopes(monkeypatch)
    kernel = njit(cache=False)(_outer)
    for x in (-3.5, -0.25, 0.0, 2.0, 7.75):
        assert kernel(x, 5) == _reference(x, 5)
    assert seen and all(blocks > 3 and scopes == 1 for blocks, scopes in seen)


def test_the_code_is_numbas_own(monkeypatch):
    cut = njit(cache=False)(_outer)
    cut(1.0, 3)
    seen = _scopes(monkeypatch)
    monkeypatch.setattr(inline_closurecall, "copy", jit.copy)  # numba's own copy, block by block
    plain = njit(cache=False)(_outer)
    plain(1.0, 3)
    assert seen and all(blocks > 3 and scopes == blocks for blocks, scopes in seen)  # (a copy per block)
    assert _llvm(plain) == _llvm(cut)
