"""The one numba flag set of the project, and its source-keyed kernel cache.

Every kernel is compiled with ``njit`` from here: cached, GIL-free (so a thread pool over tiles
uses every core) and with a fastmath subset that keeps NaN/Inf semantics (no ``nnan``/``ninf``,
numba issues #2919 and #9383) and keeps libm accuracy (no ``afn``). The cache of the package's
kernels lives in `cache.kernel_cache_dir()`, keyed on all of the package's sources (a locator
placed first in numba's list); numba's own locators serve everything else. ``hold`` and ``release``
keep this process off that cache (no loads, its saves kept back) while a worker process writes it
(rendering/compile_ahead.py); ``CACHE_EMPTY``: whether it held no kernel when this process started.

``exact_njit`` is the one exception: kernels that take over a tile's NumPy expressions (camera
rays, shading normals, the surface term's shadow rays, the exponential transmittance), without
fastmath and with NumPy's error model (x / 0 is inf or nan), so that every operation rounds as
NumPy's does (no FMA contraction) and the images stay bit for bit what the NumPy code gave
(tests/test_exact_kernels.py); and kernels whose result must not depend on how they are batched
(analytic's moment recurrences run side by side over a tile's segments, `cosine_moments_lanes`).

``jitable`` and ``exact_jitable``: the same flags for small helpers that kernels call with constant
arguments, compiled once per argument type rather than once per constant. ``OPTIONS``: ``njit``'s
flags without its cache, for the overloads that compile a registered kernel's own code into its
callers (media/integrand.py's record dispatch).

Cuts of numba's own cost per compilation: ``njit`` and ``exact_njit`` give a `Kernel`, numba's
dispatcher less the Python wrapper of the functions that only compiled code calls, which compiles a
function called from compiled code once per argument type, not once per constant; and
`TargetConfig.values` builds its dict without a property call per option (numba hashes and compares
the compile flags at every overload it tries while typing a call); and a function inlined with
``inline="always"`` is copied with one memo for all its blocks (`_inline_ir`). They rely on numba's
internals (0.68's); `CUTS` is False where those differ, and ``njit`` is numba's own.
"""
import copy
import functools
import os
import threading
from pathlib import Path

import numba
from numba.core import caching, compiler, dispatcher, errors, inline_closurecall, sigutils, targetconfig, types
from numba.core.registry import CPUDispatcher
from numba.extending import register_jitable

from .cache import PACKAGE_DIR, kernel_cache_dir

FASTMATH = frozenset({"nsz", "arcp", "contract", "reassoc"})

_Base = getattr(caching, "UserProvidedCacheLocator", None) or caching._UserProvidedCacheLocator
_Impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl


class SourceKeyedLocator(_Base):
    """numba cache locator for the functions of this package: one folder per source hash."""
    root = kernel_cache_dir()

    def __init__(self, py_func, py_file):
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        rel = Path(py_file).resolve().relative_to(PACKAGE_DIR).parent
        self._cache_path = os.path.join(self.root, str(rel))

    @classmethod
    def from_function(cls, py_func, py_file):
        if not Path(py_file).resolve().is_relative_to(PACKAGE_DIR):
            return None
        try:
            locator = cls(py_func, py_file)
            locator.ensure_cache_path()
        except OSError:  # an unwritable cache folder: numba's own locators decide
            return None
        return locator


# whether the cache held no kernel of these sources when this process started (rendering/compile_ahead.py)
CACHE_EMPTY = not any(Path(SourceKeyedLocator.root).rglob("*.nbi"))

if SourceKeyedLocator not in _Impl._locator_classes:
    _Impl._locator_classes.insert(0, SourceKeyedLocator)


def _config_values(self, _defaults={}):
    """`TargetConfig.values` without a property call per option: the same dict (every option, in the
    class's order, its set value or its default)."""
    cls = type(self)
    try:
        values = _defaults[cls].copy()
    except KeyError:
        values = _defaults.setdefault(cls, {k: option.default for k, option in cls.options.items()}).copy()
    values.update(self._values)
    return values


_copying = threading.local()  # the memo of the inlining (`_inline_ir`) the thread is in, else None


class _SharedMemo:
    """`copy` as numba's inliner (inline_closurecall) sees it: its `deepcopy` of a block takes the memo of the
    inlining in progress (`_inline_ir`)."""

    @staticmethod
    def deepcopy(x, memo=None):
        shared = getattr(_copying, "memo", None)
        return copy.deepcopy(x, shared if memo is None else memo)


def _inline_ir(inline_ir):
    """numba's `InlineWorker.inline_ir` with one deepcopy memo for all the callee's blocks. numba copies the
    callee's IR block by block, each with a memo of its own, and every block's variables hold the function's
    scope, which holds all its variables: each block copies them all, so inlining a function of b blocks and
    v variables copies b v variables, where one copy of the scope serves (as it does in the IR copied; the
    copies of the scope are equal and replaced by the caller's when the blocks are merged). The IR it gives is
    the same (the same variables renamed the same way); stage's air-light, whose `_spot_airlight` inlines
    `_spot_body` and `_piece`, compiles about a tenth faster (docs/benchmarks.md)."""
    def inline(self, *args, **kwargs):
        outer, _copying.memo = getattr(_copying, "memo", None), {}
        try:
            return inline_ir(self, *args, **kwargs)
        finally:
            _copying.memo = outer
    return inline


# the internals the cuts rely on (numba 0.68); where a numba release changes them, plain numba.njit
CUTS = (hasattr(dispatcher._FunctionCompiler, "_customize_flags") and "no_cpython_wrapper" in compiler.Flags.options
        and hasattr(CPUDispatcher, "add_overload") and "_values" in getattr(targetconfig.TargetConfig, "__slots__", ())
        and getattr(inline_closurecall, "copy", None) is copy and hasattr(inline_closurecall.InlineWorker, "inline_ir"))
