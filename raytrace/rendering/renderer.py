"""The render loop: tiles (a band's pixels dealt out in turn x pixel-sample ranges) run by an
executor, threads of this process (`Threads`: Embree and the numba kernels release the GIL) or any
object with the same two methods (api.py plugs in rendering/distributed.py's Dask cluster; this module does
not import it).

Per tile: camera rays → first hits → surface term (eq. 5) → air-light of the chosen method →
L = T(0, t) Lb + sum of air-lights (T the medium's transmittance from the camera, exp(-kt t) when
homogeneous), averaged over the pixel's samples, and beside it each pixel's error bound
(error_bounds.py: the sum of its parts' bounds over the samples / spp). Results do not depend on the
thread or worker count: the tiles are the same and each is computed and reduced the same way
wherever it runs.
"""
from __future__ import annotations

import collections
import contextlib
import copy
import dataclasses
import functools
import os
import queue
import threading
import time
from dataclasses import dataclass, field

import numpy as np

from .. import error_bounds
from ..camera import basis, pixel_rays
from ..errors import UserError
from ..geometry.accel import Accelerator
from ..interiors import crossing, rows, shapes, support
from ..interiors.held import held_airlight, held_lights, lit_from_inside
from ..jit import exact_njit
from ..lights import Lights, at_infinity, cubature, cubature_ladders, environment
from ..media.particles import particle_radiance
from ..methods import Segments, get_method, resolve_params
from ..options import RenderOptions
from ..scene.format import Scene
from ..scene.meshes import exact_spheres, scene_triangles
from ..segments import cone_segments, gather, gather_weights, whole_rays
from ..shading import (STATS_NAMES as SURFACE_NAMES, emissive_shapes, emitted_radiance, facing_normals, first_hits,
                       ground_radiance, shading_normals, surface_radiance)
from ..shadows.frusta import STATS_NAMES, build as build_frusta, exact_lit_intervals, split_lit
from ..shadows import penumbra_airlight
from ..shadows.shadow_rays import shadowed_airlight
from . import aov, compile_ahead, near_emitters

RAYS_PER_TILE = 1 << 13  # about the most rays of one tile (each costs ~1.3 ms of Python around the kernels)
PHASES = 128  # tiles a band of rows is cut into (its pixels dealt out in turn) ...
MIN_TILE_RAYS = 256  # ... or fewer, of at least this many rays each (a tiny render is not 128 tiles of overhead)
SUM_RAYS = 1 << 14  # rays a row of the image may have before a pixel's samples are summed in ranges


@dataclass
class Prepared:
    """Everything about a scene that does not depend on the method: geometry and its accelerator."""
    scene: Scene
    accel: Accelerator
    reflectance: np.ndarray
    lights: Lights
    corner_normals: np.ndarray | None = None  # shading normals at the triangles' corners (None: all flat)
    _frusta: list | None = None
    _through: list | None = None
    shape_ids: np.ndarray | None = None  # each triangle's shape (interiors/shapes.py)
    interior_shapes: np.ndarray | None = None  # the shapes that hold a medium
    interior_planes: dict = field(default_factory=dict)  # convex interiors' face planes (interiors/shapes.py)
    camera_inside: int | None = None  # the shape holding a medium that contains the camera
    lights_on: np.ndarray | None = None  # a light layer's pass (`only`): the lights it keeps (None: all)
    emission: bool = True  # whether camera rays see the background and the emitters themselves (`only`)
    emissive: list = field(default_factory=list)  # the emissive shapes (`Lights.of`'s emitters)
    base: "Prepared | None" = None  # a pixel sample's scene (`seeded`): the one whose other lights' frusta it shares
    _memo: dict = field(default_factory=dict)
    _memo_lock: threading.RLock = field(default_factory=threading.RLock)

    def memo(self, key, build):
        """`build()`, computed once per `key` for this scene (tiles run in threads: under a lock, re-entrant
        because a build may memo its parts, as the sun's faces memo the shape's planes)."""
        with self._memo_lock:
            if key not in self._memo:
                self._memo[key] = build()
            return self._memo[key]

    def frusta(self) -> list:
        """The lights' texel lists of the shadow frusta of the triangles that stop light
        (shapes.blockers), for the exact lit intervals, built once (shadows/frusta.py)."""
        if self._frusta is None:
            self._frusta = self._built(shapes.blockers(self), "frusta")
        return self._frusta

    def through(self) -> list | None:
        """The same of the index-matched interiors' triangles, which attenuate the outside air-light's
        light (shapes.attenuators; None where none need it), built once."""
        mask = shapes.attenuators(self)
        if mask is not None and self._through is None:
            self._through = self._built(mask, "through")
        return None if mask is None else self._through

    def _built(self, select, which: str) -> list:
        """`frusta` (`which`) or `through` of the triangles `select`; a pixel sample's (`base` given) builds its
        environment directions' and takes the other lights' from `base` (built once, under its lock)."""
        if self.base is None:
            return build_frusta(self.accel, self.lights, select=select)
        own = environment.owned(self.lights)
        shared = self.base.memo(which, getattr(self.base, which))
        return [b if o else s for o, b, s in zip(own, build_frusta(self.accel, self.lights, select=select, rows=own),
                                                 shared)]

    def only(self, keep: np.ndarray, emission: bool | None = None) -> "Prepared":
        """This scene lit by the lights `keep` (a boolean mask over `lights`) only, for the output
        layers (rendering/aov.py) and the environment's groups (`shade_groups`): the other lights'
        intensities are zero (their contributions exact zeros, so each light's layer holds the very
        numbers the image adds up) and their segments of the camera's medium are dropped; the
        background and the emitters are seen where `emission` (default: where no light is kept, the
        emission layer); everything else, the shadow frusta included, is shared."""
        self.through()
        view = copy.copy(self)
        view.lights = dataclasses.replace(self.lights, intensity=np.where(keep[:, None], self.lights.intensity, 0.0))
        view.lights_on = keep
        view.emission = not keep.any() if emission is None else emission
        return view

    def view(self, keep: np.ndarray, emission: bool | None = None) -> "Prepared":
        """`only(keep, emission)`, made once per scene."""
        return self.memo(("only", keep.tobytes(), emission), functools.partial(self.only, keep, emission))


@dataclass
class RenderResult:
    image: np.ndarray  # (H, W, 3) float64
    method: str
    params: dict
    seconds: float  # wall time of the render, compile time excluded
    compile_seconds: float
    stats: dict = field(default_factory=dict)
    # (H, W, 3) variance of each pixel's estimate (stochastic methods; any method where area lights'
    # penumbrae are sampled: has_variance)
    variance: np.ndarray | None = None
    passes: int = 1
    # (H, W, 3) float32 |image - exact| <= error_bound (error_bounds.py; inf: unknown); for a stochastic
    # method the bound of all but its estimator's noise, whose standard error is sqrt(variance)
    error_bound: np.ndarray | None = None
    layers: dict = field(default_factory=dict)  # output layers (rendering/aov.py): name -> (H, W, channels)


def prepare(scene: Scene) -> Prepared:
    tris, refl, ids, corners = scene_triangles(scene, shape_ids=True, normals=True)
    emissive = emissive_shapes(scene, tris, ids)
    lights = Lights.of(scene.lights, emissive)
    extent = np.concatenate([lights.position[~lights.distant], scene.camera.position[None, :]])
    inner = np.array([i for i, s in enumerate(scene.shapes) if s.interior is not None], dtype=np.int64)
    prep = Prepared(scene, Accelerator(tris, extent, *exact_spheres(scene, ids)), refl, lights, corners, shape_ids=ids,
                    interior_shapes=inner, emissive=emissive)
    if len(inner):
        prep.camera_inside = shapes.inside_of(prep, scene.camera.position, inner)
    return prep


