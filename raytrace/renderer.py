"""The render loop: tiles of rows on a thread pool (Embree and the numba kernels release the GIL).

Per tile: camera rays → first hits → surface term (eq. 5) → air-light of the chosen method →
L = exp(-kt t) Lb + sum of air-lights, averaged over the pixel's samples. Results do not depend
on the thread count: every tile is computed the same way whichever thread runs it.
"""
from __future__ import annotations

import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from .accel import Accelerator
from .camera import generate_rays
from .errors import UserError
from .media import RayBatch, get_method, resolve_params
from .scene.format import Scene
from .scene.meshes import scene_triangles
from .shading import facing_normals, surface_radiance, transmittance

RAYS_PER_TILE = 1 << 14
SHADOW_CHUNK = 1 << 10  # rays per batch of volumetric-shadow points


@dataclass
class Prepared:
    """Everything about a scene that does not depend on the method: geometry and its accelerator."""
    scene: Scene
    accel: Accelerator
    reflectance: np.ndarray
    light_pos: np.ndarray
    light_int: np.ndarray


@dataclass
class RenderResult:
    image: np.ndarray  # (H, W, 3) float64
    method: str
    params: dict
    seconds: float  # wall time of the render, compile time excluded
    compile_seconds: float
    stats: dict = field(default_factory=dict)
    variance: np.ndarray | None = None  # (H, W, 3) variance of each pixel's estimate (stochastic methods)
    passes: int = 1


def prepare(scene: Scene) -> Prepared:
    tris, refl = scene_triangles(scene)
    lights = np.array([l.position for l in scene.lights]).reshape(-1, 3)
    extent = np.concatenate([lights, scene.camera.position[None, :]])
    return Prepared(scene, Accelerator(tris, extent), refl, lights,
                    np.array([l.intensity for l in scene.lights]).reshape(-1, 3))


def default_threads() -> int:
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)


def shade_rays(prep: Prepared, method, params, origins, dirs, keys, seed):
    """Radiance (N, 3) of camera rays and the method's statistics array."""
    scene = prep.scene
    medium = scene.medium
    t, prim = prep.accel.first_hit(origins, dirs)
    hit = prim >= 0
    radiance = np.zeros((len(origins), 3))
    if hit.any():
        points = origins[hit] + t[hit, None] * dirs[hit]
        normals = facing_normals(prep.accel.normals[prim[hit]], dirs[hit])
        radiance[hit] = surface_radiance(prep.accel, points, normals, prep.reflectance[prim[hit]],
                                         prep.light_pos, prep.light_int, medium.sigma_t)
    radiance[~hit] = scene.background
    radiance *= transmittance(medium.sigma_t, t)
    stats = np.zeros(method.stats_size)
    variance = np.zeros_like(radiance) if method.stochastic else None
    if len(prep.light_pos) and np.any(medium.sigma_s > 0.0):
        batch = RayBatch(origins, dirs, t, keys, seed, prep.accel.scale)
        if params.get("volumetric_shadows"):
            air, var = shadowed_airlight(prep, method, params, batch)
            radiance += air
            if method.stochastic:
                variance = var
        else:
            res = method.airlight(batch, medium, prep.light_pos, prep.light_int, params)
            radiance += res[0]
            stats = res[1]
            if method.stochastic:
                variance = res[2]
    return radiance, stats, variance


