"""Rendering on a Dask distributed cluster (the optional extra `distributed`; imported only when used).

`Cluster(client)` is an executor of renderer.render (api.py plugs it in for `client=`): the tiles of
rendering/renderer.py (a band's pixels dealt out in turn x pixel-sample ranges) become tasks; the client adds their results
in renderer.Accumulator's fixed order, so the image is the single machine's bit for bit whatever
the number of workers. A task carries the parsed scene, not its meshes: each worker process loads
the meshes (through its own RAYTRACE_ASSETS), builds the Embree accelerator and compiles the
kernels once per scene (`_prepared`), before the first tile (`prepare_workers`) or in the first
tile of a worker that joins later. With an environment light a worker builds a pixel sample's view
(its directions' shadow frusta: renderer.seeded) for the tiles of it that it is given, sample after sample, and
drops it when it starts another sample's tile; the client has the workers drop the last ones when the render is
over or stopped (`_forget`). A worker lost mid-render loses its tasks in flight; the scheduler runs them again
elsewhere, with the same result.
"""
from __future__ import annotations

import asyncio
import hashlib
import logging
import pickle
import threading
import time
import uuid
from collections import OrderedDict
from contextlib import contextmanager
from dataclasses import dataclass, field

import dask
from distributed import Client, LocalCluster, as_completed

from ..errors import UserError, counted
from ..methods import get_method
from ..scene.format import Scene
from . import renderer

CONNECT_TIMEOUT = 10.0  # seconds to reach a scheduler
WORKER_TIMEOUT = 20.0  # seconds to wait for a scheduler's first worker
CACHED_SCENES = 2  # prepared scenes kept per worker process
# Worker settings of local clusters (README: remote workers). Dask starts worker processes with
# MALLOC_TRIM_THRESHOLD_ set, which turns off glibc's dynamic mmap threshold: every large temporary
# array of a tile is then mapped and faulted in afresh, and tiles take 25-40 % longer; its sampling
# profiler (every 10 ms) costs about 5 % of the CPU (benchmarks/cluster.py, CPU efficiency 0.87 -> 0.92).
WORKER_CONFIG = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
                 "distributed.worker.profile.enabled": False}

_cache: OrderedDict[str, renderer.Prepared] = OrderedDict()
_warm: set = set()
_lock = threading.Lock()


@dataclass(frozen=True)
class Job:
    """What every tile of one render shares: the scene without its meshes (so it is small) and the
    renderer's task."""
    scene: Scene
    task: renderer.Task
    scene_key: str = field(default="", compare=False)

    def __post_init__(self):
        if not self.scene_key:
            object.__setattr__(self, "scene_key", hashlib.sha256(pickle.dumps(self.scene)).hexdigest())


def _prepared(job: Job) -> tuple[renderer.Prepared, float, float]:
    """This process's prepared scene of `job` with its kernels compiled; the seconds spent loading and
    compiling now (0 when cached)."""
    load_s = compile_s = 0.0
    with _lock:
        prep = _cache.get(job.scene_key)
        if prep is None:
            start = time.perf_counter()
            prep = _cache[job.scene_key] = renderer.prepare(job.scene)
            while len(_cache) > CACHED_SCENES:
                _cache.popitem(last=False)
            load_s = time.perf_counter() - start
        _cache.move_to_end(job.scene_key)
        task = job.task
        if task.shadows:
            prep.frusta()
        warm = (job.scene_key, task.method, repr(task.params), task.shadows)
        if warm not in _warm:
            compile_s = renderer.warm_up(prep, get_method(task.method), task.params, task.seed, task.shadows)
            _warm.add(warm)
    return prep, load_s, compile_s


async def _preload(job: Job):
    """client.run target: prepare `job` on the worker's thread pool, not its event loop."""
    start = time.perf_counter()
    _, load_s, compile_s = await asyncio.get_running_loop().run_in_executor(None, _prepared, job)
    return {"load": load_s, "compile": compile_s, "wall": time.perf_counter() - start}


def _tile_task(job: Job, tile: renderer.Tile):
    prep, _, _ = _prepared(job)
    start = time.perf_counter()
    result = renderer.render_tile(prep, job.task, tile, every_tile=False)
    return result, time.perf_counter() - start


async def _forget(job: Job):
    """client.run target: the render of `job` is over, so its pixel samples' views are dropped here
    (renderer.forget; on the thread pool: it waits for the scene's lock)."""
    def forget():
        with _lock:
            prep = _cache.get(job.scene_key)
        if prep is not None:
            renderer.forget(prep, job.task.seed)
    await asyncio.get_running_loop().run_in_executor(None, forget)


