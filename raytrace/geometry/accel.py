"""Embree through embreex: batched first-hit and occlusion queries.

The only module that imports embreex. Rays cross into Embree as float32; what comes back is
refined in float64: the hit distance is recomputed exactly on the hit triangle's plane, so hit
points, normals and every radiometric quantity after them are float64. Shadow rays are offset by
an epsilon proportional to the scene's size. Embree treats coordinates beyond ~1.8e18 as infinite:
a scene larger than 2^40 (or smaller than 2^-40) crosses the boundary divided by a power of two
(`unit`, exact), so 1e30-metre scenes intersect as 1-metre ones. embreex releases the GIL in its
batch loop from 4.4 on (pyproject requires it; 2.17's holds it), so the renderer's tile threads
query Embree at once and `threads > 1` splits a batch over a thread pool. Every scene of a process
shares one Embree device (`_device`). Exact spheres (sphere.py) are intersected beside Embree in
float64 at every query: the nearest of both hits wins, occlusion is either's.
"""
from __future__ import annotations

import math
import os
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..jit import njit
from .shadow_rays import shadow_rays_into
from .sphere import nearest_sphere_hits, sphere_blocks

CHUNK = 1 << 15
UNIT_RANGE = 2.0 ** 40  # scenes whose size lies outside [1 / UNIT_RANGE, UNIT_RANGE] are rescaled for Embree


_DEVICE: dict = {}  # process id -> the Embree device every scene of that process shares
_DEVICE_LOCK = threading.Lock()


def _device():
    """The process's one Embree device. embreex makes a device per scene unless given one; after
    ~2000 renders in one process (each scene's device created and destroyed, each render's tiles on
    a new thread) Embree crashed in scene construction (twice in the fuzzer's slow runs, not
    reproducible on demand); Embree's documentation advises one device per application. Keyed by
    process id: a forked worker makes its own."""
    pid = os.getpid()
    with _DEVICE_LOCK:
        if pid not in _DEVICE:
            from embreex import rtcore

            _DEVICE.clear()
            _DEVICE[pid] = rtcore.EmbreeDevice()
        return _DEVICE[pid]


