"""The surface term (paper eq. 5) with shadow-ray visibility, summed over lights.

Lb = sum_lights V (rho / pi) I F T / d^2 max(0, n·wi), with n the shading normal flipped to face
the incoming ray (two-sided Lambertian surfaces): the geometric normal of a flat surface, else
`shading_normals`' interpolation of the triangle's corner normals (a shape's `smooth`). The geometric
normal keeps the visibility: shadow rays leave on its side, and a light on the far side of the
geometric plane gives nothing even where the shading cosine is positive (the terminator: both cosines
must be positive, the factor is the shading one), F a spot light's falloff toward the point
(lights.py, 1 for point lights) and T the medium's transmittance from the point to the light
(exp(-kt d) when homogeneous, the closed-form optical depth in a height fog). A directional light
gives V (rho / pi) E T max(0, n·wi) with wi against its direction of travel and T the
transmittance to infinity toward it (seed 004, eq. 34 with t1 = inf). The camera sees Lb
attenuated by its own transmittance; that factor is applied by the renderer. An atmosphere's
planet (media/atmosphere.py) is a sphere the medium intersects in float64 (`planet_hits`), a diffuse
ground of the medium's reflectance (`ground_radiance`); its shadow is in the transmittance (0 to a
light behind it). An area light's emitter (a shape with `emission`, scene/format.py) adds its radiance
where a ray meets its front (`emitted_radiance`; an area light lights surfaces through its emitter
points, spot rows of lights/area.py, like any spot light, except in penumbrae: where occluders cut
the emitter, `penumbra` samples it instead, its variance for the variance layer; and where nothing can
hide any of it, an emitter whose irradiance has a closed form about a centre (a sphere's, whose
occluders are tested against their geometry: `_free`) gives it instead of the rows in a homogeneous
medium: `_unshadowed`).
"""
from __future__ import annotations

import math

import numpy as np

from .geometry.shadow_rays import shadow_rays_into
from .jit import exact_jitable, exact_njit, njit
from .lights.area import collapsed_variance
from .lights.near_rules import free as free_of, rows_decide, seen_probes
from .rng import uniform

STATS_NAMES = ("closed form not converged",)  # surface_radiance's: points left at the finest order
SHADOW_BATCH = 1 << 15  # shadow rays (points x lights) the surface term traces in one batch at most
STRATA = 8  # a penumbra's strata per side for a method without a tolerance (even; two samples in each)
PILOT = 2  # strata per side of the pilot that chooses a penumbra's strata (`stratified`)
LADDER = (4, 8, 16)  # the strata per side a penumbra may get: the floor first, the cap last
DIM_PENUMBRA = 1 << 48  # the first random-number dimension (rng.py) of the penumbrae's samples
SAMPLES_PER_CHUNK = 1 << 16  # emitter samples (points x samples per point) per batch of shadow rays