def prepare_workers(client: Client, job: Job) -> float:
    """Load the scene and compile the kernels on every worker now, so that bad input (meshes a
    worker cannot find) fails before the first tile and compilation stays out of the render time;
    returns the longest compile time."""
    found = client.run(_preload, job, on_error="return")
    for address, r in sorted(found.items()):
        if isinstance(r, UserError):
            raise UserError(f"--scheduler: worker {address}: {r}; every worker must find the meshes (set "
                            "RAYTRACE_ASSETS for the workers)")
        if isinstance(r, BaseException) and not isinstance(r, OSError):  # OSError: a worker lost meanwhile
            raise r
    return max([r["compile"] for r in found.values() if isinstance(r, dict)], default=0.0)


def map_tiles(client: Client, job: Job, work: list[renderer.Tile], timings: list | None = None):
    """(index, result) of every tile of `work` as the cluster finishes them; `timings` collects
    each task's compute seconds."""
    token = uuid.uuid4().hex
    futures = {client.submit(_tile_task, job, tile, key=f"tile-{token}-{i}", pure=False): i
               for i, tile in enumerate(work)}
    try:
        for future, (result, seconds) in as_completed(futures, with_results=True):
            if timings is not None:
                timings.append(seconds)
            yield futures.pop(future), result
    except UserError as exc:
        raise UserError(f"--scheduler: a worker failed: {exc}") from None
    finally:
        client.cancel(list(futures))
        client.run(_forget, job, on_error="ignore")  # the last sample's views, and any a stop left


class Cluster:
    """The executor of a Dask cluster (renderer.Threads' interface): every worker loads the scene
    and compiles the kernels in `prepare`, then `map` runs the tiles as tasks."""

    def __init__(self, client: Client):
        self.client = client

    def prepare(self, prep: renderer.Prepared, task: renderer.Task) -> float:
        return prepare_workers(self.client, Job(prep.scene, task))

    def map(self, prep: renderer.Prepared, task: renderer.Task, work: list[renderer.Tile]):
        yield from map_tiles(self.client, Job(prep.scene, task), work)


def dashboard(client: Client) -> str | None:
    """The cluster's dashboard address, when its scheduler serves one (it needs bokeh)."""
    return client.dashboard_link if "dashboard" in client.scheduler_info().get("services", {}) else None


def _local_workers(spec: str) -> int:
    n = spec[len("local:"):]
    if not n.isdigit() or int(n) < 1:
        raise UserError(f"--scheduler {spec}: expected local:N with N >= 1 worker processes, e.g. local:2")
    return int(n)


@contextmanager
def connect(spec: str, log=None):
    """A Client for `--scheduler SPEC`: `local:N` starts a local cluster of N single-threaded worker
    processes, anything else is a scheduler address (tcp://HOST:PORT) that must answer within
    CONNECT_TIMEOUT seconds and have a worker within WORKER_TIMEOUT. `log(line)` gets the workers
    and the dashboard link."""
    logging.getLogger("distributed").setLevel(logging.CRITICAL)  # failures are reported as UserErrors
    if spec.startswith("local:"):
        n = _local_workers(spec)
        with (dask.config.set(WORKER_CONFIG),
              LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                           silence_logs=logging.CRITICAL) as cluster,
              Client(cluster) as client):
            _announce(client, spec, log)
            yield client
        return
    try:
        client = Client(spec, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError, ValueError) as exc:
        reason = str(exc).split("\n")[0] or type(exc).__name__
        raise UserError(f"--scheduler {spec}: no scheduler answered within {CONNECT_TIMEOUT:g} s ({reason}); "
                        "start one (`dask scheduler`) or give its address as tcp://HOST:PORT, or use local:N") from None
    with client:
        try:
            client.wait_for_workers(1, timeout=WORKER_TIMEOUT)
        except TimeoutError:
            raise UserError(f"--scheduler {spec}: the scheduler has no workers after {WORKER_TIMEOUT:g} s; start "
                            f"some with `dask worker {spec}`") from None
        _announce(client, spec, log)
        yield client


def _announce(client: Client, spec: str, log):
    if log is not None:
        nthreads = client.nthreads()
        link = dashboard(client)
        log(f"dask {spec}: {counted(len(nthreads), 'worker')}, {counted(sum(nthreads.values()), 'thread')}"
            + (f", dashboard {link}" if link else ""))
