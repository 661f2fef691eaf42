"""The GIL-free kernels that took over a tile's NumPy expressions (jit.exact_njit) give those
expressions' numbers bit for bit: each is compared here with the NumPy expression it replaced,
written out below, on random inputs with the edge cases (slivers, points on a light, vacuum
channels, infinite depths). Transcendental functions (exp, sin, cos) are libm's in the kernels and
NumPy's own loops in the references, which may differ by an ulp on some CPUs: within 1 ulp there."""
import math

import numpy as np
import pytest

from raytrace import camera, error_bounds, shading
from raytrace.geometry.accel import Accelerator
from raytrace.media.medium import exp_transmittance
from raytrace.methods import quadrature
from raytrace.scene.format import Camera

RNG = np.random.default_rng(37)


def dot(a, b):
    return np.einsum("ij,ij->i", a, b)


def mesh(n=400):
    """Random triangles, a tenth of them slivers (collinear corners), and their corner normals:
    random, equal on a fifth (flat), opposite on a few (their sum vanishes at the centroid)."""
    tri = RNG.normal(size=(n, 3, 3)) * 10.0 ** RNG.uniform(-2, 2, size=(n, 1, 1))
    tri[::10, 2] = tri[::10, 0] + 0.5 * (tri[::10, 1] - tri[::10, 0])
    corners = RNG.normal(size=(n, 3, 3))
    corners /= np.linalg.norm(corners, axis=2, keepdims=True)
    corners[::5] = corners[::5, :1]
    corners[1::17] = np.stack([corners[1::17, 0], -corners[1::17, 0], corners[1::17, 2] * 0.0], axis=1)
    return Accelerator(tri), corners


def reference_shading_normals(accel, corners, prim, points, facing):
    """shading.shading_normals as NumPy computed it (before the kernel)."""
    c = corners[prim]
    tri = accel.triangles[prim]
    e1, e2, v = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], points - tri[:, 0]
    d00, d01, d11 = (dot(a, b) for a, b in ((e1, e1), (e1, e2), (e2, e2)))
    d20, d21 = dot(v, e1), dot(v, e2)
    den = d00 * d11 - d01 * d01
    with np.errstate(divide="ignore", invalid="ignore"):
        b = np.clip(np.stack([np.zeros_like(den), (d11 * d20 - d01 * d21) / den, (d00 * d21 - d01 * d20) / den],
                             axis=1), 0.0, 1.0)
        b[:, 0] = np.maximum(1.0 - b[:, 1] - b[:, 2], 0.0)
        n = np.einsum("ij,ijk->ik", b, c)
        length = np.linalg.norm(n, axis=1)
    flat = np.all(c == c[:, :1], axis=(1, 2)) | ~(length > 0.0) | (accel.sphere_of[prim] >= 0)
    n = np.where(flat[:, None], facing, n / np.where(flat, 1.0, length)[:, None])
    flipped = dot(accel.normals[prim], facing) < 0.0
    return np.where((flipped & ~flat)[:, None], -n, n)


def test_shading_and_facing_normals_are_numpys():
    accel, corners = mesh()
    prim = RNG.integers(0, len(accel.triangles), 20000)
    w = RNG.dirichlet(np.ones(3), size=len(prim))
    points = np.einsum("ij,ijk->ik", w, accel.triangles[prim]) + RNG.normal(size=(len(prim), 3)) * 0.1
    points[:100] = accel.triangles[prim[:100]].mean(axis=1)  # centroids: the opposite corners' sums vanish
    dirs = RNG.normal(size=(len(prim), 3))
    facing = shading.facing_normals(accel.normals[prim], dirs)
    assert np.array_equal(facing, np.where((dot(accel.normals[prim], dirs) > 0.0)[:, None],
                                           -accel.normals[prim], accel.normals[prim]))
    got = shading.shading_normals(accel, corners, prim, points, facing)
    assert np.array_equal(got, reference_shading_normals(accel, corners, prim, points, facing), equal_nan=True)
    assert shading.shading_normals(accel, None, prim, points, facing) is facing