def facing_normals(normals: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """Flip each normal to the side the ray comes from."""
    out = np.empty((len(normals), 3))
    _facing(normals, dirs, out)
    return out


@exact_njit
def _facing(normals, dirs, out):
    for i in range(normals.shape[0]):
        flip = _dot(normals, i, dirs, i) > 0.0
        for a in range(3):
            out[i, a] = -normals[i, a] if flip else normals[i, a]


def shading_normals(accel, corners, prim, points, facing):
    """Unit shading normals (N, 3) at `points` on triangles `prim`: n_s = normalise(sum b_i n_i) with
    b the barycentric coordinates of the point (clipped to the triangle) and n_i the triangle's corner
    normals (`corners` (T, 3, 3), on the side of its winding), flipped where the geometric normal was
    flipped to give `facing` (`facing_normals`). The geometric normal itself (`facing`) on flat
    triangles (equal corners), where the sum vanishes, on exact spheres (whose geometric normal is
    exact) and everywhere when `corners` is None."""
    if corners is None:
        return facing
    out = np.empty_like(facing)
    _shading_normals(corners, accel.triangles, accel.normals, accel.sphere_of, prim, points, facing, out)
    return out


@exact_njit
def _toward_light(points, normals, shading, terminator, lp, to_light, dist, cos, lit):
    """Per point: to_light = lp - p, its length `dist`, the cosine `cos` of the (shading, with
    `terminator`) normal to it (0 at the light) and `lit`, where the geometric normal, and with
    `terminator` the shading one too, faces the light."""
    for i in range(points.shape[0]):
        for a in range(3):
            to_light[i, a] = lp[a] - points[i, a]
        x, y, z = to_light[i, 0], to_light[i, 1], to_light[i, 2]
        dist[i] = math.sqrt(x * x + y * y + z * z)
        over = dist[i] if dist[i] > 0.0 else 1.0
        cos[i] = _dot(normals, i, to_light, i) / over
        lit[i] = cos[i] > 0.0 and dist[i] > 0.0
        if terminator:
            cos[i] = _dot(shading, i, to_light, i) / over
            lit[i] = lit[i] and cos[i] > 0.0


@exact_jitable  # called with constant rows: one compilation, not one per constant
def _dot(a, i, b, j):
    """a[i] . b[j] of (N, 3) rows, summed as NumPy's einsum("ij,ij->i") sums three terms."""
    return (a[i, 0] * b[j, 0] + a[i, 2] * b[j, 2]) + a[i, 1] * b[j, 1]


@exact_njit
def _shading_normals(corners, triangles, normals, sphere_of, prim, points, facing, out):
    """`shading_normals` into `out`, one point at a time (the NumPy expressions it replaced, each
    rounded the same way)."""
    e = np.empty((3, 3))  # e1, e2, v
    b = np.empty(3)
    n = np.empty(3)
    for i in range(prim.shape[0]):
        k = prim[i]
        same = True  # every corner normal equal to the first (most of a mesh's triangles, often)
        for c in range(1, 3):
            for a in range(3):
                same = same and corners[k, c, a] == corners[k, 0, a]
        if same or sphere_of[k] >= 0:  # flat: the geometric normal, nothing to interpolate
            for a in range(3):
                out[i, a] = facing[i, a]
            continue
        for a in range(3):
            e[0, a] = triangles[k, 1, a] - triangles[k, 0, a]
            e[1, a] = triangles[k, 2, a] - triangles[k, 0, a]
            e[2, a] = points[i, a] - triangles[k, 0, a]
        d00, d01, d11 = _dot(e, 0, e, 0), _dot(e, 0, e, 1), _dot(e, 1, e, 1)
        d20, d21 = _dot(e, 2, e, 0), _dot(e, 2, e, 1)
        den = d00 * d11 - d01 * d01  # > 0 but for slivers (then nan: flat below)
        b[1] = (d11 * d20 - d01 * d21) / den
        b[2] = (d00 * d21 - d01 * d20) / den
        for a in range(1, 3):  # np.clip(b, 0, 1), nan kept
            b[a] = b[a] if math.isnan(b[a]) else min(max(b[a], 0.0), 1.0)
        b[0] = 1.0 - b[1] - b[2]
        b[0] = b[0] if math.isnan(b[0]) else max(b[0], 0.0)  # np.maximum(b0, 0)
        for a in range(3):
            n[a] = b[0] * corners[k, 0, a] + b[1] * corners[k, 1, a] + b[2] * corners[k, 2, a]
        length = math.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
        flat = not (length > 0.0)
        flip = -1.0 if _dot(normals, k, facing, i) < 0.0 and not flat else 1.0
        for a in range(3):
            out[i, a] = facing[i, a] if flat else flip * (n[a] / length)


def surface_radiance(accel, points, normals, reflectance, lights, medium, through=None, shading=None, keys=None,
                     seed=0, variance=None, tol=None, stats=None):
    """Reflected radiance (N, 3) at surface points with ray-facing unit geometric normals `normals`
    and shading normals `shading` (`shading_normals`; None: the geometric ones). `through(li, points)`,
    if given, is the transmittance (M, 3) toward light li of points whose shadow ray is occluded (0
    where truly blocked; interiors/shapes.py's shadows through index-matched interiors).
    `keys` (N,), the points' pixel-sample keys (rng.py), with `seed`: an emitter's rows whose shadow
    rays disagree at a point (a penumbra) are replaced there by stratified samples of the emitter
    (`penumbra`, their strata following the method's relative tolerance `tol`: `Method.tolerance`;
    black points are not sampled: they reflect nothing either way), whose variance is added to
    `variance` (N, 3) if given, and where none is blocked by the emitter's closed form if it has one
    (`_unshadowed`, to `tol`); without keys (or with `through`) the rows alone, everywhere. `stats`
    (STATS_NAMES), if given: += the points where that closed form did not converge."""
    out = np.zeros((len(points), 3))
    sampled = keys is not None and through is None and any(e is not None for e in lights.emitters)
    terminator = shading is not None and shading is not normals  # both must face the light
    rows = {}  # per sampled emitter: its rows' radiance (N, 3) and how many reached, were blocked (N,) each
    dark = ~lights.intensity.any(axis=1)  # nothing to add (a light layer's other lights, renderer.Prepared.only)
    run = []  # point-like lights since the last directional one: their shadow rays in one batch
    for li in range(len(lights)):
        if dark[li]:
            continue
        if lights.distant[li]:
            _add_lights(out, rows, accel, points, normals, shading if terminator else normals, terminator,
                        reflectance, lights, run, medium, through, sampled)
            run = []
            _add_directional(out, accel, points, normals, reflectance, lights, li, medium, through, shading)
            continue
        run.append(li)
    _add_lights(out, rows, accel, points, normals, shading if terminator else normals, terminator, reflectance,
                lights, run, medium, through, sampled)
    for owner in np.unique(lights.owner[~dark]) if sampled else ():  # spheres no row reaches: their probes may
        if lights.emitters[owner] is not None and not rows_decide(lights.emitters[owner]):
            rows.setdefault(owner, (np.zeros_like(out), np.zeros(len(out), np.int64), np.zeros(len(out), np.int64)))
    for owner, (value, reached, missed) in rows.items():
        free = _free(accel, points, normals, lights.emitters[owner])
        cut = _cut(accel, points, normals, shading if terminator else None, lights.emitters[owner], reached, missed,
                   free)
        ruled = _unshadowed(out, value, points, normals, shading if terminator else None, reflectance,
                            lights.emitters[owner], medium, tol, free | ~cut & (reached > 0) & (missed == 0), stats)
        at = np.flatnonzero(cut & ~ruled & np.any(reflectance > 0.0, axis=1))  # black: 0 either way
        if len(at):
            est, var = penumbra(accel, points[at], normals[at], shading[at] if terminator else None,
                                reflectance[at], lights.emitters[owner], medium, keys[at], seed, owner, tol)
            out[at] += est - value[at]
            if variance is not None:
                variance[at] += var
    return out


def _unshadowed(out, value, points, normals, shading, reflectance, emitter, medium, tol, clear, stats):
    """out += at the points `clear` (nothing can hide the emitter from them (`_free`: rows blocked there
    lie below the point's own horizon, which the closed form clips), or every row of the emitter that
    emits toward the point reached it, some did, and nothing cut it) the emitter's irradiance in closed
    form (`lights.Emitter.irradiance`, to the relative tolerance `tol`) in place of its rows' share
    `value`, where the emitter has it and the medium is homogeneous (the transmittance along each
    direction then depends on the distance alone); (N,) where it did. `stats` (STATS_NAMES) or None."""
    ruled = np.zeros(len(points), dtype=bool)
    if emitter.irradiance is None or not medium.homogeneous:
        return ruled
    at = np.flatnonzero(clear & np.any(reflectance > 0.0, axis=1))  # black: 0 either way
    if not len(at):
        return ruled
    e, applies = emitter.irradiance(points[at], normals[at], None if shading is None else shading[at],
                                    medium.sigma_t, tol, None if stats is None else stats[:1])
    at, e = at[applies], e[applies]
    out[at] += reflectance[at] / math.pi * e - value[at]
    ruled[at] = True
    return ruled


def _add_lights(out, rows, accel, points, normals, facing, terminator, reflectance, lights, run, medium, through,
                sampled):
    """out += the reflected radiance of the point-like lights `run` (in their order, each point's terms
    added light by light), the shadow rays of up to SHADOW_BATCH points x lights traced in one batch;
    per sampled emitter (`sampled`) its rows' share and how many of them reached, were blocked at each
    point, into `rows` (`surface_radiance`). `facing`: the normals whose terminator counts (the shading
    ones with `terminator`)."""
    step = max(1, SHADOW_BATCH // max(len(points), 1))
    for k in range(0, len(run), step):
        _add_batch(out, rows, accel, points, normals, facing, terminator, reflectance, lights, run[k:k + step],
                   medium, through, sampled)


def _add_batch(out, rows, accel, points, normals, facing, terminator, reflectance, lights, run, medium, through,
               sampled):
    """`_add_lights` of one batch of lights."""
    to_light, dist, cos, seen, starts, o, d, t, as32 = _light_rays(points, normals, facing, terminator,
                                                                   lights.position[run], accel.epsilon, accel.unit)
    shines = [j for j in range(len(run)) if starts[j + 1] > starts[j]]  # the lights that light some points
    if not shines:
        return
    occ = accel.occluded(o, d, t, as32=as32)
    blocked, parts = occ, {}  # parts: per light, the transmittance of the shapes its let-through rays pass
    if through is not None and occ.any():
        blocked = occ.copy()
        for j in shines:
            span = slice(starts[j], starts[j + 1])
            blocked[span], part = _let_through(occ[span], seen[span], points, run[j], through)
            if part is not None:
                parts[j] = part
    idx, at, wi, back, dl, cl, ends = _reached_rays(seen, starts, blocked, points, to_light, dist, cos)
    tr = medium.transmittance_on(at, wi, 0.0, dl)
    irradiance = np.empty((len(idx), 3))
    for j in shines:
        got = slice(ends[j], ends[j + 1])
        irradiance[got] = lights.irradiance(run[j], back[got], dl[got])
        if j in parts:
            tr[got] = tr[got] * parts[j]
    _add_reflected(out, idx, reflectance, irradiance, tr, cl)  # light after light at each point
    if not sampled:
        return
    owners = lights.owner[run]
    for owner in dict.fromkeys(owners[shines].tolist()):  # in the order the lights name them
        if owner < 0 or lights.emitters[owner] is None:
            continue
        value, reached, missed = rows.setdefault(owner, (np.zeros_like(out), np.zeros(len(out), np.int64),
                                                         np.zeros(len(out), np.int64)))
        mine = np.repeat(owners == owner, np.diff(ends))
        _add_reflected(value, idx[mine], reflectance, irradiance[mine], tr[mine], cl[mine])
        for j in shines:
            if owners[j] == owner:
                mark, hit = seen[starts[j]:starts[j + 1]], blocked[starts[j]:starts[j + 1]]
                emits = to_light[j][mark] @ lights.axis[run[j]] < 0.0  # the row's LAMBERT falloff is not zero there
                reached += np.bincount(mark[emits & ~hit], minlength=len(out))
                missed += np.bincount(mark[emits & hit], minlength=len(out))


def _light_rays(points, normals, facing, terminator, positions, eps, unit):
    """The shadow rays of the lights at `positions` (L, 3): per light j, `_toward_light`'s to_light (L, N, 3),
    dist, cos (L, N), the points it lights, seen[starts[j]:starts[j + 1]], and their shadow rays in that
    order (`Accelerator.shadow_rays`: o, d, t and their float32 copies for Embree), in one GIL-free pass
    (`_light_rays_into`; the arrays made here: a kernel's own allocations compile numba's overloads of
    np.empty once more)."""
    k, n = len(positions), len(points)
    to_light, dist, cos, lit = np.empty((k, n, 3)), np.empty((k, n)), np.empty((k, n)), np.empty(n, np.bool_)
    seen, starts = np.empty(k * n, np.int64), np.empty(k + 1, np.int64)
    o, d, t = np.empty((k * n, 3)), np.empty((k * n, 3)), np.empty(k * n)
    o32, d32, t32 = np.empty((k * n, 3), np.float32), np.empty((k * n, 3), np.float32), np.empty(k * n, np.float32)
    m = _light_rays_into(points, normals, facing, terminator, positions, eps, unit, to_light, dist, cos, lit, seen,
                         starts, o, d, t, o32, d32, t32)
    return to_light, dist, cos, seen[:m], starts, o[:m], d[:m], t[:m], (o32[:m], d32[:m], t32[:m])


@exact_njit
def _light_rays_into(points, normals, facing, terminator, positions, eps, unit, to_light, dist, cos, lit, seen,
                     starts, o, d, t, o32, d32, t32):
    """`_light_rays` into its arrays (`lit` (N,) scratch); returns how many rays."""
    m = starts[0] = 0
    for j in range(positions.shape[0]):
        _toward_light(points, normals, facing, terminator, positions[j], to_light[j], dist[j], cos[j], lit)
        for i in range(points.shape[0]):
            if lit[i]:
                seen[m] = i
                m += 1
        starts[j + 1] = m
        shadow_rays_into(points, normals, seen, starts[j], m, positions[j], eps, unit, o, d, t, o32, d32, t32)
    return m


@exact_njit
def _add_reflected(out, idx, reflectance, irradiance, tr, cos):
    """out[idx] += reflectance[idx] / pi * (irradiance tr cos), rounded as that NumPy expression."""
    for i in range(idx.shape[0]):
        k = idx[i]
        for c in range(3):
            out[k, c] = out[k, c] + reflectance[k, c] / math.pi * (irradiance[i, c] * tr[i, c] * cos[i])


def _blocked(accel, o, d, tmax, idx, points, li, through, as32=None):
    """Which of the points idx have shadow rays (o, d, tmax) that do not reach light li (a mask over
    idx), and the transmittance (M, 3) of the shapes the M others pass through (`_let_through`);
    `as32`: the rays' float32 copies for Embree where `Accelerator.shadow_rays` made them."""
    return _let_through(accel.occluded(o, d, tmax, as32=as32), idx, points, li, through)


def _let_through(occ, idx, points, li, through):
    """(blocked, part): of the points idx whose shadow rays toward light li are occluded (`occ`) those
    that stay blocked where `through` lets some through, and the transmittance (M, 3) of the shapes
    the M others pass through (None where every factor is 1: no ray was let through)."""
    if through is None or not occ.any():
        return occ, None
    part = np.ones((len(idx), 3))
    part[occ] = through(li, points[idx[occ]])
    occ = ~np.any(part > 0.0, axis=1)
    return occ, part[~occ]


def _reached_rays(seen, starts, blocked, points, to_light, dist, cos):
    """(idx, points, unit directions to the light, the light's vector to the points, distances,
    cosines, ends (L + 1,)) of the points seen[starts[j]:starts[j + 1]] whose shadow rays toward light j
    (`_light_rays`) are not `blocked`, light after light (light j's at [ends[j], ends[j + 1])): per
    light, points[idx], to_light[j, idx] / dist[j, idx], -to_light[j, idx], dist[j, idx], cos[j, idx]
    in one GIL-free pass (`_reached_into`)."""
    n = len(seen)
    idx, at, wi, back, dl, cl = (np.empty(n, np.int64), np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3)),
                                 np.empty(n), np.empty(n))
    ends = np.empty(len(starts), np.int64)
    m = _reached_into(seen, starts, blocked, points, to_light, dist, cos, idx, at, wi, back, dl, cl, ends)
    return idx[:m], at[:m], wi[:m], back[:m], dl[:m], cl[:m], ends


