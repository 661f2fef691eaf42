"""Typed records and their compile-time dispatch: the one interface of the shared integrators
(adaptive.py's Gauss-Legendre driver, march.py's midpoint march, methods/montecarlo.py's sampler).

A record is a NamedTuple. `record_dispatch(stub, at)` makes numba dispatch the pure-Python function
`stub` on the class of its argument number `at` when it compiles a caller (an overload), and returns
the decorator that registers an njit implementation for one class. The integrators therefore import
none of the modules that define records, numba caches them (no first-class function arguments),
and a record class without an implementation is a compile-time error (a numba TypingError), never
a fall-through to another record's code. The overload's implementation is the registered function's
own Python code, compiled with `jit.njit`'s flags (which a registered function must have) once per
argument types, and a caller calls it directly: no forwarding function between them, which would be
compiled too and whose module would optimise the integrand once more (tests/test_compile_specialisations.py).
A dispatch made with inline=True compiles the code of the implementations registered with inline=True
into each caller's own (numba's inlining: the caller's hot loop then holds no call and takes no
reference to the record's arrays per call) and a call of the others' compiled functions there.

`integrand(x, rec)`: the value at x of the integrand a record names, registered with `integrand_of`.
"""
import inspect

from numba.core.errors import TypingError
from numba.extending import overload

from ..jit import OPTIONS


def record_dispatch(stub, at, inline=False):
    """Dispatch `stub` on the record class of its argument `at`; returns `register(cls, inline=False)`,
    the decorator that makes an njit function (with stub's arguments) the implementation for cls;
    with inline, those registered with inline=True are inlined into their callers (module docstring)."""
    impls, names = {}, ", ".join(inspect.signature(stub).parameters)

    @overload(stub, jit_options=OPTIONS, strict=False, inline="always" if inline else "never")
    def _dispatch(*args):
        impl, inlined = impls.get(getattr(args[at], "instance_class", None), (None, False))
        if impl is None:
            raise TypingError(f"{stub.__name__}: nothing is registered for {args[at]} (media/integrand.py)")
        if inlined or not inline:
            return impl.py_func
        scope = {"impl": impl}  # a call of the compiled implementation, inlined
        exec(f"def call({names}):\n    return impl({names})", scope)
        return scope["call"]

    def register(cls, inline=False):
        def decorate(fn):
            assert cls not in impls, f"{stub.__name__} is already registered for {cls.__name__}"
            assert all(fn.targetoptions.get(k) == v for k, v in OPTIONS.items()), f"{fn}: not jit.njit's flags"
            impls[cls] = fn, inline
            return fn
        return decorate
    return register


def integrand(x, rec):
    """The value at x of the integrand that the record `rec` names (`integrand_of`)."""


integrand_of = record_dispatch(integrand, 1)
