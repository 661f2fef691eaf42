"""The first render's compile split over two processes, on an empty kernel cache.

numba compiles under one lock per process, but the kernel cache is shared on disk. While the
warm-up (renderer.warm_up) compiles the shadow frusta's and the surfaces' kernels in this process,
a worker process started at its beginning compiles the air-light's kernels
(renderer.compile_airlight) into the cache. Which process compiles what does not depend on timing:
until the worker has finished, this process neither loads from the cache nor writes to it
(`jit.hold`: it compiles whatever it calls itself), and its method's air-light (`Gated`) first waits
for the worker, then loads what the worker compiled. Engaged for the first warm-up of a process
that started with no kernel in the cache, on two cores or more, where that warm-up builds shadow
frusta (the two groups: frusta and surfaces here, the air-light there; a scene whose area lights'
cubature pilot warms up first, unshadowed, compiles in one process); ``RAYTRACE_COMPILE_AHEAD=0``
turns it off. The worker is a fresh interpreter on this one's module path (not multiprocessing's
spawn, which would run the caller's main script again where it has no ``if __name__ ==
"__main__"`` guard).
"""
from __future__ import annotations

import os
import pickle
import subprocess
import sys
from pathlib import Path

from .. import jit

_started = []  # the warm-ups of this process that asked for a worker


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


def start(split: bool, fn, *args) -> Ahead | None:
    """`Ahead(fn, *args)` for the first warm-up of a process (`start`'s first call) where `split` (it
    compiles a second group of kernels meanwhile) and `engaged`, else None (also where no process
    can be started or the arguments cannot be pickled)."""
    first = not _started
    _started.append(fn)
    if not (split and first and engaged()):
        return None
    try:
        return Ahead(fn, *args)
    except (OSError, pickle.PicklingError, AttributeError, TypeError):
        return None


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