@exact_njit
def _reached_into(seen, starts, blocked, points, to_light, dist, cos, idx, at, wi, back, dl, cl, ends):
    """`_reached_rays` into its arrays; returns how many reached."""
    m = ends[0] = 0
    for j in range(starts.shape[0] - 1):
        for r in range(starts[j], starts[j + 1]):
            if blocked[r]:
                continue
            k = seen[r]
            idx[m], dl[m], cl[m] = k, dist[j, k], cos[j, k]
            for a in range(3):
                at[m, a] = points[k, a]
                wi[m, a] = to_light[j, k, a] / dist[j, k]
                back[m, a] = -to_light[j, k, a]
            m += 1
        ends[j + 1] = m
    return m


def _free(accel, points, normals, emitter):
    """(N,) where nothing but the emitter can hide any of it from the points: for a sphere, the exact test
    of the occluders' geometry (`near_rules.free`, the same for every cubature order); nowhere for other
    emitters (their rows and probes tell)."""
    return free_of(emitter, accel, points, normals)


def _cut(accel, points, normals, shading, emitter, reached, blocked, free):
    """(N,) where the emitter (`lights.Emitter`) seen from the points is cut: the shadow rays of its rows
    that emit toward a point (`reached`, `blocked`: how many reached it, were blocked) disagree; for a
    sphere (whose rows decide nothing: `near_rules.rows_decide`), where the rows agree and the point is
    not `free` of occluders (`_free`), wherever any of its rows or of the probes of the part the point
    sees (`_ball_probes`, the same for every cubature order) reaches the point (all blocked: hidden, 0);
    for an emitter with corner probes, where the point's horizon (its tangent plane, or the terminator
    of its shading normal) passes between them, or, where the rows agree, the shadow rays to those that
    emit toward the point disagree with them."""
    cut = (reached > 0) & (blocked > 0)
    if not rows_decide(emitter):
        at = np.flatnonzero(~cut & ~free)
        seen = _ball_probes(accel, points[at], normals[at], None if shading is None else shading[at], emitter)
        cut[at] = reached[at] + seen > 0
        return cut
    if emitter.probes is None:
        return cut
    terminator = shading is not None
    above = np.zeros(len(points), np.int64)
    for y in emitter.probes[0]:
        above += _toward_probe(points, normals, shading, y)[0]
    cut |= _horizon_cuts(above, len(emitter.probes[0]))
    agree = np.flatnonzero(((reached > 0) ^ (blocked > 0)) & ~cut)
    p, n = points[agree], normals[agree]
    for y, ny in zip(*emitter.probes):
        lit, to_light = _toward_probe(p, n, shading[agree] if terminator else None, y)
        facing = to_light @ ny
        idx = np.flatnonzero(lit & ((facing != 0.0) if emitter.two_sided else (facing < 0.0)))
        o, d, tmax, as32 = accel.shadow_rays(p, n, y, idx)
        reach = ~accel.occluded(o, d, tmax, as32=as32)
        cut[agree[idx]] |= reach != (reached[agree[idx]] > 0)
    return cut


