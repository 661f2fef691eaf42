"""The first render's compile split over two processes, on an empty kernel cache.

numba compiles under one lock per process, but the kernel cache is shared on disk. While the
warm-up (renderer.warm_up) compiles the shadow frusta's and the surfaces' kernels in this process,
a worker process started at its beginning compiles the air-light's kernels and the inside
integrals of the rays into media inside shapes (renderer.compile_airlight, `interiors_ahead`: the
warm-up shades those rays after the worker) into the cache. Which process compiles what does not depend on timing:
until the worker has finished, this process neither loads from the cache nor writes to it
(`jit.hold`: it compiles whatever it calls itself), and its method's air-light (`Gated`) first waits
for the worker, then loads what the worker compiled. Engaged for the first warm-up of a process
that started with no kernel in the cache, on two cores or more, where that warm-up builds shadow
frusta (the two groups: frusta and surfaces here, the air-light there). Where the area lights'
cubature pilot warms up first, unshadowed, before a render with shadows, the groups go the other way
round: the pilot's warm-up compiles the air-light and the surfaces here while the worker compiles the
shadows' kernels (renderer.compile_shadows), which the render's own warm-up then loads (`settle`
waits for the worker first); ``RAYTRACE_COMPILE_AHEAD=0``
turns it off. A method's air-light may leave some of its kernels to this process (`compile_here`: compiled
by signature before the gate, so that neither process waits on them; analytic's moment recurrences), the worker
running it without them (`ahead`). The worker is a fresh interpreter on this one's module path (not multiprocessing's
spawn, which would run the caller's main script again where it has no ``if __name__ ==
"__main__"`` guard).
"""
from __future__ import annotations

import dataclasses
import os
import pickle
import subprocess
import sys
import time
from pathlib import Path

from .. import jit

_started = []  # the warm-ups of this process that asked for a worker
_later = []  # a worker that compiles a later warm-up's kernels (`start(later=True)`), until `settle`


def engaged() -> bool:
    """Whether this process may compile ahead in a worker: it started with no kernel in the cache
    (`jit.CACHE_EMPTY`) and has two cores or more."""
    if not (jit.CUTS and jit.CACHE_EMPTY) or os.environ.get("RAYTRACE_COMPILE_AHEAD") == "0":
        return False
    return (len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1) > 1


class Ahead:
    """`fn(*args)` (picklable) in a worker process on this process's kernel cache, this process's
    cache held (`jit.hold`) until `wait`."""

    def __init__(self, fn, *args):
        call = pickle.dumps((fn, args))
        code = f"import sys; sys.path[:] = {sys.path!r}; from {__name__} import serve; serve()"
        env = dict(os.environ, RAYTRACE_CACHE=str(Path(jit.SourceKeyedLocator.root).parents[1]))
        self._proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE,
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
        try:
            self._proc.stdin.write(call)
            self._proc.stdin.close()
        except OSError:  # the worker died at once: it compiles nothing
            pass
        jit.hold()

    def wait(self, stop: bool = False):
        """Wait for the worker (once; `stop`: end it first, as when the warm-up failed or was
        interrupted), then release the cache. A worker that failed leaves its kernels to this process."""
        if self._proc is not None:
            if stop:
                self._proc.kill()
            self._proc.wait()
            self._proc = None
            jit.release()


def start(split: bool, fn, *args, later: bool = False) -> Ahead | None:
    """`Ahead(fn, *args)` for the first warm-up of a process (`start`'s first call) where `split` (it
    compiles a second group of kernels meanwhile) and `engaged`, else None (also where no process
    can be started or the arguments cannot be pickled). `later`: `fn` compiles the kernels of a later
    warm-up, not this one's: the worker is kept for `settle`, and None returned."""
    first = not _started
    _started.append(fn)
    if not (split and first and engaged()):
        return None
    try:
        ahead = Ahead(fn, *args)
    except (OSError, pickle.PicklingError, AttributeError, TypeError):
        return None
    if later:
        _later.append(ahead)
        return None
    return ahead


def settle(stop: bool = False) -> float:
    """Wait for the worker `start(later=True)` left, if any (`stop`: end it first); the seconds waited
    (0 where there is none)."""
    if not _later:
        return 0.0
    begin = time.perf_counter()
    while _later:
        _later.pop().wait(stop)
    return time.perf_counter() - begin


def compile_here(method, medium, lights, params):
    """Compile in this process, by signature, the kernels of `method`'s air-light that it leaves to the render's
    process while the worker compiles the rest (`Method.compile_here`, where it has one)."""
    if method.compile_here is not None:
        method.compile_here(medium, lights, params)


def ahead(method):
    """`method` as the worker runs it: its air-light without the kernels `compile_here` compiles
    (`Method.worker_airlight`, where it has one; the values it gives are not used)."""
    rest = method.worker_airlight
    return method if rest is None else dataclasses.replace(method, airlight=rest)


def serve():
    """The worker: the call `Ahead` writes to its standard input."""
    fn, args = pickle.load(sys.stdin.buffer)
    fn(*args)


class Gated:
    """`method` whose air-light first waits for `ahead` (`Ahead.wait`)."""

    def __init__(self, method, ahead: Ahead):
        self._method, self._ahead = method, ahead

    def __getattr__(self, name):
        return getattr(self._method, name)

    def airlight(self, *args, **kwargs):
        self._ahead.wait()
        return self._method.airlight(*args, **kwargs)