def shadowed_airlight(prep: Prepared, method, params, batch: RayBatch):
    """Air-light with volumetric shadows: a shadow ray from every medium point of the method's
    estimate to its light (Embree, in one batch per light and channel), then the estimate's mean
    over iterations and the variance of that mean."""
    if len(batch.origins) > SHADOW_CHUNK:  # bound the memory of the sample points
        parts = [shadowed_airlight(prep, method, params, RayBatch(batch.origins[i:i + SHADOW_CHUNK],
                                   batch.dirs[i:i + SHADOW_CHUNK], batch.tmax[i:i + SHADOW_CHUNK],
                                   batch.keys[i:i + SHADOW_CHUNK], batch.seed, batch.scale))
                 for i in range(0, len(batch.origins), SHADOW_CHUNK)]
        return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
    pos, weight = method.points(batch, prep.scene.medium, prep.light_pos, prep.light_int, params)
    visible = np.zeros(weight.shape, dtype=bool)
    eps = prep.accel.epsilon
    for li, lp in enumerate(prep.light_pos):
        for c in range(3):
            p, w = pos[:, li, ..., c, :], weight[:, li, ..., c]
            if c > 0 and np.array_equal(p, pos[:, li, ..., 0, :]):
                visible[:, li, ..., c] = visible[:, li, ..., 0]
                continue
            m = w != 0.0
            to_light = lp - p[m]
            dist = np.linalg.norm(to_light, axis=1)
            d = to_light / np.where(dist > 0.0, dist, 1.0)[:, None]
            vis = visible[:, li, ..., c]
            vis[m] = ~prep.accel.occluded(p[m] + eps * d, d, dist - 2.0 * eps)
            visible[:, li, ..., c] = vis
    per_iter = (weight * visible).sum(axis=(1, 3))  # (N, n, 3): each iteration's estimate of the whole air-light
    n = per_iter.shape[1]
    var = per_iter.var(axis=1, ddof=1) / n if n > 1 else np.zeros((len(per_iter), 3))
    return per_iter.mean(axis=1), var


def warm_up(prep: Prepared, method, params, seed) -> float:
    """Compile the method's kernels on a few rays; returns the seconds it took."""
    start = time.perf_counter()
    o, d = generate_rays(prep.scene.camera, slice(0, 1), slice(0, 1))
    shade_rays(prep, method, params, o[:1], d[:1], np.zeros(1, dtype=np.uint64), seed)
    return time.perf_counter() - start


def render(prep: Prepared, method_name: str, given_params: dict | None = None, seed: int = 0,
           threads: int | None = None, progress=None, source: str = "render", crop=None) -> RenderResult:
    """Render the image, or the pixel block `crop` = (x0, y0, x1, y1) of it (end exclusive; the same
    samples and random numbers as in the whole image). `progress(n)` gets the rows finished."""
    scene = prep.scene
    method = get_method(method_name)
    params = resolve_params(method, given_params or {}, source)
    method.check(scene.medium, params)
    if params.get("volumetric_shadows") and method.points is None:
        raise UserError(f"{source}: --volumetric-shadows: method {method.name} has no medium sample points; "
                        "use raymarch or montecarlo")
    cam = scene.camera
    x0, y0, x1, y1 = crop or (0, 0, cam.width, cam.height)
    cols = slice(x0, x1)
    compile_s = warm_up(prep, method, params, seed)
    rows_per_tile = max(1, RAYS_PER_TILE // ((x1 - x0) * cam.spp))
    tiles = [slice(r, min(r + rows_per_tile, y1)) for r in range(y0, y1, rows_per_tile)]
    image = np.zeros((y1 - y0, x1 - x0, 3))
    variance = np.zeros_like(image) if method.stochastic else None
    totals = np.zeros(method.stats_size)

    def work(rows):
        o, d = generate_rays(cam, rows, cols)
        pix = (np.arange(rows.start, rows.stop)[:, None] * cam.width + np.arange(x0, x1)[None, :]).ravel()
        keys = (pix[:, None].astype(np.uint64) * np.uint64(cam.spp) + np.arange(cam.spp, dtype=np.uint64)).ravel()
        rad, stats, var = shade_rays(prep, method, params, o, d, keys, seed)
        shape = (rows.stop - rows.start, x1 - x0, cam.spp, 3)
        block = slice(rows.start - y0, rows.stop - y0)
        image[block] = rad.reshape(shape).mean(axis=2)
        if variance is not None:  # variance of the pixel mean of independent per-ray estimates
            variance[block] = var.reshape(shape).sum(axis=2) / cam.spp**2
        return rows.stop - rows.start, stats

    start = time.perf_counter()
    threads = threads or default_threads()
    with ThreadPoolExecutor(threads) as pool:
        for n_rows, stats in pool.map(work, tiles):
            if len(stats):
                totals += stats
            if progress is not None:
                progress(n_rows)
    seconds = time.perf_counter() - start
    return RenderResult(image, method.name, params, seconds, compile_s, method.summarize(totals), variance)