def adapt_cubature(prep: Prepared, method, params, seed, shadows=False) -> tuple[Prepared, dict, float]:
    """The scene with each emitter's cubature order chosen by the pilot (lights/cubature.py) for a
    method with a tolerance (`Method.tolerance`), the pilot's statistics and the seconds its kernels
    took to compile (`warm_up`, before it, unshadowed; where the render has volumetric `shadows`, their
    kernels compile meanwhile in a second process on an empty kernel cache, and the wait for it after
    the pilot counts too); else `prep`, {} and 0."""
    tol = method.tolerance(params)
    ladders, counts = cubature_ladders(prep.scene.lights, prep.emissive)
    if tol is None or all(l is None for l in ladders):
        return prep, {}, 0.0
    try:
        compile_s = warm_up(prep, method, params, seed, then_shadows=shadows)
        adapted, pilot = _pilot(prep, method, params, seed, tol, ladders, counts)
    except BaseException:
        compile_ahead.settle(stop=True)
        raise
    return adapted, pilot, compile_s + compile_ahead.settle()


def _pilot(prep: Prepared, method, params, seed, tol, ladders, counts) -> tuple[Prepared, dict]:
    """`adapt_cubature`'s scene and statistics, its kernels compiled."""
    scene, cam = prep.scene, prep.scene.camera

    def rays_of(pixels):
        return pixel_rays(cam, pixels[:, 0].astype(float), pixels[:, 1].astype(float), slice(0, 1))

    pixels, near = cubature.pilot_pixels(prep.lights.emitters, ladders, rays_of, cam.width, cam.height)
    o, d = rays_of(pixels)
    keys = (pixels[:, 0] * cam.width + pixels[:, 1]).astype(np.uint64) * np.uint64(cam.spp)

    @functools.lru_cache(maxsize=None)
    def rows_at(orders):
        return dataclasses.replace(prep, lights=Lights.of(scene.lights, prep.emissive, orders, prep.lights.emitters),
                                   _frusta=None,
                                   _through=None, _memo={}, _memo_lock=threading.RLock())

    def shade(orders, rays):
        return shade_rays(rows_at(orders), method, params, o[rays], d[rays], keys[rays], seed)[0]

    orders, capped, n_near, stray = cubature.choose(ladders, counts, near, shade, tol)
    adapted = dataclasses.replace(rows_at(orders), _memo={}, _memo_lock=threading.RLock())  # the frusta shared
    emitters = [s for s, ladder in enumerate(ladders) if ladder is not None]
    n_rows = int(np.count_nonzero(np.isin(adapted.lights.owner, emitters)))
    return adapted, {"cubature: rows": n_rows, "cubature: pilot rays": len(o),
                     "cubature: emitters capped": capped, "cubature: pilot rays near an emitter": n_near,
                     "cubature: pilot rays not converged": stray}


def default_threads() -> int:
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)


def airlight(method, medium, lights, params, segs, n_rays: int):
    """Air-light (N, 3) of the camera rays from their segments, the method's statistics, the
    variance (N, 3) of a stochastic method's estimate (else None) and the error bound (N, 3): the
    method's own segment bounds where it gives them (`Method.airlight`'s third value of a
    deterministic method), else infinite on every ray with a segment; 0 for a stochastic method,
    whose error is its variance."""
    res = method.airlight(segs, medium, lights, params)
    var = gather(segs, res[2], n_rays, medium, power=2) if method.stochastic else None
    tr = gather_weights(segs, medium)  # once for the air-light and its bound
    if method.stochastic:
        bound = np.zeros((n_rays, 3))
    elif len(res) > 2:
        bound = gather(segs, res[2], n_rays, medium, tr=tr)
    else:
        bound = np.where(error_bounds.rays_with(segs.ray, n_rays)[:, None], np.inf, np.zeros((n_rays, 3)))
    if lights.cubature.any():  # area lights' cubature
        bound[error_bounds.rays_with(segs.ray[lights.cubature[segs.light]], n_rays)] = np.inf
    return gather(segs, res[0], n_rays, medium, tr=tr), res[1], var, bound


def sees_emission(prep: Prepared) -> bool:
    """Whether camera rays see the background and the emitters themselves: in every pass but a light
    layer's or an environment group's (`Prepared.only`), whose rays see only those lights' light."""
    return prep.emission


