"""`jit.exact_njit` kernels compile without fast-math whoever compiles them first.

numba gives a function whose own flags leave `fastmath` unset the flags of the kernel that compiles
it (its caller), and keeps that one compilation for every later caller: an exact helper first
called from a `jit.njit` kernel would carry LLVM's fast-math flags (FMA contraction,
reassociation) into the exact kernels too. Here an exact dot product is compiled first from a
fastmath caller; its LLVM IR must hold no instruction with a fast-math flag and no fused
multiply-add, and its machine code no FMA instruction, while the fastmath caller's IR does hold
the flags (so the check can see them)."""
import re

import numpy as np

from raytrace.jit import exact_njit, njit

FLAGGED = re.compile(r"=\s*(fadd|fsub|fmul|fdiv|frem|fneg|fcmp|call)\s+(fast|nnan|ninf|nsz|arcp|contract|afn|reassoc)\b")
FUSED = re.compile(r"@llvm\.(fma|fmuladd)\.")
FMA_ASM = re.compile(r"\bv?fn?m(add|sub)\d{3}[sp]d\b")


@exact_njit(cache=False)
def _exact_dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=False)
def _fast_caller(a, b):
    return _exact_dot(a, b) * a[0] + b[1] * b[2]


def test_an_exact_kernel_compiled_from_a_fastmath_kernel_has_no_fastmath():
    a, b = np.array([1.0, 2.0, 3.0]), np.array([0.1, 0.2, 0.3])
    _fast_caller(a, b)  # compiles _exact_dot first, inside the fastmath kernel's compilation
    assert len(_exact_dot.signatures) == 1
    sig = _exact_dot.signatures[0]
    ir, asm = _exact_dot.inspect_llvm(sig), _exact_dot.inspect_asm(sig)
    assert "fmul" in ir and "fadd" in ir
    assert not FLAGGED.findall(ir), FLAGGED.findall(ir)[:5]
    assert not FUSED.search(ir)
    assert not FMA_ASM.search(asm)
    assert FLAGGED.search(_fast_caller.inspect_llvm(_fast_caller.signatures[0]))  # the check sees fast-math
    assert _exact_dot(a, b) == (1.0 * 0.1 + 2.0 * 0.2) + 3.0 * 0.3  # rounded as written