class Accelerator:
    def __init__(self, triangles: np.ndarray, extent_points: np.ndarray | None = None,
                 spheres: np.ndarray | None = None, sphere_of: np.ndarray | None = None):
        """`triangles`: (T, 3, 3) float64. `extent_points`: more points (camera, lights) that set the
        scale of the shadow-ray offset together with the geometry. `spheres`: (S, 4) exact spheres
        (centre, radius) and `sphere_of` (T,) the sphere whose mesh each row is (-1: a triangle that
        Embree intersects); a sphere's hits are reported on its first row (sphere.py)."""
        self.triangles = np.ascontiguousarray(triangles, dtype=np.float64)
        e1 = self.triangles[:, 1] - self.triangles[:, 0]
        e2 = self.triangles[:, 2] - self.triangles[:, 0]
        n = np.cross(e1, e2)
        norm = np.linalg.norm(n, axis=1)
        self.normals = n / np.where(norm > 0, norm, 1.0)[:, None]
        pts = self.triangles.reshape(-1, 3)
        if extent_points is not None and len(extent_points):
            pts = np.concatenate([pts, np.asarray(extent_points, dtype=np.float64).reshape(-1, 3)])
        self.scale = (float(np.max(np.abs(pts))) if len(pts) else 0.0) or 1.0
        self.epsilon = 1e-5 * max(self.scale, 1e-6)
        self.unit = 1.0 if 1.0 / UNIT_RANGE <= self.scale <= UNIT_RANGE else 2.0 ** round(math.log2(self.scale))
        self.ids = np.arange(len(self.triangles))  # each triangle's index in the scene (`subset`)
        self.spheres = np.zeros((0, 4)) if spheres is None else np.ascontiguousarray(spheres, dtype=np.float64)
        self.sphere_of = np.full(len(self.triangles), -1, dtype=np.int64) if sphere_of is None else \
            np.asarray(sphere_of, dtype=np.int64)
        self._subsets: dict = {}
        self._lock = threading.Lock()
        self._build()

    def _build(self):
        """Embree's scene of the rows that are triangles (`_tri_rows`: Embree's primitive -> row) and
        each exact sphere's first row (`sphere_rows`, -1 where none of its rows is here)."""
        self._scene = None
        self._tri_rows = np.nonzero(self.sphere_of < 0)[0]
        self.sphere_rows = np.full(len(self.spheres), -1, dtype=np.int64)
        on = np.nonzero(self.sphere_of >= 0)[0]
        which, first = np.unique(self.sphere_of[on], return_index=True)
        self.sphere_rows[which] = on[first]
        self._any_sphere = bool(len(on))
        if len(self._tri_rows):
            from embreex import rtcore_scene
            from embreex.mesh_construction import TriangleMesh

            self._scene = rtcore_scene.EmbreeScene(_device(), robust=True)
            TriangleMesh(self._scene, self._to_embree(self.triangles[self._tri_rows]))

    def subset(self, key, keep) -> Accelerator:
        """An accelerator over the triangles `keep()` (indices into this one's), built once per `key`,
        with this one's scale, epsilon and unit: the same float32 crossing and float64 refinement;
        its triangle indices map back through its `ids`. Used to query some shapes without the
        others (an interior's own boundary; the opaque surfaces apart from the interiors)."""
        with self._lock:
            if key not in self._subsets:
                part = object.__new__(Accelerator)
                part.__dict__.update(self.__dict__)
                part.ids = np.asarray(keep(), dtype=np.int64)
                part.triangles, part.normals = self.triangles[part.ids], self.normals[part.ids]
                part.sphere_of = self.sphere_of[part.ids]
                part._subsets, part._lock = {}, threading.Lock()
                part._build()
                self._subsets[key] = part
            return self._subsets[key]

    def _to_embree(self, a):
        """Coordinates or distances as Embree sees them: float32, in units of `unit`."""
        return np.ascontiguousarray(a if self.unit == 1.0 else a / self.unit, dtype=np.float32)

    def _map(self, fn, n, threads, *arrays):
        chunks = [tuple(a[i:i + CHUNK] for a in arrays) for i in range(0, n, CHUNK)]
        if threads <= 1 or len(chunks) <= 1:
            return [fn(*c) for c in chunks]
        with ThreadPoolExecutor(threads) as pool:
            return list(pool.map(lambda c: fn(*c), chunks))

    def first_hit(self, origins: np.ndarray, dirs: np.ndarray, threads: int = 1):
        """Nearest hit of each ray: (t float64, inf on a miss; triangle index int64, -1 on a miss)."""
        n = len(origins)
        if (self._scene is None and not self._any_sphere) or n == 0:
            return np.full(n, np.inf), np.full(n, -1, dtype=np.int64)
        if n <= CHUNK:  # a tile's rays: one batch, no pool
            return self._first_hit_chunk(origins, dirs)
        parts = self._map(self._first_hit_chunk, n, threads, origins, dirs)
        return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])

    def _first_hit_chunk(self, origins, dirs):
        if self._scene is None:
            t, prim = np.full(len(origins), np.inf), np.full(len(origins), -1, dtype=np.int64)
        else:
            o32 = self._to_embree(origins)
            d32 = np.ascontiguousarray(dirs, dtype=np.float32)
            prim = self._scene.run(o32, d32).astype(np.int64)
            if self._any_sphere:  # Embree's primitives are the rows that are triangles
                prim[prim >= 0] = self._tri_rows[prim[prim >= 0]]
            t = np.empty(len(prim))
            _refine(self.triangles, self.normals, origins, dirs, prim, t)
            bad = np.isnan(t)
            if bad.any():  # degenerate plane solve: fall back to Embree's float32 distance
                t[bad] = self._scene.run(o32[bad], d32[bad], query="DISTANCE").astype(np.float64) * self.unit
        self._sphere_hits(origins, dirs, t, prim)
        return t, prim

    def _sphere_hits(self, origins, dirs, t, prim):
        """t, prim <- the exact spheres' hits where nearer (sphere.py)."""
        if self._any_sphere:
            nearest_sphere_hits(np.ascontiguousarray(origins, dtype=np.float64),
                                np.ascontiguousarray(dirs, dtype=np.float64), self.spheres, self.sphere_rows, t, prim)

    def hit_distance32(self, origins: np.ndarray, dirs: np.ndarray) -> np.ndarray:
        """Embree's own float32 distance to the nearest hit (inf on a miss): a check on `first_hit`'s
        plane distance where a ray grazing an edge is reported on the neighbouring triangle; an exact
        sphere's float64 distance where it is nearer."""
        t = np.full(len(origins), np.inf)
        if self._scene is not None and len(origins):
            t32 = self._scene.run(self._to_embree(origins), np.ascontiguousarray(dirs, dtype=np.float32),
                                  query="DISTANCE")
            t = np.where(t32 < 1e37, t32.astype(np.float64) * self.unit, np.inf)
        self._sphere_hits(origins, dirs, t, np.zeros(len(origins), dtype=np.int64))
        return t

    def occluded(self, origins: np.ndarray, dirs: np.ndarray, tmax: np.ndarray, threads: int = 1, as32=None):
        """True where something lies between origin and origin + tmax * dir. `as32`: the rays as
        Embree takes them (`shadow_rays` makes them), else made here."""
        n = len(origins)
        occ = np.zeros(n, dtype=bool)
        if n == 0:
            return occ
        if self._scene is not None:
            o32, d32, t32 = as32 if as32 is not None else (
                self._to_embree(origins), np.ascontiguousarray(dirs, dtype=np.float32),
                self._to_embree(np.maximum(tmax, 0.0)))
            if n <= CHUNK:  # a tile's rays: one batch, no pool
                occ = self._scene.run(o32, d32, dists=t32, query="OCCLUDED") >= 0
            else:
                res = self._map(lambda o, d, t: self._scene.run(o, d, dists=t, query="OCCLUDED"), n, threads, o32,
                                d32, t32)
                occ = np.concatenate(res) >= 0
        if self._any_sphere:
            sphere_blocks(np.ascontiguousarray(origins, dtype=np.float64), np.ascontiguousarray(dirs, dtype=np.float64),
                          np.ascontiguousarray(np.broadcast_to(tmax, (n,)), dtype=np.float64), self.spheres,
                          self.sphere_rows, occ)
        return occ

    def hit_normals(self, prim: np.ndarray, points: np.ndarray) -> np.ndarray:
        """Unit geometric normals (N, 3) at hit `points` on rows `prim`: the triangle's (its winding's
        side), an exact sphere's (p - c) / r (outward)."""
        out = self.normals[prim]
        k = self.sphere_of[prim] if len(self.spheres) else None
        if k is not None and np.any(k >= 0):
            on = k >= 0
            rel = points[on] - self.spheres[k[on], :3]
            out[on] = rel / np.linalg.norm(rel, axis=1, keepdims=True)
        return out

    def shadow_rays(self, points: np.ndarray, normals: np.ndarray, light: np.ndarray, idx: np.ndarray | None = None):
        """Rays from surface points (offset along the normal facing the light) towards `light`:
        (origins, unit directions, distances to stop at, and these three as Embree takes them,
        `occluded`'s `as32`), in one GIL-free pass; from the points `idx` (int64) alone if given (the
        rays of points[idx], normals[idx], without those copies)."""
        idx = np.arange(len(points)) if idx is None else idx
        n = len(idx)
        o, d, t = np.empty((n, 3)), np.empty((n, 3)), np.empty(n)
        as32 = (np.empty((n, 3), np.float32), np.empty((n, 3), np.float32), np.empty(n, np.float32))
        shadow_rays_into(points, normals, idx, 0, n, np.asarray(light, np.float64), self.epsilon, self.unit, o, d, t,
                         *as32)
        return o, d, t, as32


@njit
def _refine(triangles, normals, origins, dirs, prim, t):
    """Exact float64 distance from each origin to the plane of its hit triangle (inf on a miss,
    NaN where the plane solve is degenerate)."""
    for i in range(prim.shape[0]):
        k = prim[i]
        if k < 0:
            t[i] = np.inf
            continue
        num = 0.0
        den = 0.0
        for a in range(3):
            num += normals[k, a] * (triangles[k, 0, a] - origins[i, a])
            den += normals[k, a] * dirs[i, a]
        t[i] = num / den if den != 0.0 and num / den > 0.0 else np.nan