def shade_rays(prep: Prepared, method, params, origins, dirs, keys, seed, shadows: bool = False, depth=0,
               hits=None):
    """Radiance (N, 3) of camera rays, the statistics array (`stats_size`: the method's, the lit
    intervals', the inside integrals', summed over the rays followed behind shapes), for a stochastic
    method the variance (N, 3) of each ray's estimate (else None), and the error bound (N, 3) of each
    ray's radiance (error_bounds.py). `shadows`: False for the paper's unshadowed air-light, True for the
    air-light over the exact lit intervals (shadows/frusta.py).
    Rays entering a shape that holds a medium are taken across its boundary (crossing.cross; `depth`
    boundaries deep): their inside rows are integrated by the method's inside rule (rows.py)
    and the rays going on beyond are shaded here (`_across`). `hits`: the rays' `first_hits`, when
    the caller has them (not changed here)."""
    scene = prep.scene
    medium = scene.medium
    t, prim, ground = (first_hits(prep.accel, medium, origins, dirs) if hits is None
                       else (hits[0].copy(), hits[1].copy(), hits[2]))  # an atmosphere's planet in float64

    n_stats, varies = stats_size(method), has_variance(prep, method)
    deeper = np.zeros(n_stats)  # of the inside integrals and of the rays leaving shapes
    if depth == 0 and prep.camera_inside is not None:  # camera rays start inside a medium (crossing.py)
        boundary = crossing.start_inside(prep, origins, dirs, t, prim, keys)
        rad, var, bound = _across(prep, method, params, boundary, seed, shadows, 0, deeper)
        return rad, deeper, var if varies else None, bound
    radiance = np.zeros((len(origins), 3))
    into = shapes.enters(prep, prim)
    # the rays that hit a surface (not one holding a medium), their points, directions, rows and keys
    n = len(origins)
    surf, points, surf_dirs = np.empty(n, np.int64), np.empty((n, 3)), np.empty((n, 3))
    surf_prim, surf_keys, surf_refl = np.empty(n, np.int64), np.empty(n, keys.dtype), np.empty((n, 3))
    m, entering, missed, grounded = _surface_hits(origins, dirs, t, prim, keys, into, ground, prep.reflectance, surf,
                                                  points, surf_dirs, surf_prim, surf_keys, surf_refl)
    surf, points, surf_dirs, surf_prim, surf_keys, surf_refl = (a[:m] for a in (surf, points, surf_dirs, surf_prim,
                                                                                surf_keys, surf_refl))
    if len(surf):
        normals = facing_normals(prep.accel.hit_normals(surf_prim, points), surf_dirs)
        shading = shading_normals(prep.accel, prep.corner_normals, surf_prim, points, normals)
        surf_var = np.zeros((len(points), 3)) if varies else None  # shading.penumbra's
        radiance[surf] = surface_radiance(prep.accel, points, normals, surf_refl, prep.lights,
                                          medium, shapes.shadow_through(prep), shading, surf_keys, seed, surf_var,
                                          method.tolerance(params), deeper[SURFACE_STATS])
        if held_lights(prep):  # lights inside refractive shapes
            radiance[surf] += lit_from_inside(prep, points, normals, shading, surf_refl)
        if sees_emission(prep) and prep.memo("emits", lambda: any(s.emission is not None for s in scene.shapes)):
            radiance[surf] += emitted_radiance(scene.shapes, prep.shape_ids[surf_prim],
                                               prep.accel.hit_normals(surf_prim, points), surf_dirs)
    if grounded:
        radiance[ground] = ground_radiance(prep.accel, origins[ground], dirs[ground], t[ground], prep.lights, medium)
    if entering:
        boundary = crossing.cross(prep, origins[into], dirs[into], t[into], prim[into], keys[into], depth)
        if boundary is None:  # black by the model (crossing.MAX_DEPTH)
            into_var = into_bound = np.zeros((np.count_nonzero(into), 3))
        else:
            radiance[into], into_var, into_bound = _across(prep, method, params, boundary, seed, shadows, depth,
                                                           deeper)
    if missed and sees_emission(prep):
        miss = (prim < 0) & ~ground
        radiance[miss] = at_infinity(scene.lights, scene.background, dirs[miss])
    tr = medium.transmittance_on(origins, dirs, 0.0, t)
    radiance *= tr
    stats = np.zeros(n_stats)
    variance = np.zeros(radiance.shape) if varies else None
    if len(surf) and variance is not None:
        variance[surf] = surf_var * tr[surf] ** 2
    if entering and variance is not None:
        variance[into] = into_var * tr[into] ** 2
    bound = np.zeros(radiance.shape)
    if len(surf) and prep.lights.cubature.any():  # an area light's cubature on surfaces: no bound
        bound[surf] = np.inf
    if entering:
        bound[into] = crossing.scaled(into_bound, tr[into])
    if len(prep.lights) and prep.memo("scatters", lambda: medium.scatters):
        segs = whole_rays(origins, dirs, t, keys, len(prep.lights), seed, prep.accel.scale)
        held = None
        if held_lights(prep):  # lights inside refractive shapes: their light refracted out
            segs, *held = held_airlight(prep, method, params, segs, len(origins), depth, shadows)
        segs, _ = cone_segments(segs, prep.lights)
        if prep.lights_on is not None:  # a light layer's pass (Prepared.only)
            segs = segs.take(np.nonzero(prep.lights_on[segs.light])[0])
        if shadows and method.samples_shadows(params):
            near = None
            if near_emitters.applies(prep.lights, method, sampled=True):  # a sphere by the method's own estimate
                segs, *near = near_emitters.replaced(prep.lights, method, medium, params, method.tolerance(params),
                                                     segs, segs, (origins, dirs, t, keys, seed), True, radiance,
                                                     (prep.accel, shapes.blockers(prep)))
                stats[NEAR_STATS] = near[1]
            air, var = shadowed_airlight(prep.accel, method, medium, prep.lights, params, segs, len(origins))
            if near is not None:
                air, var = air + near[0], var + near[3]
                bound[near[2]] = np.inf
            if not method.stochastic:  # the shadow-tested samples of raymarch: no bound
                bound[error_bounds.rays_with(segs.ray, len(origins))] = np.inf
        else:
            through = sampled = drawn = None
            if shadows:
                cone = segs
                segs, stats[method.stats_size:method.stats_size + len(STATS_NAMES)] = exact_lit_intervals(
                    prep.accel, segs, prep.lights, len(prep.lights), prep.frusta())
                if prep.through() is not None:  # pieces whose light crosses index-matched interiors
                    segs, through, _ = split_lit(prep.accel, segs, len(prep.lights), prep.through())
                elif penumbra_airlight.applies(prep.lights, method, shadows):  # emitters cut by occluders
                    segs, *sampled = penumbra_airlight.sampled((prep.accel, prep.lights), method, medium, params,
                                                               cone, segs, (origins, dirs, t, keys, seed),
                                                               shapes.blockers(prep))
                elif penumbra_airlight.draws(prep.lights, method, shadows):  # by the method's drawn points
                    segs, drawn = penumbra_airlight.drawn((prep.accel, prep.lights), cone, segs,
                                                          (origins, dirs, t, keys, seed), shapes.blockers(prep))
            near = None
            if near_emitters.applies(prep.lights, method) and (through is None or not len(through)):
                segs, *near = near_emitters.replaced(prep.lights, method, medium, params, method.tolerance(params),
                                                     cone if shadows else segs, segs,
                                                     (origins, dirs, t, keys, seed), shadows, radiance,
                                                     (prep.accel, shapes.blockers(prep)))
                stats[NEAR_STATS] = near[1]
            air, stats[:method.stats_size], var, air_bound = airlight(method, medium, prep.lights, params, segs,
                                                                      len(origins))
            bound += air_bound
            if near is not None:
                air = air + near[0]
                if variance is not None:  # a sphere's pairs sampled where occluders may hide part of it
                    variance = variance + near[3]
                bound[near[2]] = np.inf  # the rule about the foot point: no bound, as the rows'
            if sampled is not None:
                air, variance = air + sampled[0], variance + sampled[1]
                bound[sampled[2]] = np.inf
            if drawn is not None and len(drawn):
                drawn_air, drawn_var = shadowed_airlight(prep.accel, method, medium, prep.lights,
                                                         {**params, "shadow_test": "samples"}, drawn, len(origins))
                air, var = air + drawn_air, var + drawn_var
            if through is not None and len(through):
                through_air, through_var, through_bound = rows.through_airlight(
                    prep, method, params, through, len(origins), stats[-support.STATS_SIZE:])
                air = air + through_air
                if method.stochastic:
                    var = var + through_var
                bound += through_bound
        if held is not None:
            air = air + held[0]
            stats[-support.STATS_SIZE:] += held[3]
            var = var + held[1] if method.stochastic else var
            bound += held[2]
        radiance += air
        if method.stochastic:
            variance = variance + var
    if medium.particles is not None:  # seed 003's particle layer on top of the air-light (no bound)
        glints = particle_radiance(medium.particles, medium, prep.lights, prep.accel, origins, dirs, t, keys,
                                   shadows)
        radiance += glints
        bound[np.any(glints != 0.0, axis=1)] = np.inf
    bound += error_bounds.ROUNDING * np.abs(radiance)  # the float64 closed forms and sums
    return radiance, stats + deeper, variance, bound


@exact_njit
def _surface_hits(origins, dirs, t, prim, keys, into, ground, reflectance, idx, points, d, rows, k, refl):
    """Of rays with first hits (t, prim; `into`: the hit's shape holds a medium, `ground`: the
    medium's ground is hit), those that hit a surface (prim >= 0, not `into`), into the first m
    places of the arrays idx ... refl: their indices, hit points origins + t dirs (rounded as NumPy's
    expression), directions, rows, keys and rows' `reflectance`. Returns m, whether any ray enters a
    shape, how many see the sky (prim < 0, not `ground`) and how many the ground."""
    m, entering, missed, grounded = 0, False, 0, 0
    for i in range(prim.shape[0]):
        entering |= into[i]
        if prim[i] < 0:
            if ground[i]:
                grounded += 1
            else:
                missed += 1
        elif not into[i]:
            idx[m], rows[m], k[m] = i, prim[i], keys[i]
            for a in range(3):
                d[m, a] = dirs[i, a]
                points[m, a] = origins[i, a] + t[i] * dirs[i, a]
                refl[m, a] = reflectance[prim[i], a]
            m += 1
    return m, entering, missed, grounded