def test_toward_light_is_numpys():
    n = 5000
    points, lp = RNG.normal(size=(n, 3)), RNG.normal(size=3)
    points[:10] = lp  # on the light: no direction, unlit
    normals, shade = (RNG.normal(size=(n, 3)) for _ in range(2))
    for terminator in (False, True):
        to_light, dist, cos, lit = np.empty((n, 3)), np.empty(n), np.empty(n), np.empty(n, dtype=bool)
        shading._toward_light(points, normals, shade if terminator else normals, terminator, lp, to_light, dist,
                              cos, lit)
        ref_to = lp[None, :] - points
        ref_dist = np.linalg.norm(ref_to, axis=1)
        ref_cos = dot(normals, ref_to) / np.where(ref_dist > 0.0, ref_dist, 1.0)
        ref_lit = (ref_cos > 0.0) & (ref_dist > 0.0)
        if terminator:
            ref_cos = dot(shade, ref_to) / np.where(ref_dist > 0.0, ref_dist, 1.0)
            ref_lit &= ref_cos > 0.0
        for a, b in ((to_light, ref_to), (dist, ref_dist), (cos, ref_cos), (lit, ref_lit)):
            assert np.array_equal(a, b)
        assert not lit[:10].any()


def test_reflected_radiance_is_numpys():
    n, m = 3000, 2000
    out = RNG.uniform(size=(n, 3))
    idx = np.sort(RNG.choice(n, m, replace=False))
    refl, irr, tr, cos = RNG.uniform(size=(n, 3)), RNG.uniform(size=(m, 3)) * 1e3, RNG.uniform(size=(m, 3)), \
        RNG.uniform(size=m)
    ref = out.copy()
    ref[idx] += refl[idx] / math.pi * (irr * tr * cos[:, None])
    shading._add_reflected(out, idx, refl, irr, tr, cos)
    assert np.array_equal(out, ref)


def test_reached_points_are_numpys():
    """shading._reached_rays against the fancy indexing it replaced (per light, the lit points whose
    shadow rays are not blocked, light after light), with points on the light (distance 0: inf and nan
    directions, as NumPy divides) and a light that lights nothing."""
    n, lights = 5000, 3
    points, to_light, cos = RNG.normal(size=(n, 3)), RNG.normal(size=(lights, n, 3)), RNG.normal(size=(lights, n))
    to_light[:, :7] = 0.0
    dist = np.linalg.norm(to_light, axis=2)
    seens = [np.flatnonzero(RNG.uniform(size=n) < 0.7), np.zeros(0, np.int64), np.flatnonzero(RNG.uniform(size=n) < 0.5)]
    seens[0][:3] = [0, 1, 2]
    seen, starts = np.concatenate(seens), np.cumsum([0] + [len(s) for s in seens])
    for blocked in (RNG.uniform(size=len(seen)) < 0.4, np.zeros(len(seen), bool), np.ones(len(seen), bool)):
        refs = []
        for j, s in enumerate(seens):
            idx = s[~blocked[starts[j]:starts[j + 1]]]
            with np.errstate(divide="ignore", invalid="ignore"):
                refs.append((idx, points[idx], to_light[j, idx] / dist[j, idx][:, None], -to_light[j, idx],
                             dist[j, idx], cos[j, idx]))
        ref = [np.concatenate([r[k] for r in refs]) for k in range(6)]
        *got, ends = shading._reached_rays(seen, starts, blocked, points, to_light, dist, cos)
        for a, b in zip(got, ref):
            assert a.dtype == b.dtype and np.array_equal(a, b, equal_nan=True)
        assert np.array_equal(ends, np.cumsum([0] + [len(r[0]) for r in refs]))
        near = np.concatenate([r[0] for r in refs]) < 7
        assert np.all(got[3][near] == 0.0) and np.signbit(got[3][near]).all()  # -0.0 as NumPy negates


