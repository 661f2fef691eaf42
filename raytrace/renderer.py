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
from .lights import Lights
from .methods import get_method, resolve_params
from .scene.format import Scene
from .scene.meshes import scene_triangles
from .shading import facing_normals, surface_radiance
from .visibility import shadowed_airlight, unshadowed_airlight, whole_rays

RAYS_PER_TILE = 1 << 14


@dataclass
class Prepared:
    """Everything about a scene that does not depend on the method: geometry and its accelerator."""
    scene: Scene
    accel: Accelerator
    reflectance: np.ndarray
    lights: Lights


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
    lights = Lights.of(scene.lights)
    extent = np.concatenate([lights.position, scene.camera.position[None, :]])
    return Prepared(scene, Accelerator(tris, extent), refl, lights)


def default_threads() -> int:
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)


def shade_rays(prep: Prepared, method, params, origins, dirs, keys, seed, volumetric_shadows=False):
    """Radiance (N, 3) of camera rays, the method's statistics array and, for a stochastic method,
    the variance (N, 3) of each ray's estimate."""
    scene = prep.scene
    medium = scene.medium
    t, prim = prep.accel.first_hit(origins, dirs)
    hit = prim >= 0
    radiance = np.zeros((len(origins), 3))
    if hit.any():
        points = origins[hit] + t[hit, None] * dirs[hit]
        normals = facing_normals(prep.accel.normals[prim[hit]], dirs[hit])
        radiance[hit] = surface_radiance(prep.accel, points, normals, prep.reflectance[prim[hit]], prep.lights,
                                         medium)
    radiance[~hit] = scene.background
    radiance *= medium.transmittance(t)
    stats = np.zeros(method.stats_size)
    variance = np.zeros_like(radiance) if method.stochastic else None
    if len(prep.lights) and medium.scatters:
        if volumetric_shadows:
            segs = whole_rays(origins, dirs, t, keys, len(prep.lights), seed, prep.accel.scale)
            air, var = shadowed_airlight(prep.accel, method, medium, prep.lights, params, segs, len(origins))
        else:
            air, stats, var = unshadowed_airlight(method, medium, prep.lights, params, origins, dirs, t, keys, seed,
                                                  prep.accel.scale)
        radiance += air
        if method.stochastic:
            variance = var
    return radiance, stats, variance


def warm_up(prep: Prepared, method, params, seed, volumetric_shadows=False) -> float:
    """Compile the method's kernels on a few rays; returns the seconds it took."""
    start = time.perf_counter()
    o, d = generate_rays(prep.scene.camera, slice(0, 1), slice(0, 1))
    shade_rays(prep, method, params, o[:1], d[:1], np.zeros(1, dtype=np.uint64), seed, volumetric_shadows)
    return time.perf_counter() - start


def check_options(method, volumetric_shadows, source):
    if volumetric_shadows and method.points is None:
        raise UserError(f"{source}: --volumetric-shadows (render.volumetric_shadows): method {method.name} has no "
                        "medium sample points yet; use --method raymarch or montecarlo, or leave shadows off")


def render(prep: Prepared, method_name: str, given_params: dict | None = None, seed: int = 0,
           threads: int | None = None, progress=None, source: str = "render", crop=None,
           volumetric_shadows: bool = False) -> RenderResult:
    """Render the image, or the pixel block `crop` = (x0, y0, x1, y1) of it (end exclusive; the same
    samples and random numbers as in the whole image). `progress(n)` gets the rows finished.
    `given_params` are the method's own parameters (any other key is refused); seed, threads, crop
    and volumetric_shadows are render options."""
    scene = prep.scene
    method = get_method(method_name)
    params = resolve_params(method, given_params or {}, source)
    method.check(scene.medium, params)
    check_options(method, volumetric_shadows, source)
    cam = scene.camera
    x0, y0, x1, y1 = crop or (0, 0, cam.width, cam.height)
    cols = slice(x0, x1)
    compile_s = warm_up(prep, method, params, seed, volumetric_shadows)
    rows_per_tile = max(1, RAYS_PER_TILE // ((x1 - x0) * cam.spp))
    tiles = [slice(r, min(r + rows_per_tile, y1)) for r in range(y0, y1, rows_per_tile)]
    image = np.zeros((y1 - y0, x1 - x0, 3))
    variance = np.zeros_like(image) if method.stochastic else None
    totals = np.zeros(method.stats_size)

    def work(rows):
        o, d = generate_rays(cam, rows, cols)
        pix = (np.arange(rows.start, rows.stop)[:, None] * cam.width + np.arange(x0, x1)[None, :]).ravel()
        keys = (pix[:, None].astype(np.uint64) * np.uint64(cam.spp) + np.arange(cam.spp, dtype=np.uint64)).ravel()
        rad, stats, var = shade_rays(prep, method, params, o, d, keys, seed, volumetric_shadows)
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