def _across(prep: Prepared, method, params, boundary, seed, shadows, depth, stats):
    """Radiance, variance and error bound (N, 3) back along the rays of a boundary crossing
    (crossing.py): its inside rows integrated (rows.py), the rays going on beyond shaded one
    boundary deeper, combined (crossing.combine); their statistics added to `stats`."""
    inner, inner_var, inner_bound, inside = rows.integrate(prep, method, params, boundary.rows, seed, depth,
                                                         shadows)
    stats[-support.STATS_SIZE:] += inside
    if len(boundary.origins):  # from the boundary, their first hits asked past the face they leave
        t, prim, ground = first_hits(prep.accel, prep.scene.medium, boundary.origins + boundary.skip[:, None]
                                     * boundary.dirs, boundary.dirs)
        seen, seen_stats, seen_var, seen_bound = shade_rays(prep, method, params, boundary.origins, boundary.dirs,
                                                            boundary.keys, seed, shadows, depth + 1,
                                                            (t + boundary.skip, prim, ground))
        stats += seen_stats
    else:
        seen = seen_bound = np.zeros((0, 3))
        seen_var = seen if method.stochastic else None
    return crossing.combine(boundary, inner, inner_var, inner_bound, seen, seen_var, seen_bound)


def has_variance(prep: Prepared, method) -> bool:
    """Whether a render has a variance layer: a stochastic method's, the surface term's samples of
    area lights' emitters in penumbrae (shading.penumbra) or an environment light's groups of directions."""
    return (method.stochastic or any(e is not None for e in prep.lights.emitters)
            or prep.memo("environment", lambda: bool(environment.groups(prep.lights))))


NEAR_STATS = slice(-support.STATS_SIZE - len(near_emitters.STATS_NAMES), -support.STATS_SIZE)  # their place in the stats
SURFACE_STATS = slice(NEAR_STATS.start - len(SURFACE_NAMES), NEAR_STATS.start)  # the surface term's


def stats_size(method) -> int:
    """The length of a render's statistics array: the method's, the lit intervals', the surface term's,
    the rays near flat emitters', the inside integrals'."""
    return (method.stats_size + len(STATS_NAMES) + len(SURFACE_NAMES) + len(near_emitters.STATS_NAMES)
            + support.STATS_SIZE)


WARM_UP_GRID = 8  # the warm-up traces the first sample of the pixels of an 8 x 8 grid over the image


WARMED = set()  # (scene file, its size and time, method, parameters, shadows) warmed up in this process


def warm_up(prep: Prepared, method, params, seed, shadows=False, then_shadows=False) -> float:
    """Build the lights' shadow frusta (with `shadows`) and compile the method's kernels on a few rays
    (`warm_up_rays`), so that the tiles compile nothing later; on an empty kernel cache the air-light's
    kernels and those of the media inside shapes compile meanwhile in a second process (compile_ahead.py,
    `compile_airlight`; the rays into those media are shaded here after it; the air-light's kernels it leaves to
    this process compiled here first, `compile_ahead.compile_here`), or, where a warm-up with shadows
    follows this one without (`then_shadows`: the cubature pilot's), the shadows' kernels
    (`compile_shadows`). Returns the seconds it took. Once per scene file (unchanged), method,
    parameters and `shadows` in a process: a later render of the same compiles nothing."""
    path = prep.scene.path
    key = None if path is None or not os.path.isfile(path) else (
        os.path.abspath(path), os.stat(path).st_size, os.stat(path).st_mtime_ns, method.name, repr(sorted(params.items())),
        shadows)
    if key in WARMED:
        if shadows:
            prep.frusta()
        return 0.0
    start = time.perf_counter()
    if then_shadows and not shadows:
        ahead = compile_ahead.start(True, compile_shadows, prep.scene, method.name, seed, later=True)
    else:
        ahead = compile_ahead.start(shadows, compile_airlight, prep.scene, method.name, params, seed)
    try:
        if ahead is not None:  # (the air-light's kernels that the worker leaves to this process)
            compile_ahead.compile_here(method, prep.scene.medium, prep.lights, params)
        _tile_keys(0, 1, 0, 0, 1, 1, 1, 0, np.zeros(1, np.int64), np.zeros(1, np.int64),  # the tiles' pixels and keys
                   np.zeros(1, np.uint64))  # (`render_tile`; before the worker's gate, where this process waits)
        if shadows:
            prep.frusta()  # before the tiles' threads share it
        o, d = warm_up_rays(prep)
        hits = first_hits(prep.accel, prep.scene.medium, o, d)
        if ahead is not None and prep.scene.medium.particles is not None:  # (this process compiles them: here,
            particles_ahead(prep, o, d, hits[0], shadows)  # before the gate, not after the wait)
        later = interiors_ahead(prep, hits[1]) if ahead is not None else np.zeros(len(o), dtype=bool)
        for part in (~later, later):  # the rays into media inside shapes after the worker (it compiles their kernels)
            if part is later and np.any(later):
                if shadows:  # their lit intervals' kernels here, before the wait (without a medium outside, the
                    shadow_kernels(prep, method.name, seed)  # rays before compiled none)
                ahead.wait()
            if np.any(part):
                radiance = shade_rays(prep, method if ahead is None else compile_ahead.Gated(method, ahead), params,
                                      o[part], d[part], np.zeros(np.count_nonzero(part), dtype=np.uint64), seed,
                                      shadows, hits=tuple(a[part] for a in hits))[0]
                sum_samples(radiance, 1)  # the tiles' sums over their samples
    except BaseException:
        if ahead is not None:
            ahead.wait(stop=True)
        raise
    if ahead is not None:
        ahead.wait()
    if key is not None:
        WARMED.add(key)
    return time.perf_counter() - start