def test_light_rays_are_numpys():
    """shading._light_rays (the shadow rays of several lights in one pass) against what it replaced: per
    light `_toward_light`, its lit points and `Accelerator.shadow_rays` of them, concatenated; with a
    light that lights nothing and points on a light."""
    accel, _ = mesh()
    n = 4000
    points, normals, shade = RNG.normal(size=(n, 3)), RNG.normal(size=(n, 3)), RNG.normal(size=(n, 3))
    positions = RNG.normal(size=(3, 3)) * 2.0
    points[:5] = positions[0]  # on light 0: unlit by it
    away = np.where((dot(normals, positions[1][None, :] - points) > 0.0)[:, None], -normals, normals)
    for terminator in (False, True):  # every point's geometric normal faces away from light 1: it lights none
        facing = shade if terminator else away
        got = shading._light_rays(points, away, facing, terminator, positions, accel.epsilon, accel.unit)
        to_light, dist, cos, seen, starts, o, d, t, (o32, d32, t32) = got
        ref = {k: [] for k in ("seen", "o", "d", "t", "o32", "d32", "t32")}
        for j, lp in enumerate(positions):
            rt, rd, rc, lit = np.empty((n, 3)), np.empty(n), np.empty(n), np.empty(n, dtype=bool)
            shading._toward_light(points, away, facing, terminator, lp, rt, rd, rc, lit)
            for a, b in ((to_light[j], rt), (dist[j], rd), (cos[j], rc)):
                assert np.array_equal(a, b)
            s = np.flatnonzero(lit)
            assert starts[j + 1] - starts[j] == len(s)
            ro, rdir, rtm, (r32o, r32d, r32t) = accel.shadow_rays(points, away, lp, s)
            for k, v in zip(ref, (s, ro, rdir, rtm, r32o, r32d, r32t)):
                ref[k].append(v)
        assert starts[0] == 0 and starts[2] == starts[1] and starts[3] == len(seen)
        for a, k in zip((seen, o, d, t, o32, d32, t32), ref):
            b = np.concatenate(ref[k])
            assert a.dtype == b.dtype and np.array_equal(a, b)