if CUTS:
    targetconfig.TargetConfig.values = _config_values
    inline_closurecall.copy = _SharedMemo
    inline_closurecall.InlineWorker.inline_ir = _inline_ir(inline_closurecall.InlineWorker.inline_ir)

_nesting = threading.local()  # how many of this package's compilations the thread is inside


def _has_python_wrapper(cres) -> bool:
    return bool(cres.library.get_pointer_to_function(cres.fndesc.llvm_cpython_wrapper_name))


_held = None  # while the disk cache is held (`hold`): the saves kept back, else None


def hold():
    """Hold this process's disk cache of the package's kernels: no loads, and every save kept back
    until `release` (rendering/compile_ahead.py: another process writes the cache meanwhile)."""
    global _held
    _held = []


def release():
    """Write the saves held back since `hold`, then load and save as usual."""
    global _held
    pending, _held = _held or [], None
    for cache, sig, cres in pending:
        cache.save_overload(sig, cres)


class _Cache:
    """A dispatcher's disk cache that stores only compilations with a Python wrapper (and neither
    loads nor saves while `hold` holds it)."""

    def __init__(self, cache):
        self._cache = cache

    def __getattr__(self, name):
        return getattr(self._cache, name)

    def load_overload(self, sig, target_context):
        return None if _held is not None else self._cache.load_overload(sig, target_context)

    def save_overload(self, sig, cres):
        if not _has_python_wrapper(cres):
            return
        if _held is not None:
            _held.append((self._cache, sig, cres))
        else:
            self._cache.save_overload(sig, cres)


class Kernel(CPUDispatcher):
    """numba's dispatcher, less the Python wrapper where only compiled code calls a function.

    numba builds a wrapper that unboxes Python arguments for every compilation, also for the helpers
    that only other kernels call (their callers link the helper's own code, never its wrapper): ~1 s of
    the default scene's compile. A compilation nested in another one of the package is made without it,
    is not inserted in the table Python calls look up and is not written to the disk cache (its code is
    in its callers'); a call from Python with those argument types compiles it again, with its wrapper.
    """

    def _compile_core_flags(self, flags):
        if getattr(_nesting, "depth", 0) > 1:
            flags.no_cpython_wrapper = True
        return flags

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._compiler._customize_flags = self._compile_core_flags

    def enable_caching(self):
        super().enable_caching()
        self._cache = _Cache(self._cache)

    def add_overload(self, cres):
        if _has_python_wrapper(cres):
            super().add_overload(cres)
        else:
            self.overloads[tuple(cres.signature.args)] = cres

    def get_call_template(self, args, kws):
        """A call from compiled code, typed for its arguments' non-literal types: numba types a constant
        argument as a literal (`Literal[int](0)`), also while a variable's type is not yet settled (`m = 0`
        then `m += 1`: int64 in the end), and compiles a specialisation per literal, used or not. A
        function that needs the constant (`numba.literally`, a tuple indexed by it) gets the literal."""
        plain, plain_kws = tuple(types.unliteral(a) for a in args), {k: types.unliteral(v) for k, v in kws.items()}
        if self._can_compile and (plain != tuple(args) or plain_kws != kws):
            try:
                return super().get_call_template(plain, plain_kws)
            except errors.NumbaError:
                pass
        return super().get_call_template(args, kws)

    def compile(self, sig):
        depth = getattr(_nesting, "depth", 0)
        if not depth:  # from Python: a compilation without the wrapper is made again with it
            args, _ = sigutils.normalize_signature(sig)
            existing = self.overloads.get(tuple(args))
            if existing is not None and not _has_python_wrapper(existing):
                del self.overloads[tuple(args)]
        _nesting.depth = depth + 1
        try:
            return super().compile(sig)
        finally:
            _nesting.depth = depth


def _jit(**options):
    """numba.njit with these flags (cached unless ``cache=False``), giving a `Kernel` (where `CUTS`)."""
    if not CUTS:
        return functools.partial(numba.njit, cache=True, **options)

    def decorate(fn=None, *, cache=True, **more):
        if fn is None:
            return functools.partial(decorate, cache=cache, **more)
        disp = Kernel(py_func=fn, locals={}, targetoptions={**options, **more, "nopython": True})
        if cache:
            disp.enable_caching()
        return disp
    return decorate


# no_cfunc_wrapper: no C-callable wrapper per compiled function (it serves only first-class function
# arguments, which no kernel takes): about 10 ms less compile per function, the kernels' code unchanged
OPTIONS = dict(nogil=True, fastmath=set(FASTMATH), no_cfunc_wrapper=True)  # njit's flags, less its cache
njit = _jit(**OPTIONS)
# fastmath=False explicitly: a kernel whose flags leave fastmath unset inherits its caller's when a fastmath
# kernel compiles it first (numba's ConfigStack), and keeps those flags for every later caller
exact_njit = _jit(nogil=True, fastmath=False, error_model="numpy", no_cfunc_wrapper=True)
# small helpers that kernels call with constant arguments (row indices, a range's start): an overload is
# typed on its arguments' non-literal types first, so it compiles once per array type, where a dispatcher
# compiles once per constant (numba types a constant argument as Literal[int]); it has no cache of its
# own (it is compiled into its callers, which are cached)
jitable = register_jitable(**OPTIONS)
exact_jitable = register_jitable(fastmath=False, error_model="numpy", nogil=True, no_cfunc_wrapper=True)