def warm_up_rays(prep: Prepared):
    """Origins and directions of the warm-up's rays: the first sample of the pixels of a grid over the
    image (so that rays into a spot's cone or through a refracting surface are among them; each pixel once
    where the image is narrower than the grid) and one at each shape holding a medium."""
    cam, n = prep.scene.camera, WARM_UP_GRID
    ys, xs = np.meshgrid(np.unique(np.arange(n) * cam.height // n), np.unique(np.arange(n) * cam.width // n),
                         indexing="ij")
    o, d = pixel_rays(cam, ys.ravel().astype(float), xs.ravel().astype(float), slice(0, 1))
    return crossing.warm_up_rays(prep, o, d)


def compile_airlight(scene: Scene, method_name: str, params: dict, seed: int):
    """compile_ahead's worker: the air-light's kernels (the method's and their gathering, `airlight`) on one
    segment per light (`axis_segments`), not on the warm-up's rays: the camera rays', first hits', surfaces'
    and cone cuts' kernels, which the warm-up compiles meanwhile in the render's process, are not compiled
    here too (the air-light's kernels take the same argument types from these segments as from the
    warm-up's), and a scene without shapes that emit or hold a medium is not even prepared (its meshes
    loaded, their accelerator built: the lights suffice); then the inside integrals of the rays into media
    inside shapes (`interiors_ahead`: their boundary crossing and their inside rows, not the rays beyond
    them), which the render's warm-up shades after this worker. Where the camera is inside a medium, the
    warm-up's rays shaded from there (crossing.start_inside). The air-light's kernels that the render's process
    compiles meanwhile (`compile_ahead.compile_here`) are left out (`compile_ahead.ahead`)."""
    method = compile_ahead.ahead(get_method(method_name))
    prep = prepare(scene) if any(s.interior is not None or s.emission is not None for s in scene.shapes) else None
    if prep is not None and prep.camera_inside is not None:
        o, d = warm_up_rays(prep)
        shade_rays(prep, method, params, o, d, np.zeros(len(o), dtype=np.uint64), seed)
        return
    lights = Lights.of(scene.lights, []) if prep is None else prep.lights
    if len(lights) and scene.medium.scatters:
        airlight(method, scene.medium, lights, params, axis_segments(scene.camera, lights, seed), 1)
    if prep is None:
        return
    o, d = warm_up_rays(prep)
    keys = np.zeros(len(o), dtype=np.uint64)
    t, prim, _ = first_hits(prep.accel, scene.medium, o, d)
    into = interiors_ahead(prep, prim)
    if np.any(into):
        boundary = crossing.cross(prep, o[into], d[into], t[into], prim[into], keys[into], 0)
        if boundary is not None:
            rows.integrate(prep, method, params, boundary.rows, seed, 0, False)


def axis_segments(camera, lights: Lights, seed: int) -> Segments:
    """One segment per light along a line of sight near the camera's axis (tilted off it: not through a light
    placed on the axis), from a quarter of the scene's size (the lights' and the camera's distance from the
    origin) to its end: a piece of a camera ray (t0 > 0), as the lit intervals' are, so that `gather` weighs it
    by the transmittance before it as it weighs theirs."""
    forward, right, up = basis(camera)
    n = len(lights)
    scale = float(np.max(np.abs(np.concatenate([lights.position[~lights.distant], [camera.position]])))) or 1.0
    d = forward + 0.0123 * right + 0.0311 * up
    d = np.tile(d / np.linalg.norm(d), (n, 1))
    t0 = np.full(n, 0.25 * scale)
    light = np.arange(n, dtype=np.int64)
    return Segments(camera.position + t0[:, None] * d, d, np.full(n, 0.75 * scale), light, np.zeros(n, np.int64), t0,
                    np.zeros(n, np.uint64), light.copy(), int(seed), scale)


def particles_ahead(prep: Prepared, origins, dirs, t, shadows: bool):
    """The particle layer's kernels (`particle_radiance`) on the warm-up's rays, compiled in this process before
    the compile worker's gate: `shade_rays` adds the layer after the air-light, which waits for the worker, so
    that this process compiled them after the wait (the worker does not: they are no air-light's)."""
    particle_radiance(prep.scene.medium.particles, prep.scene.medium, prep.lights, prep.accel, origins, dirs, t,
                      np.zeros(len(origins), dtype=np.uint64), shadows)


def interiors_ahead(prep: Prepared, prim) -> np.ndarray:
    """Which warm-up rays (their first hits `prim`) enter media inside shapes whose kernels the compile
    worker compiles (`compile_airlight`): all that enter one, where the camera is outside every medium
    (else the worker's rays start inside one and the render's process compiles them)."""
    if prep.camera_inside is not None:
        return np.zeros(len(prim), dtype=bool)
    return shapes.enters(prep, prim)


def compile_shadows(scene: Scene, method_name: str, seed: int):
    """compile_ahead's worker beside the cubature pilot's warm-up: the kernels of the exact lit
    intervals (the frusta, `exact_lit_intervals`) and of the penumbrae's pieces (`penumbra_airlight.
    lit_pieces`), without their air-light (which the pilot's warm-up compiles), on one segment per
    light along the camera's axis: the camera rays', first hits' and cone cuts' kernels, which the
    pilot's warm-up compiles meanwhile, are not compiled here too (the lit intervals' kernels take
    the same argument types from these segments as from the warm-up's)."""
    prep = prepare(scene)
    o = np.array([prep.scene.camera.position], np.float64)
    d = np.array([basis(prep.scene.camera)[0]], np.float64)
    lit_kernels(prep, method_name, whole_rays(o, d, np.array([prep.accel.scale]), np.zeros(1, dtype=np.uint64),
                                              len(prep.lights), seed, prep.accel.scale))


def shadow_kernels(prep: Prepared, method_name: str, seed: int):
    """`compile_shadows`' kernels, in this process, on the warm-up's rays."""
    o, d = warm_up_rays(prep)
    t, _, _ = first_hits(prep.accel, prep.scene.medium, o, d)
    segs, _ = cone_segments(whole_rays(o, d, t, np.zeros(len(o), dtype=np.uint64), len(prep.lights), seed,
                                       prep.accel.scale), prep.lights)
    lit_kernels(prep, method_name, segs)


def lit_kernels(prep: Prepared, method_name: str, segs):
    """The lit intervals' kernels (and the penumbrae's pieces', where they apply) on the segments `segs`."""
    exact_lit_intervals(prep.accel, segs, prep.lights, len(prep.lights), prep.frusta())
    if penumbra_airlight.applies(prep.lights, get_method(method_name), True):
        penumbra_airlight.lit_pieces(prep.accel, prep.lights, segs, 1, shapes.blockers(prep))


def check_options(method, params, volumetric_shadows, source, lights, medium):
    if method.samples_shadows(params) and not volumetric_shadows:
        raise UserError(f"{source}: --shadow-test samples (render.shadow_test): only acts with volumetric shadows, "
                        "which are off in this render; remove it")
    if method.samples_shadows(params) and not medium.homogeneous:
        raise UserError(f"{source}: --shadow-test samples (render.shadow_test): not implemented in {medium.type_name} "
                        "media; use --shadow-test intervals (the default)")


@dataclass(frozen=True)
class Tile:
    """One task of a render: of the band of image rows `rows` (of the render's columns), the pixels
    `pixels` of its raster order (phase::stride: spread evenly over the band) x the pixel samples
    `samples`."""
    rows: slice
    pixels: slice
    samples: slice


@dataclass(frozen=True)
class Task:
    """What every tile of one render shares besides the prepared scene (small and picklable: a
    cluster's tasks carry it): the method, its resolved parameters, the seed, `shadows` (whether the
    air-light is shadowed: volumetric shadows), the
    pixel block `box` = (x0, y0, x1, y1) and the output layers `aov` (aov.NAMES) beside the image."""
    method: str
    params: dict
    seed: int
    shadows: bool
    box: tuple
    aov: tuple = ()


def sample_ranges(cam) -> list[slice]:
    """The ranges a pixel's samples are summed in, each in sample order, then added in range order:
    all of them, or SUM_RAYS // width at a time when a row of the whole image has more rays (the
    earlier tiles of whole rows; kept so that every pixel is the same sum in the same order)."""
    n = cam.spp if cam.width * cam.spp <= SUM_RAYS else max(1, SUM_RAYS // cam.width)
    return [slice(s, min(s + n, cam.spp)) for s in range(0, cam.spp, n)]


def tiles(cam, box, by_sample: bool = False) -> list[Tile]:
    """The tasks of a render of the pixel block `box` = (x0, y0, x1, y1): bands of rows of about
    PHASES x RAYS_PER_TILE rays, each cut into PHASES tiles (fewer in a band of fewer than
    PHASES x MIN_TILE_RAYS rays) that take every PHASES-th pixel of its raster order, per sample
    range. A tile is a sample of the whole band, so no tile holds much more than 1/PHASES of a
    band's work even where it lies in a few rows (benchmarks/scenes/sun_over_height_fog.toml: 79 %
    in its horizon row); nothing depends on the thread or worker count. `by_sample` (an environment light,
    whose directions and their frusta are a pixel sample's: `seeded`): every range one sample, the whole
    image's tiles sample after sample, so that the tiles in flight need few samples and each sample's
    frusta are built once."""
    x0, y0, x1, y1 = box
    ranges = [slice(s, s + 1) for s in range(cam.spp)] if by_sample else sample_ranges(cam)
    n = cam.spp if by_sample else ranges[0].stop - ranges[0].start
    band = max(1, PHASES * RAYS_PER_TILE // ((x1 - x0) * n))
    bands = []  # (rows, pixels, stride)
    for r in range(y0, y1, band):
        rows = slice(r, min(r + band, y1))
        pixels = (rows.stop - rows.start) * (x1 - x0)
        per_tile = 1 if by_sample else n  # a tile's samples of a pixel
        bands.append((rows, pixels, max(1, min(PHASES, pixels, pixels * per_tile // MIN_TILE_RAYS))))
    if by_sample:
        return [Tile(rows, slice(k, pixels, stride), s) for s in ranges for rows, pixels, stride in bands
                for k in range(stride)]
    return [Tile(rows, slice(k, pixels, stride), s) for rows, pixels, stride in bands for k in range(stride)
            for s in ranges]


def sum_samples(values: np.ndarray, samples: int) -> np.ndarray:
    """(pixels, k) sums of (pixels x samples, k) per-ray values: each pixel's samples added in sample
    order (as the earlier tiles' numpy sum over them did)."""
    total = np.empty((len(values) // samples, values.shape[1]))
    _sum_samples(values, samples, total)
    return total


@exact_njit
def _sum_samples(values, samples, out):
    """out[p] = values[p S] + values[p S + 1] + ... (S = samples), added in that order: the bits of
    the NumPy loop it replaced (a copy of the first sample, then += each next one)."""
    for p in range(out.shape[0]):
        for c in range(out.shape[1]):
            total = values[p * samples, c]
            for k in range(1, samples):
                total += values[p * samples + k, c]
            out[p, c] = total


_method = functools.lru_cache(maxsize=None)(get_method)  # every tile asks: the registry's imports once


def render_tile(prep: Prepared, task: Task, tile: Tile, every_tile: bool = True):
    """The tile's radiance summed over its samples (pixels, 3), its statistics, for a stochastic
    method its summed variance (else None), its summed error bound and its output layers' summed
    columns (pixels, aov.width; None without layers): a function of the arguments alone, the same
    whichever thread or cluster worker computes it. `every_tile`: this process runs every tile of the
    render (False: a cluster worker, given some), which says when a pixel sample's view is done (`seeded`)."""
    cam = prep.scene.camera
    x0, _, x1, _ = task.box
    n = tile.samples.stop - tile.samples.start
    q = range(tile.pixels.stop)[tile.pixels]  # the pixels' places in the band's raster order
    ys, xs, keys = np.empty(len(q), np.int64), np.empty(len(q), np.int64), np.empty(len(q) * n, np.uint64)
    _tile_keys(q.start, q.step, tile.rows.start, x0, x1 - x0, cam.width, cam.spp, tile.samples.start, ys, xs, keys)
    o, d = pixel_rays(cam, ys, xs, tile.samples)
    method = _method(task.method)
    if prep.memo("environment", lambda: bool(environment.groups(prep.lights))):  # the views' lights share its rows
        uses = tile_uses(prep, task.box) if every_tile else None
        rad, stats, var, bound, layers = _sample_by_sample(prep, method, task, tile, o, d, keys, uses)
    else:
        hits = first_hits(prep.accel, prep.scene.medium, o, d) if task.aov else None  # the layers' too
        rad, stats, var, bound = shade_rays(prep, method, task.params, o, d, keys, task.seed, task.shadows, hits=hits)
        layers = None if not task.aov else layer_columns(prep, method, task, o, d, keys, hits)
    layers = None if layers is None else sum_samples(layers, n)
    return sum_samples(rad, n), stats, None if var is None else sum_samples(var, n), sum_samples(bound, n), layers


@exact_njit
def _tile_keys(first, step, row, x0, width, image_width, spp, sample, ys, xs, keys):
    """The image rows `ys` and columns `xs` of a tile's pixels (the band's raster order from `first`, every
    `step`-th, `width` columns from x0, the band's first row `row`) and the rng.py keys of their samples
    (pixel (y image_width + x) spp + s for the samples s from `sample`, pixel after pixel), in one GIL-free
    pass."""
    n = keys.shape[0] // ys.shape[0] if ys.shape[0] else 0
    for i in range(ys.shape[0]):
        q = first + i * step
        ys[i], xs[i] = row + q // width, x0 + q % width
        for s in range(n):
            keys[i * n + s] = np.uint64(ys[i] * image_width + xs[i]) * np.uint64(spp) + np.uint64(sample + s)


def _sample_by_sample(prep: Prepared, method, task: Task, tile: Tile, origins, dirs, keys, uses):
    """`shade_rays`' four values and the layers' columns (None without layers) of the tile's rays (pixel by
    pixel, `tile.samples` each) with an environment light: each pixel sample index s its own directions
    (`seeded`, shared with the other tiles of that sample and dropped after the last: `uses`, `tile_uses`'
    counts, or None on a cluster's worker), their groups shaded apart (`shade_groups`); the statistics added
    in sample order."""
    n = tile.samples.stop - tile.samples.start
    out = [np.zeros((len(keys), 3)) for _ in range(3)]
    layers, stats = None, 0.0
    for j in range(n):
        at, sample = slice(j, None, n), tile.samples.start + j
        view = seeded(prep, task.seed, sample, task.shadows, ("tiles", None if uses is None else uses[sample]))
        try:
            o, d, k = origins[at], dirs[at], keys[at]
            hits = first_hits(view.accel, view.scene.medium, o, d)  # shared by the passes
            rad, st, var, bound = shade_groups(view, environment.groups(view.lights), method, task.params, o, d, k,
                                               task.seed, task.shadows, hits)
            for total, value in zip(out, (rad, var, bound)):
                total[at] = value
            stats = stats + st
            if task.aov:
                cols = layer_columns(view, method, task, o, d, k, hits)
                layers = np.zeros((len(keys), cols.shape[1])) if layers is None else layers
                layers[at] = cols
        finally:
            release(prep, task.seed, sample, "tiles")
    return out[0], stats, out[1], out[2], layers


def tile_uses(prep: Prepared, box) -> collections.Counter:
    """pixel sample -> how many tiles of a render of `box` shade that sample (`tiles`, one sample a tile with an
    environment), once per camera."""
    cam = prep.scene.camera
    return prep.memo(("tile uses", box, cam.width, cam.height, cam.spp), lambda: collections.Counter(
        s for t in tiles(cam, box, by_sample=True) for s in range(t.samples.start, t.samples.stop)))


def shade_groups(prep: Prepared, split: list, method, params, origins, dirs, keys, seed, shadows, hits):
    """`shade_rays`' four values with an environment light, the G groups of its directions (`split`:
    environment.groups' masks) shaded apart: a pass (`Prepared.view`) per group and one of the other lights
    and the emission, added up in that order. The variance is the other lights' plus the groups' spread
    G / (G - 1) sum_g (P_g - P / G)^2, P_g a group's radiance and P their sum (the variance of the sum of G
    independent unbiased estimates of P / G, from their sample variance); a stochastic method's own variance
    of a group's rows is part of that spread, so not added."""
    rest = prep.view(~np.any(split, axis=0), emission=True)
    rad, stats, var, bound = shade_rays(rest, method, params, origins, dirs, keys, seed, shadows, hits=hits)
    parts = []
    for keep in split:
        part, part_stats, _, part_bound = shade_rays(prep.view(keep), method, params, origins, dirs, keys, seed,
                                                     shadows, hits=hits)
        rad, stats, bound = rad + part, stats + part_stats, bound + part_bound
        parts.append(part)
    parts = np.array(parts)
    G = len(parts)
    spread = G / (G - 1) * np.sum((parts - parts.sum(axis=0) / G) ** 2, axis=0)
    return rad, stats, spread if var is None else var + spread, bound


def seeded(prep: Prepared, seed: int, sample: int, shadows: bool = False, band: tuple | None = None) -> Prepared:
    """`prep` with the environment light's directions of the pixel sample `sample` for `seed`
    (environment.seeded; `prep` itself where they are the same), their shadow frusta its own and the other
    lights' `prep`'s (`Prepared.base`), built here with `shadows` (once, before any view of it copies it:
    `shade_groups`' passes and the layers' views share them). `band` = (key, uses): one use of the view shared
    by the calls with that key, each ended by `release`. With `uses` a count (the tiles of a sample in a render
    that runs them all: `tile_uses`) the view is dropped after the last; with None (a cluster worker, given some
    of the tiles, sample after sample) it is kept while a use is in flight and dropped when a use of another
    sample starts (one that comes back later builds it again, the same). Without `band`, kept while `seed` is
    the last seed."""
    key = (None if band is None else band[0], sample)
    with prep._memo_lock:
        views = _views(prep, seed)
        if key not in views:
            lights = environment.seeded(prep.lights, prep.scene.lights, seed, sample)
            views[key] = [prep if lights is prep.lights else dataclasses.replace(
                prep, lights=lights, base=prep, _frusta=None, _through=None, _memo={}, _memo_lock=threading.RLock()),
                None if band is None else band[1], 0]  # view, uses left (None: unknown), uses in flight
        views[key][2] += 1
        if band is not None and band[1] is None:
            for other in [k for k, (_, left, busy) in views.items() if k[0] == key[0] and k != key and left is None
                          and busy <= 0]:
                _drop(prep, views, other)
        view = views[key][0]
    if shadows:
        view.memo("frusta", view.frusta)  # under the view's lock: a tile of another sample does not wait
    return view


def release(prep: Prepared, seed: int, sample: int, key):
    """One use of `seeded(prep, seed, sample, band=(key, uses))` done: the view is dropped after the last of
    `uses` (see `seeded` for None)."""
    with prep._memo_lock:
        views = _views(prep, seed, create=False)
        entry = views.get((key, sample))
        if entry is not None:
            entry[2] -= 1
            if entry[1] is not None:
                entry[1] -= 1
                if entry[1] <= 0:
                    _drop(prep, views, (key, sample))


def forget(prep: Prepared, seed: int):
    """A render of `seed` over (finished or stopped: Ctrl-C, an error): the views of `seed` in no use now are
    dropped, the others after their uses in flight."""
    with prep._memo_lock:
        views = _views(prep, seed, create=False)
        for key, entry in list(views.items()):
            if entry[2] <= 0:
                _drop(prep, views, key)
            else:
                entry[1] = entry[2]


def _views(prep: Prepared, seed: int, create: bool = True) -> dict:
    """The views of `seed` (`seeded`): key -> [view, uses left, uses in flight]; another seed's are dropped
    (`create`) or left ({} returned)."""
    last = prep._memo.get("seeded")
    if last is None or last[0] != seed:
        if not create:
            return {}
        last = prep._memo["seeded"] = (seed, {})
    return last[1]


def _drop(prep: Prepared, views: dict, key):
    """The view under `key` forgotten (`_views`' entry removed, its memo cleared)."""
    view = views.pop(key)[0]
    if view is not prep:  # its passes' views (copies sharing the memo) hold it in a cycle: freed now
        view._memo.clear()


def layer_columns(prep: Prepared, method, task: Task, origins, dirs, keys, hits) -> np.ndarray:
    """The output layers' columns (N, aov.width) of camera rays: their first hits' depth, normal and
    albedo, and each light's radiance and the emission (the rays shaded again by `Prepared.only`,
    the views made once per scene); `hits` the rays' `first_hits`."""
    cols = [aov.hit_columns(prep, task.aov, origins, dirs, hits)]
    if "lights" in task.aov:
        for keep in aov.light_masks(prep.lights):
            cols.append(shade_rays(prep.view(keep), method, task.params, origins, dirs, keys, task.seed, task.shadows,
                                   hits=hits)[0])
    return np.concatenate(cols, axis=1)


def prepare_task(prep: Prepared, task: Task) -> float:
    """Build what the tiles of `task` share (the lights' shadow maps) and compile the method's
    kernels; returns the seconds the compilation took."""
    return warm_up(prep, get_method(task.method), task.params, task.seed, task.shadows)


class Threads:
    """The executor of one machine: the tiles on `threads` threads (default: every core), each taking
    the next tile not yet taken. An executor has `prepare(prep, task)` (returns the compile seconds,
    before the timed render) and `map(prep, task, work)`, a generator of (index in `work`,
    render_tile's result) in any order; `render` closes it when it stops early (Ctrl-C, a callback's
    or a tile's exception), and then no further tile starts.

    The threads are daemon threads and a closed map does not wait for the tiles in flight (a tile
    may run for seconds): Ctrl-C returns at once, and the process may exit meanwhile. Their results
    go nowhere but the abandoned queue; nothing is written outside it."""

    def __init__(self, threads: int | None = None):
        self.threads = threads

    def prepare(self, prep: Prepared, task: Task) -> float:
        return prepare_task(prep, task)

    def map(self, prep: Prepared, task: Task, work: list[Tile]):
        todo = iter(range(len(work)))  # shared: next() under `taking`
        taking, stop, finished = threading.Lock(), threading.Event(), queue.SimpleQueue()

        def run():
            while not stop.is_set():
                with taking:
                    i = next(todo, None)
                if i is None:
                    return
                try:
                    finished.put((i, render_tile(prep, task, work[i]), None))
                except BaseException as exc:  # handed to the consumer, which raises it
                    finished.put((i, None, exc))
                    return

        for k in range(min(self.threads or default_threads(), len(work))):
            threading.Thread(target=run, name=f"tile-{k}", daemon=True).start()
        try:
            for _ in work:
                i, result, exc = finished.get()
                if exc is not None:
                    raise exc
                yield i, result
        finally:  # done, Ctrl-C, the generator closed (GeneratorExit) or a tile's error
            stop.set()
            forget(prep, task.seed)  # the views of samples whose tiles will not run


class Accumulator:
    """Tile results reduced in one fixed order whatever order they arrive in: a band's pixel sums of
    each sample range are gathered, then its ranges added in sample order (each pixel the same sum
    as in the earlier tiles of whole rows), the statistics in tile order; the error bound is the
    mean of the samples' bounds."""

    def __init__(self, work: list[Tile], box, spp: int, stochastic: bool, stats_size: int, layers: int = 0):
        x0, self.y0, x1, y1 = box
        self.work, self.spp, self.width = work, spp, x1 - x0
        self.image = np.zeros((y1 - self.y0, x1 - x0, 3))
        self.layers = np.zeros((y1 - self.y0, x1 - x0, layers)) if layers else None  # output layers' columns
        self.variance = np.zeros_like(self.image) if stochastic else None
        self.bound = np.zeros(self.image.shape, dtype=np.float32)  # rounded up: still a bound, half the memory
        self._left = collections.Counter(t.rows.start for t in work)  # first row of a band -> tiles to come
        self._pending = {}  # first row of a band -> {first sample: [radiance, variance, bound, layers] sums}
        self._stats = [np.zeros(stats_size)] * len(work)

    def add(self, i: int, result) -> slice | None:
        """Add tile `i`'s result; returns the rows of the image (relative to the block) that it
        finished, or None while some of their tiles are still to come."""
        tile = self.work[i]
        rad, self._stats[i], var, bound, layers = result
        band = tile.rows.start
        parts = self._pending.setdefault(band, {})
        if tile.samples.start not in parts:
            shape = ((tile.rows.stop - band) * self.width, 3)
            parts[tile.samples.start] = [np.zeros(shape), None if var is None else np.zeros(shape), np.zeros(shape),
                                         None if layers is None else np.zeros((shape[0], layers.shape[1]))]
        for total, value in zip(parts[tile.samples.start], (rad, var, bound, layers)):
            if value is not None:
                total[tile.pixels] = value
        self._left[band] -= 1
        if self._left[band]:
            return None
        del self._pending[band]
        order = [[a.reshape(-1, self.width, a.shape[1]) if a is not None else None for a in parts[k]]
                 for k in sorted(parts)]
        block = slice(band - self.y0, tile.rows.stop - self.y0)
        _mean([r for r, _, _, _ in order], self.spp, self.image[block])
        if self.variance is not None:  # variance of the pixel mean of independent per-ray estimates
            _mean([v for _, v, _, _ in order], self.spp**2, self.variance[block])
        error_bounds.add_up(self.bound[block], functools.reduce(np.add, [b for _, _, b, _ in order]), self.spp)
        if self.layers is not None:
            _mean([a for _, _, _, a in order], self.spp, self.layers[block])
        return block

    def totals(self) -> np.ndarray:
        totals = np.zeros_like(self._stats[0])
        for s in self._stats:
            totals += s
        return totals


def _mean(parts: list, divide, out: np.ndarray):
    """out = (parts[0] + parts[1] + ...) / divide, added in that order (`Accumulator`'s sample ranges), in
    place: no image-sized temporaries."""
    if len(parts) == 1:
        np.divide(parts[0], divide, out=out)
        return
    np.add(parts[0], parts[1], out=out)
    for part in parts[2:]:
        np.add(out, part, out=out)
    np.divide(out, divide, out=out)


def check(prep: Prepared, method_name: str, given_params: dict, options: RenderOptions, source: str) -> dict:
    """What `render` checks before its first tile, without rendering: the method's parameters
    (resolved and returned), its medium, lights and options and the media inside shapes on the
    prepared scene; UserError naming the first refusal."""
    method = get_method(method_name)
    params = resolve_params(method, given_params, source)
    method.check_medium(prep.scene.medium, source)
    method.check(prep.scene.medium, params)
    method.check_lights(support.outside_lights(prep), source)
    check_options(method, params, options.volumetric_shadows, source, prep.lights, prep.scene.medium)
    support.check(prep, method, params, source, options.shadows)
    return params


COMPILE_NOTICE = 1.0  # seconds of compiling before it is announced


def noticed(work, notice=None):
    """`work()` (it compiles the kernels of the scene's kinds on first use), telling `notice` when it
    takes longer than COMPILE_NOTICE seconds and then how long it took."""
    if notice is None:
        return work()
    said = threading.Event()

    def say():
        said.set()
        notice("compiling kernels (first use of this scene's kinds)...")

    timer = threading.Timer(COMPILE_NOTICE, say)
    timer.daemon = True
    start = time.perf_counter()
    timer.start()
    try:
        result = work()
    finally:
        timer.cancel()
        timer.join()  # a notice being said is finished first
    if said.is_set():
        notice(f"compiled in {time.perf_counter() - start:.1f} s")
    return result


def render(prep: Prepared, method_name: str, given_params: dict | None = None,
           options: RenderOptions = RenderOptions(), executor=None, source: str = "render") -> RenderResult:
    """Render the image, or the pixel block `options.crop` of it (the same samples and random numbers
    as in the whole image), with `options`' seed, spp and size and volumetric shadows. The tiles run
    on `executor` (default: `Threads(options.threads)`); `options.progress(done, total)` gets the
    tiles finished and `options.observer(y0, y1, x0, x1, block)` every block of rows as soon as it is
    final, each pixel once; `options.notice(line)` gets a line when compiling the kernels takes
    longer than COMPILE_NOTICE seconds, and one when it is done. `given_params` are the method's own
    parameters (any other key is refused). The result does not depend on the executor, its threads
    or workers."""
    scene = prep.scene
    method = get_method(method_name)
    params = check(prep, method_name, given_params or {}, options, source)
    cam = scene.camera
    options.apply_camera(cam)
    box = options.crop or (0, 0, cam.width, cam.height)
    task = Task(method.name, params, options.seed, options.shadows, box, options.aov)
    work = tiles(cam, box, by_sample=bool(environment.groups(prep.lights)))
    acc = Accumulator(work, box, cam.spp, has_variance(prep, method), stats_size(method), aov.width(task.aov, aov.sources(prep.lights)))
    executor = executor if executor is not None else Threads(options.threads)
    pilot_start = time.perf_counter()

    def first_use():  # the kernels compiled on first use: the cubature pilot's warm-up, then the tiles'
        adapted, pilot, compile_s = adapt_cubature(prep, method, params, options.seed, options.shadows)
        pilot_s = time.perf_counter() - pilot_start - compile_s  # counted in the render's seconds
        return adapted, pilot, pilot_s, compile_s + executor.prepare(adapted, task)
    prep, pilot, pilot_s, compile_s = noticed(first_use, options.notice)
    start = time.perf_counter() - pilot_s
    with contextlib.closing(executor.map(prep, task, work)) as results:  # an exception here stops the tiles
        for n, (i, result) in enumerate(results, 1):
            rows = acc.add(i, result)
            if rows is not None and options.observer is not None:
                options.observer(box[1] + rows.start, box[1] + rows.stop, box[0], box[2], acc.image[rows])
            if options.progress is not None:
                options.progress(n, len(work))
    seconds = time.perf_counter() - start
    totals = acc.totals()
    summary = method.summarize(totals[:method.stats_size])
    if task.shadows:
        summary.update({f"shadows: {k}": int(v) for k, v in zip(STATS_NAMES, totals[method.stats_size:])})
    if near_emitters.applies(prep.lights, method):
        summary.update({f"cubature: {k}": int(v) for k, v in zip(near_emitters.STATS_NAMES, totals[NEAR_STATS])})
    if any(e is not None and e.irradiance is not None for e in prep.lights.emitters):
        summary.update({f"surface: {k}": int(v) for k, v in zip(SURFACE_NAMES, totals[SURFACE_STATS])})
    summary.update(support.summarize(prep, method, totals[-support.STATS_SIZE:], task.shadows))
    summary.update(error_bounds.summary(acc.bound))
    summary.update(pilot)
    layers = {} if acc.layers is None else aov.split(task.aov, aov.sources(prep.lights), acc.layers)
    return RenderResult(acc.image, method.name, params, seconds, compile_s, summary, acc.variance,
                        error_bound=acc.bound, layers=layers)