def _ball_probes(accel, points, normals, shading, emitter):
    """(M,) how many of a sphere emitter's probes (`near_rules.seen_probes`, the same for every cubature
    order) above each point's horizon (its shading normal's terminator too, where given) reach the
    point: shadow rays as `_emitter_samples` traces them (the exact sphere does not shadow its own
    surface's near side)."""
    y, outward = seen_probes(emitter, points, [normals] if shading is None else [normals, shading])
    per = y.shape[1]
    y, outward = y.reshape(-1, 3), outward.reshape(-1, 3)
    p, n = np.repeat(points, per, axis=0), np.repeat(normals, per, axis=0)
    to = y - p
    lit = np.einsum("ij,ij->i", n, to) > 0.0  # False where NaN (no probe)
    if shading is not None:
        lit &= np.einsum("ij,ij->i", np.repeat(shading, per, axis=0), to) > 0.0
    idx = np.flatnonzero(lit & (np.einsum("ij,ij->i", outward, to) < 0.0))  # the probe faces the point
    o = p[idx] + accel.epsilon * n[idx]
    d = y[idx] - o
    length = np.linalg.norm(d, axis=1)
    blocked = accel.occluded(o, d / np.where(length > 0.0, length, 1.0)[:, None], length - accel.epsilon)
    return np.bincount(idx[~blocked] // per, minlength=len(points)).astype(np.int64)


def _toward_probe(points, normals, shading, y):
    """(lit (N,), to_light (N, 3)): `_toward_light` of the points (their shading normals' terminator too
    where `shading` is given) toward the probe y."""
    to_light, dist, cos = np.empty_like(points), np.empty(len(points)), np.empty(len(points))
    lit = np.empty(len(points), dtype=np.bool_)
    _toward_light(points, normals, normals if shading is None else shading, shading is not None, y, to_light, dist,
                  cos, lit)
    return lit, to_light


def _horizon_cuts(above, probes: int):
    """(N,) where a point's horizon passes between an emitter's `probes`: some, not all, `above` it."""
    return (above > 0) & (above < probes)


def penumbra(accel, points, normals, shading, reflectance, emitter, medium, keys, seed, owner, tol=None):
    """(radiance, variance), each (M, 3): eq. 5 for one emitter (`lights.Emitter`) at M surface
    points (normals, shading normals or None, reflectance as in `surface_radiance`), estimated from
    2 S stratified samples of its (u, v) square (S = k^2 strata, two independent uniform points in
    each, keyed by the points' `keys`, `seed`, the emitter's index `owner` and k: rng.py, `block`;
    k per point chosen by a pilot to meet the relative tolerance `tol`, STRATA without one:
    `stratified`), each with its shadow ray: with y a sample, n_y its normal, w = (y - x) / d, p_A
    its area density, g = rho / pi L T(x, y) V(x, y) cos_x max(0, n_y . -w) / (d^2 p_A) (|n_y . w|
    two-sided), the estimate is the mean of the g. Its variance sum_s sigma_s^2 / (2 S^2) is
    estimated with the strata collapsed in blocks of 2 x 2 (lights.area.collapsed_variance:
    conservative, and unlike the pairs within one stratum it does not vanish where a shadow edge
    crosses strata whose two samples happen to agree). Where every sample's shadow ray agrees (all
    reach the emitter, or none: the rows or probes saw a sliver the samples missed), the variance is
    at least that of one sample's share, (G / 2 S)^2, G the mean of the g without visibility (V = 1):
    the estimator's resolution."""

    def estimate(at, strata, stage):
        return _penumbra_at(accel, points[at], normals[at], None if shading is None else shading[at], reflectance[at],
                            emitter, medium, keys[at], seed, block(DIM_PENUMBRA, owner, stage), strata)

    return stratified(estimate, len(points), tol)


def stratified(estimate, count: int, tol):
    """(estimate, variance), each (count, 3), of `count` stratified estimates (a penumbra's: of one
    emitter at surface points, or along camera rays: shadows/penumbra_airlight.py): with a relative
    tolerance `tol`, a pilot of PILOT x PILOT strata for each chooses its strata (`choose_strata`)
    and the estimate is made from fresh samples at those strata (the pilot's are not reused: the
    estimate is independent of the choice, so unbiased); without one (None), STRATA x STRATA.
    `estimate(at, strata, stage)`: (value, variance) of the items `at` at `strata` per side, from the
    random numbers of LADDER[stage] (stage len(LADDER): the pilot's and STRATA's; `block`)."""
    everything = np.arange(count)
    if tol is None:
        return estimate(everything, STRATA, len(LADDER))
    strata = choose_strata(*estimate(everything, PILOT, len(LADDER)), tol)
    value, var = np.empty((count, 3)), np.empty((count, 3))
    for stage, k in enumerate(LADDER):
        at = np.flatnonzero(strata == k)
        if len(at):
            value[at], var[at] = estimate(at, k, stage)
    return value, var


def choose_strata(value, var, tol) -> np.ndarray:
    """(M,) the strata per side for each of M estimates from a pilot of PILOT x PILOT strata (its
    estimate and variance, (M, 3) each): the smallest of LADDER at which the standard error would be
    at most tol x the estimate in every channel, taking it to fall as k^(-3/2) with k strata a side (a
    shadow edge crosses about k of the k^2 strata, each adding a variance ~ 1 / k^4 to the mean's);
    LADDER's last (the cap) where the pilot's estimate is 0 but its variance is not."""
    ratio = np.full(var.shape, np.inf)
    np.divide(np.sqrt(var), tol * value, out=ratio, where=value > 0.0)
    ratio = np.where(var > 0.0, ratio, 0.0).max(axis=1)  # var 0: nothing to gain (value exact or 0)
    need = PILOT * ratio ** (2.0 / 3.0)
    rung = np.searchsorted(np.array(LADDER, float), need, side="left")
    return np.array(LADDER)[np.minimum(rung, len(LADDER) - 1)]


def block(base: int, owner: int, stage: int) -> int:
    """The first random-number dimension of emitter `owner`'s samples at LADDER[stage] strata (the
    pilot's and STRATA's at stage len(LADDER)), from `base`: disjoint blocks, each of two dimensions
    per sample of the cap."""
    return base + (owner * (len(LADDER) + 1) + stage) * 4 * LADDER[-1] ** 2


def _penumbra_at(accel, points, normals, shading, reflectance, emitter, medium, keys, seed, dim, strata):
    """`penumbra`'s (estimate, variance) at `strata` per side, random numbers from dimension `dim`."""
    per = 2 * strata * strata
    value, var = np.zeros((len(points), 3)), np.zeros((len(points), 3))
    step = max(1, SAMPLES_PER_CHUNK // per)
    half = strata // 2
    for lo in range(0, len(points), step):
        at = slice(lo, lo + step)
        g, free, seen = _emitter_samples(accel, points[at], normals[at], None if shading is None else shading[at],
                                         reflectance[at], emitter, medium, keys[at], seed, dim, strata)
        blocks = g.reshape(-1, half, 2, half, 2, 2, 3).transpose(0, 1, 3, 2, 4, 5, 6).reshape(-1, half * half, 8, 3)
        value[at] = blocks.mean(axis=(1, 2))
        var[at] = collapsed_variance(g.reshape(-1, per, 3), strata)
        seen, gives = seen.reshape(-1, per), np.any(free > 0.0, axis=1).reshape(-1, per)
        agree = np.all(seen | ~gives, axis=1) | ~np.any(seen, axis=1)
        floor = (free.reshape(-1, per, 3).mean(axis=1) / per) ** 2
        var[at] = np.where(agree[:, None], np.maximum(var[at], floor), var[at])
    return value, var


def _emitter_samples(accel, points, normals, shading, reflectance, emitter, medium, keys, seed, dim, strata):
    """The `penumbra` values g (M x per, 3) of per = 2 strata^2 samples of the emitter at each point
    (random numbers from dimension `dim`), the same without visibility (V = 1) and whether each
    sample's shadow ray reached it (M x per,; False where the sample gives nothing anyway: behind the
    point or the emitter)."""
    per = 2 * strata * strata
    u, v = np.empty((len(points), per)), np.empty((len(points), per))
    _jitter(keys, seed, dim, strata, u, v)
    y, ny, density = emitter.sample(u.ravel(), v.ravel())
    p, n = np.repeat(points, per, axis=0), np.repeat(normals, per, axis=0)
    to = y - p
    dist = np.linalg.norm(to, axis=1)
    w = to / np.where(dist > 0.0, dist, 1.0)[:, None]
    cos = np.einsum("ij,ij->i", n, w)
    lit = (cos > 0.0) & (dist > 0.0)
    if shading is not None:  # the terminator, as in surface_radiance
        cos = np.einsum("ij,ij->i", np.repeat(shading, per, axis=0), w)
        lit &= cos > 0.0
    cos_y = -np.einsum("ij,ij->i", ny, w)
    cos_y = np.abs(cos_y) if emitter.two_sided else cos_y
    idx = np.flatnonzero(lit & (cos_y > 0.0))
    o = p[idx] + accel.epsilon * n[idx]  # as Accelerator.shadow_rays: off the surface, toward the light
    d = y[idx] - o
    length = np.linalg.norm(d, axis=1)
    seen = np.zeros(len(p), dtype=bool)
    seen[idx] = ~accel.occluded(o, d / np.where(length > 0.0, length, 1.0)[:, None], length - accel.epsilon)
    free = np.zeros((len(p), 3))
    tr = medium.transmittance_on(p[idx], w[idx], 0.0, dist[idx])
    weight = cos[idx] * cos_y[idx] / (dist[idx] ** 2 * density[idx])
    free[idx] = np.repeat(reflectance, per, axis=0)[idx] / math.pi * emitter.radiance * tr * weight[:, None]
    return free * seen[:, None], free, seen


@njit
def _jitter(keys, seed, dim, strata, u, v):
    """u, v (M, 2 strata^2): two uniform points in each stratum (a, b) of the unit square, sample
    j = 2 (a strata + b) + s at dimensions dim + 2 j, dim + 2 j + 1 of its point's key (rng.py)."""
    for i in range(u.shape[0]):
        for a in range(strata):
            for b in range(strata):
                for s in range(2):
                    j = 2 * (a * strata + b) + s
                    u[i, j] = (a + uniform(keys[i], dim + 2 * j, seed)) / strata
                    v[i, j] = (b + uniform(keys[i], dim + 2 * j + 1, seed)) / strata


def _add_directional(out, accel, points, normals, reflectance, lights, li, medium, through=None, shading=None):
    """out += the directional light li's reflected radiance (shadow rays to infinity toward it)."""
    wi = -lights.axis[li]
    cos = normals @ wi
    lit = cos > 0.0
    if shading is not None and shading is not normals:  # the terminator, as in surface_radiance
        cos = shading @ wi
        lit &= cos > 0.0
    idx = np.nonzero(lit)[0]
    if not len(idx):
        return
    o = points[idx] + accel.epsilon * normals[idx]
    d = np.broadcast_to(wi, o.shape)
    blocked, part = _blocked(accel, o, d, np.full(len(idx), np.inf), idx, points, li, through)
    idx = idx[~blocked]
    tr = medium.transmittance_on(points[idx], np.broadcast_to(wi, (len(idx), 3)), 0.0, np.inf)
    if part is not None:
        tr = tr * part
    out[idx] += reflectance[idx] / math.pi * lights.intensity[li] * tr * cos[idx, None]


def emitted_radiance(shapes, shape_ids, winding_normals, dirs):
    """Radiance (N, 3) the rays `dirs` see emitted where they hit triangles of the shapes `shape_ids`
    with unit winding normals `winding_normals`: the shape's `emission` on the side its winding's
    normal points to (the ray travels against it), on both if `two_sided`; 0 elsewhere."""
    emission = np.array([np.zeros(3) if s.emission is None else s.emission for s in shapes]).reshape(-1, 3)
    both = np.array([s.two_sided for s in shapes], dtype=bool)
    front = np.einsum("ij,ij->i", winding_normals, dirs) < 0.0
    return emission[shape_ids] * (front | both[shape_ids])[:, None]


def emissive_shapes(scene, triangles, shape_ids) -> list:
    """The `emitters` of `Lights.of`: (world triangles, emission, two_sided, key) of each shape of the
    file with `emission` (an area light's own emitter shape is that light's rows already)."""
    return [(triangles[shape_ids == i], s.emission, s.two_sided, f"{scene.path or 'scene'}: shape[{i}]")
            for i, s in enumerate(scene.shapes) if s.emission is not None and s.light is None]


def planet_hits(medium, origins, dirs, t):
    """(ground, t): where rays meet the medium's own ground (an atmosphere's planet) before the mesh
    hit at t, and t with those distances (float64, the numbers the transmittance compares with)."""
    if not medium.has_ground:
        return np.zeros(len(t), dtype=bool), t
    tg = medium.ground_hits(origins, dirs)
    ground = tg < t
    return ground, np.where(ground, tg, t)


def first_hits(accel, medium, origins, dirs):
    """(t, prim, ground) of camera rays: the nearest mesh hit (prim -1 where none) or the medium's own
    ground (`planet_hits`: `ground`, prim -1 there), t inf where neither."""
    t, prim = accel.first_hit(origins, dirs)
    ground, t = planet_hits(medium, origins, dirs, t)
    prim[ground] = -1
    return t, prim, ground


def ground_radiance(accel, origins, dirs, t, lights, medium):
    """Reflected radiance (N, 3) of the medium's ground where rays origins + t dirs meet it."""
    points = origins + t[:, None] * dirs
    normals, refl = medium.ground_surface(points)
    return surface_radiance(accel, points, facing_normals(normals, dirs), refl, lights, medium)