@pytest.mark.parametrize("size", [1.0, 1e30])  # 1e30: Embree's coordinates in units of `unit`
def test_shadow_rays_and_their_float32_copies_are_numpys(size):
    accel, _ = mesh()
    accel.scale, accel.epsilon = size, 1e-5 * size
    accel.unit = 1.0 if size == 1.0 else 2.0 ** round(math.log2(size))
    n = 5000
    points, normals, light = RNG.normal(size=(n, 3)) * size, RNG.normal(size=(n, 3)), RNG.normal(size=3) * size
    points[:5] = light  # on the light: zero length, no direction
    normals[5:10] = 0.0  # no side
    o, d, t, (o32, d32, t32) = accel.shadow_rays(points, normals, light)
    idx = np.sort(RNG.choice(n, n // 2, replace=False))  # the rays of some points, by index, are those points' rays
    for a, b in zip((o, d, t), accel.shadow_rays(points, normals, light, idx)[:3]):
        assert np.array_equal(a[idx], b)
    side = np.sign(dot(normals, light[None, :] - points))[:, None]
    ref_o = points + side * accel.epsilon * normals
    seg = light[None, :] - ref_o
    seg_len = np.linalg.norm(seg, axis=1)
    ref_d = seg / np.where(seg_len > 0, seg_len, 1.0)[:, None]
    ref_t = seg_len - accel.epsilon
    for a, b in ((o, ref_o), (d, ref_d), (t, ref_t), (o32, accel._to_embree(ref_o)),
                 (d32, ref_d.astype(np.float32)), (t32, accel._to_embree(np.maximum(ref_t, 0.0)))):
        assert a.dtype == b.dtype and np.array_equal(a, b)


def reference_rays(cam, x, y):
    """camera._rays as NumPy computed it (before the kernel)."""
    forward, right, up = camera.basis(cam)
    W, H = cam.width, cam.height
    if cam.type == "perspective":
        tan = math.tan(math.radians(cam.fov) / 2.0)
        a, b = (2.0 * x / W - 1.0) * tan * (W / H), (1.0 - 2.0 * y / H) * tan
        d = forward + a[..., None] * right + b[..., None] * up
    else:
        phi, theta = 2.0 * math.pi * (x / W - 0.5), math.pi * y / H
        d = np.sin(theta)[..., None] * (np.cos(phi)[..., None] * forward + np.sin(phi)[..., None] * right) \
            + np.cos(theta)[..., None] * up
    d = d.reshape(-1, 3)
    d /= np.linalg.norm(d, axis=1)[:, None]
    return np.broadcast_to(cam.position, d.shape), d


@pytest.mark.parametrize("kind", ["perspective", "environment"])
def test_camera_rays_are_numpys(kind):
    cam = Camera(kind, np.array([1.0, 2.0, 3.0]), np.array([0.3, 1.0, -2.0]), np.array([0.0, 1.0, 0.0]), 50.0, 640, 360,
                 4)
    x, y = RNG.uniform(0, 640, size=(3000, 4)), RNG.uniform(0, 360, size=(3000, 4))
    # the points themselves: zero offsets (x + 0.0 is x)
    (o, d), (ref_o, ref_d) = camera._rays(cam, x.ravel(), y.ravel(), np.zeros((1, 2))), reference_rays(cam, x, y)
    assert np.array_equal(o, ref_o)
    if kind == "perspective":
        assert np.array_equal(d, ref_d)
    else:  # libm's sin and cos against NumPy's
        np.testing.assert_array_max_ulp(d, ref_d, maxulp=1)



@pytest.mark.parametrize("kind", ["perspective", "environment"])
def test_pixel_rays_are_the_offsets_sums(kind):
    """`pixel_rays` and `generate_rays` are the rays through pixel + offset, the sums made in NumPy
    (the broadcast the kernel took over), in the order (pixel, sample)."""
    cam = Camera(kind, np.array([1.0, 2.0, 3.0]), np.array([0.3, 1.0, -2.0]), np.array([0.0, 1.0, 0.0]), 50.0, 64, 36,
                 5)  # 5 spp: the R2 offsets, not a grid
    off = camera.sample_offsets(cam.spp)[1:4]
    ys, xs = RNG.integers(0, 36, size=200), RNG.integers(0, 64, size=200)
    got = camera.pixel_rays(cam, ys, xs, slice(1, 4))
    ref = camera._rays(cam, (xs[:, None] + off[None, :, 0]).ravel(), (ys[:, None] + off[None, :, 1]).ravel(),
                       np.zeros((1, 2)))
    assert all(np.array_equal(a, b) for a, b in zip(got, ref))
    j, i = np.arange(3.0, 9.0), np.arange(10.0, 17.0)
    every = camera.generate_rays(cam, slice(3, 9), slice(10, 17), slice(1, 4))
    x = (i[None, :, None] + off[None, None, :, 0]) * np.ones((len(j), 1, 1))
    y = (j[:, None, None] + off[None, None, :, 1]) * np.ones((1, len(i), 1))
    assert all(np.array_equal(a, b) for a, b in zip(every, camera._rays(cam, x.ravel(), y.ravel(), np.zeros((1, 2)))))

def test_exp_transmittance_is_numpys():
    kt = np.array([0.0, 0.3, 1e300])  # a vacuum channel, an ordinary one, one that overflows
    tau = np.concatenate([RNG.exponential(10.0, size=5000), [0.0, np.inf, 1e-300]])
    with np.errstate(invalid="ignore", over="ignore"):
        ref = np.where(kt[None, :] == 0.0, 1.0, np.exp(-kt[None, :] * tau[:, None]))
    got = exp_transmittance(kt, tau)
    assert np.all(got[:, 0] == 1.0) and got[-2, 1] == 0.0 and got[-1, 2] == math.exp(-1.0)
    np.testing.assert_array_max_ulp(got, ref, maxulp=1)



def test_exp_transmittance_grey_channels_are_each_channels_own():
    """Channels with equal coefficients share one exp per ray: each column is, bit for bit, what the
    kernel gives that channel alone (vacuum, overflowing and repeated channels among them)."""
    kt = np.array([0.3, 0.0, 0.3, 1e300, 0.7, 1e300, 0.3, 0.0])
    tau = np.concatenate([RNG.exponential(10.0, size=3000), [0.0, np.inf, 1e-300]])
    got = exp_transmittance(kt, tau)
    for c in range(len(kt)):
        assert np.array_equal(got[:, c], exp_transmittance(kt[c:c + 1], tau)[:, 0])
    with np.errstate(invalid="ignore", over="ignore"):
        ref = np.where(kt[None, :] == 0.0, 1.0, np.exp(-kt[None, :] * tau[:, None]))
    np.testing.assert_array_max_ulp(got, ref, maxulp=1)

def edge_values(n, scale):
    """n random magnitudes over many decades, with 0, inf and the largest double among them."""
    v = scale * 10.0 ** RNG.uniform(-20, 20, size=n)
    v[:: 7] = 0.0
    v[3:: 53] = np.inf
    v[5:: 61] = np.finfo(float).max
    return v


def test_fog_bound_rounding_is_numpys():
    """quadrature._add_rounding against `_fog`'s NumPy expression for its bound's rounding terms."""
    n = 6000
    prefix = edge_values(n, 1e-14)
    cos_end = np.where(RNG.uniform(size=n) < 0.3, -2.0, RNG.uniform(-1.0, 1.0, size=n))  # a third without cones
    cos_end[:20] = [1.0, -1.0, np.nextafter(1.0, 0.0), np.nextafter(-1.0, 0.0)] * 5  # cones of no width, the edges
    radiance = np.stack([edge_values(n, 1.0) for _ in range(3)], axis=1)
    bound = np.stack([edge_values(n, 1e-10) for _ in range(3)], axis=1)
    for kt in (np.array([0.0, 0.06, 1e300]), np.array([0.5, 0.5, 0.5])):  # a vacuum channel, an overflow
        with np.errstate(over="ignore"):
            rel = (error_bounds.ROUNDING + error_bounds.spot_rounding(cos_end)[:, None]
                   + error_bounds.product(prefix[:, None], kt[None, :]))
            ref = bound + error_bounds.product(rel, np.abs(radiance))
        got = bound.copy()
        quadrature._add_rounding(prefix, kt, cos_end, radiance, got)
        assert np.array_equal(got, ref) and np.isinf(got).any() and not np.isnan(got).any()


def test_relative_bound_is_numpys():
    """error_bounds.relative_bound's kernel against its NumPy expression (analytic's bound, and
    quadrature's in homogeneous media)."""
    n = 6000
    cos_end = np.where(RNG.uniform(size=n) < 0.3, -2.0, RNG.uniform(-1.0, 1.0, size=n))
    cos_end[:20] = [1.0, -1.0, np.nextafter(1.0, 0.0), np.nextafter(-1.0, 0.0)] * 5
    radiance = np.stack([edge_values(n, 1.0) for _ in range(3)], axis=1)
    met = [RNG.uniform(size=n) < 0.9, np.ones(n, bool), np.zeros(n, bool)]
    for rel in (1e-3 + error_bounds.ROUNDING, error_bounds.KERNEL_FLOOR + error_bounds.ROUNDING):
        ref = (rel + error_bounds.spot_rounding(cos_end)[:, None]) * np.abs(radiance)
        for c in range(3):
            ref[~met[c], c] = np.inf
        got = np.empty_like(radiance)
        error_bounds._relative(radiance, rel, cos_end, tuple(met), got)
        assert np.array_equal(got, ref) and np.isinf(got[:, 1]).any()


def test_relative_bound_shares_channel_keys():
    """relative_bound takes each channel's `met` by its (sigma_t, sigma_s) key; a channel without one
    (it does not scatter) keeps its bound (rel |value|)."""
    class Medium:
        sigma_t, sigma_s = np.array([0.5, 0.5, 0.2]), np.array([0.3, 0.3, 0.0])

    n = 500
    radiance = RNG.uniform(size=(n, 3))
    radiance[:, 2] = 0.0
    met = {(0.5, 0.3): RNG.uniform(size=n) < 0.5}
    got = error_bounds.relative_bound(radiance, 1e-3, met, Medium, np.full(n, -2.0))
    ref = (1e-3 + error_bounds.ROUNDING) * radiance
    ref[~met[(0.5, 0.3)], :2] = np.inf
    assert np.array_equal(got, ref)


def test_sums_of_samples_are_numpys():
    """renderer.sum_samples' kernel against the NumPy loop it replaced."""
    from raytrace.rendering import renderer

    for samples in (1, 4, 7):
        values = edge_values(300 * samples, 1.0).reshape(-1, 3) * RNG.uniform(size=(100 * samples, 3))
        per = values.reshape(-1, samples, 3)
        total = per[:, 0].copy()
        for k in range(1, samples):
            total += per[:, k]
        assert np.array_equal(renderer.sum_samples(values, samples), total)


def test_surface_hits_are_numpys():
    """renderer._surface_hits against the masks and fancy indexing it replaced in shade_rays."""
    from raytrace.rendering import renderer

    n = 4000
    origins, dirs = RNG.normal(size=(n, 3)) * 100.0, RNG.normal(size=(n, 3))
    t = RNG.exponential(10.0, size=n)
    prim = RNG.integers(-1, 50, size=n)
    keys = RNG.integers(0, 2**63, size=n).astype(np.uint64)
    reflectance = RNG.uniform(size=(50, 3))
    for into, ground in ((np.zeros(n, bool), np.zeros(n, bool)),
                         (RNG.uniform(size=n) < 0.2, (prim < 0) & (RNG.uniform(size=n) < 0.5))):
        t[prim < 0] = np.inf
        surf = (prim >= 0) & ~into
        outs = (np.empty(n, np.int64), np.empty((n, 3)), np.empty((n, 3)), np.empty(n, np.int64),
                np.empty(n, np.uint64), np.empty((n, 3)))
        m, entering, missed, grounded = renderer._surface_hits(origins, dirs, t, prim, keys, into & (prim >= 0), ground,
                                                               reflectance, *outs)
        ref = (np.flatnonzero(surf), origins[surf] + t[surf, None] * dirs[surf], dirs[surf], prim[surf], keys[surf],
               reflectance[prim[surf]])
        for a, b in zip(outs, ref):
            assert a.dtype == b.dtype and np.array_equal(a[:m], b)
        assert entering == (into & (prim >= 0)).any()
        assert missed == np.count_nonzero((prim < 0) & ~ground) and grounded == np.count_nonzero(ground)


def test_scaled_channels_are_numpys():
    """geometry._scale_channels (by_channel's unit air-light times each light's intensity, 0 for a dark
    light even where the unit value overflowed) against its NumPy expression."""
    from raytrace.methods import geometry

    n = 3000
    intensity = np.array([[1.0, 0.0, 3.5], [2.0, 1e300, 0.0], [0.25, 7.0, 1.0]])
    light = RNG.integers(0, 3, size=n)
    u = [edge_values(n, 1.0), edge_values(n, 1e10), np.zeros(0)]
    out = np.zeros((n, 3))
    geometry._scale_channels(out, *u, intensity, light)
    with np.errstate(over="ignore", invalid="ignore"):
        for c in range(2):
            i = intensity[light, c]
            assert np.array_equal(out[:, c], np.where(i != 0.0, u[c] * i, 0.0))
    assert not out[:, 2].any()
