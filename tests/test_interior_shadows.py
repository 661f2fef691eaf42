"""Volumetric shadows with media inside shapes (crossing.py, shadows/frusta.py, interiors/paths.py).

Two twins, written from the scene alone (tests/oracle.py's camera rays, plate tests and shadow
boundaries, a ray-box clip here), scipy quad between the analytic shadow boundaries:
- inside: an index-matched box of a scattering medium under a point light, an opaque plate between
  them throwing its shadow across half the box; the light's path inside is its straight chord to the
  top face, the plate blocks it;
- outside: fog around a denser index-matched box hanging between a point light and the camera's
  rays below it; the fog's light is attenuated by exp(-(sigma_t inside - sigma_t outside) chord).
Shadowed renders must equal the twins to 1e-8 relative on every pixel whose ray does not graze a
shadow boundary or an edge within float32 reach; the unshadowed renders differ by far more. Both
requests were refused before ("not implemented with media inside shapes").
"""
from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from scipy import integrate

from raytrace.interiors import shapes
from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import load_scene

from . import oracle
from .conftest import to_toml
from .test_bounded_media import slab

LIGHT = np.array([0.0, 3.0, 0.0])
INTENSITY = 10.0
SHADOWED = RenderOptions(threads=1, volumetric_shadows=True)
UNSHADOWED = RenderOptions(threads=1)

# inside: a box of medium, a plate above it (y = 2) covering x > 0.1 (its shadow: x > 0.1 (3 - y))
IN_LO, IN_HI = np.array([-0.5, 0.0, -0.5]), np.array([0.5, 1.0, 0.5])
IN_KS, IN_KA = np.array([0.8, 0.6, 0.4]), np.array([0.2, 0.5, 0.9])
PLATE = (2.0, (0.1, 1.5), (-1.5, 1.5))
IN_CAMERA = {"position": [2.0, 0.6, 2.2], "look_at": [0.0, 0.5, 0.0], "fov": 30.0, "width": 16, "height": 12,
             "spp": 1}

# outside: fog, a denser box hanging above the camera's lower rays
FOG_KS, FOG_KA = np.array([0.05, 0.06, 0.07]), np.array([0.01, 0.01, 0.02])
OUT_LO, OUT_HI = np.array([-0.4, 1.2, -0.6]), np.array([0.6, 2.0, 0.4])
OUT_KS, OUT_KA = np.array([0.5, 0.7, 0.9]), np.array([0.6, 0.3, 0.1])
OUT_CAMERA = {"position": [0.0, 0.4, 4.0], "look_at": [0.0, 0.6, 0.0], "fov": 50.0, "width": 10, "height": 8,
              "spp": 1}


def box_clip(o, d, lo, hi):
    """(t_in, t_out) of the line o + t d through the box [lo, hi] (t_in may be negative), or None."""
    hit = slab(o, d, lo, hi)
    return None if hit is None else hit[:2]


def chord(p, lo, hi):
    """Length inside the box of the segment from p to the light."""
    rel = LIGHT - p
    dist = math.sqrt(rel @ rel)
    hit = box_clip(p, rel / dist, lo, hi)
    if hit is None:
        return 0.0
    return max(min(hit[1], dist) - max(hit[0], 0.0), 0.0)


def write(tmp_path, sc):
    (tmp_path / "s.toml").write_text(to_toml(sc))
    return prepare(load_scene(tmp_path / "s.toml"))


def inside_scene(tmp_path):
    return write(tmp_path, {
        "name": "shadow in a box", "camera": IN_CAMERA,
        "light": [{"type": "point", "position": LIGHT.tolist(), "intensity": INTENSITY}],
        "shape": [{"primitive": "box", "min": IN_LO.tolist(), "max": IN_HI.tolist(),
                   "interior": {"sigma_a": IN_KA.tolist(), "sigma_s": IN_KS.tolist()}},
                  {"primitive": "quad", "reflectance": 0.5,
                   "corners": [[0.1, 2.0, -1.5], [1.5, 2.0, -1.5], [1.5, 2.0, 1.5], [0.1, 2.0, 1.5]]}]})


def outside_scene(tmp_path, ior=1.0):
    return write(tmp_path, {
        "name": "fog under a box", "camera": OUT_CAMERA,
        "medium": {"type": "homogeneous", "sigma_a": FOG_KA.tolist(), "sigma_s": FOG_KS.tolist()},
        "light": [{"type": "point", "position": LIGHT.tolist(), "intensity": INTENSITY}],
        "shape": [{"primitive": "box", "min": OUT_LO.tolist(), "max": OUT_HI.tolist(),
                   "interior": {"sigma_a": OUT_KA.tolist(), "sigma_s": OUT_KS.tolist(), "ior": ior}}]})


def relative(img, ref):
    """|img - ref| / ref, and |img| / the brightest pixel where ref is 0 (wholly shadowed rays)."""
    return np.abs(img - ref) / np.where(ref > 0.0, ref, ref.max())


def quad(f, a, b, breaks):
    edges = sorted({a, b, *(x for x in breaks if a < x < b)})
    return sum(integrate.quad(f, u, v, epsabs=0.0, epsrel=1e-12, limit=400)[0] for u, v in zip(edges[:-1], edges[1:]))


def inside_twin(i, j):
    """The pixel (3,) and whether its ray meets the box: the box's single scattering of the light, lit
    where the plate does not block the path to the light (nothing lies behind the box)."""
    o, d = oracle.camera_ray(IN_CAMERA, i, j)
    hit = box_clip(o, d, IN_LO, IN_HI)
    if hit is None:
        return np.zeros(3), False
    t_in, t_out = hit
    breaks = oracle.plate_shadow_breaks(o, d, t_out, LIGHT, PLATE)
    out = np.zeros(3)
    for c in range(3):
        kt = IN_KS[c] + IN_KA[c]

        def f(x):
            if oracle.plate_blocks(o, d, x, LIGHT, PLATE):
                return 0.0
            p = o + x * d
            rel = LIGHT - p
            dist = math.sqrt(rel @ rel)
            return (IN_KS[c] * INTENSITY / (4 * math.pi) * math.exp(-kt * (x - t_in) - kt * chord(p, IN_LO, IN_HI))
                    / dist**2)
        out[c] = quad(f, t_in, t_out, breaks)
    return out, True


def outside_twin(i, j):
    """The pixel (3,) of a ray that misses the box (None for one that meets it): the fog's air-light to
    infinity, the light's path attenuated by the box's denser medium where it crosses it."""
    o, d = oracle.camera_ray(OUT_CAMERA, i, j)
    hit = box_clip(o, d, OUT_LO, OUT_HI)
    if hit is not None and hit[1] > 0.0:
        return None
    # the path to the light can enter or leave the box, or change faces, only where the ray crosses a
    # plane through the light and one of the box's 12 edges: every such crossing is a break
    kt = FOG_KS + FOG_KA
    end = 40.0 / kt.min()
    corners = [np.array([OUT_LO[0] if m & 1 else OUT_HI[0], OUT_LO[1] if m & 2 else OUT_HI[1],
                         OUT_LO[2] if m & 4 else OUT_HI[2]]) for m in range(8)]
    kinks = []
    for u in range(8):
        for v in range(u + 1, 8):
            if bin(u ^ v).count("1") == 1:  # an edge
                n = np.cross(corners[u] - LIGHT, corners[v] - LIGHT)
                if n @ d != 0.0:
                    kinks.append(float(n @ (LIGHT - o) / (n @ d)))
    out = np.zeros(3)
    for c in range(3):
        dk = OUT_KS[c] + OUT_KA[c] - kt[c]

        def f(x):
            p = o + x * d
            rel = LIGHT - p
            dist = math.sqrt(rel @ rel)
            return (FOG_KS[c] * INTENSITY / (4 * math.pi) * math.exp(-kt[c] * (x + dist) - dk * chord(p, OUT_LO, OUT_HI))
                    / dist**2)
        out[c] = quad(f, 0.0, end, kinks)
    return out


@functools.cache
def outside_image():
    """The outside twin's image and the pixels beside the box."""
    twin = [[outside_twin(i, j) for i in range(OUT_CAMERA["width"])] for j in range(OUT_CAMERA["height"])]
    return (np.array([[v if v is not None else np.zeros(3) for v in row] for row in twin]),
            np.array([[v is not None for v in row] for row in twin]))


def test_a_plate_shadows_the_medium_inside_a_box(tmp_path):
    """Shadowed quadrature within 1e-8 of the twin on every pixel whose ray meets the box (the pixels
    beside it are black); unshadowed, the shadowed half of the box is lit and far off."""
    prep = inside_scene(tmp_path)
    twin = [[inside_twin(i, j) for i in range(IN_CAMERA["width"])] for j in range(IN_CAMERA["height"])]
    ref = np.array([[v for v, _ in row] for row in twin])
    seen = np.array([[s for _, s in row] for row in twin])
    assert seen.sum() >= 40 and (~seen).sum() >= 10
    res = render(prep, "quadrature", {}, SHADOWED)
    rel = relative(res.image, ref)[seen]
    print(f"inside shadow: worst relative error {rel.max():.2e}; stats {res.stats}")
    assert rel.max() <= 1e-8
    assert np.all(res.image[~seen] == 0.0)
    assert res.stats["inside: lit pieces"] > 0 and res.stats["inside: segments unshadowed (refractive or planar model)"] == 0
    off = render(prep, "quadrature", {}, UNSHADOWED).image
    assert np.max(relative(off, ref)[seen]) > 0.5  # the plate's shadow is half the box


def test_the_sampling_methods_see_the_inside_shadow(tmp_path):
    """raymarch converges to the same twin (2048 steps: 1e-4), montecarlo agrees within its error."""
    prep = inside_scene(tmp_path)
    ref, seen = inside_twin(8, 6)  # its ray crosses the shadow boundary inside the box
    assert seen
    opts = RenderOptions(threads=1, volumetric_shadows=True, crop=(8, 6, 9, 7))
    march = render(prep, "raymarch", {"steps": 2048}, opts).image[0, 0]
    assert np.all(np.abs(march - ref) <= 1e-4 * ref)
    mc = render(prep, "montecarlo", {"samples": 4096}, opts)
    z = (mc.image[0, 0] - ref) / np.sqrt(mc.variance[0, 0])
    assert np.all(np.abs(z) < 5.0), z


def test_fog_below_a_denser_box_gets_the_light_through_it(tmp_path, method="quadrature", tol=1e-8):
    """The fog whose light crosses the box: the light's attenuation through the box's medium on every
    pixel beside the box (within 1e-8), integrated by the traced quadrature, counted, inside its bound
    (finite: media/convex_chords.py's rule, plus the twin's own 1e-12); unshadowed (the box ignored) is
    far off."""
    prep = outside_scene(tmp_path)
    ref, beside = outside_image()
    assert beside.sum() >= 40 and (~beside).sum() >= 4
    res = render(prep, method, {}, SHADOWED)
    rel = relative(res.image, ref)[beside]
    print(f"{method} through the box: worst relative error {rel.max():.2e}")
    assert rel.max() <= tol
    assert res.stats["shadows: pieces through interiors (quadrature)"] > 0
    assert res.stats["shadows: through-interior integrals not converged"] == 0
    assert np.all(np.isfinite(res.error_bound[beside]))
    assert np.all(np.abs(res.image - ref)[beside] <= res.error_bound[beside] + 1e-12 * ref[beside])
    off = render(prep, method, {}, UNSHADOWED).image
    assert np.max(relative(off, ref)[beside]) > 0.05


def test_refractive_interiors_block_and_are_shadowed_inside(tmp_path):
    """A refractive box stops the fog's light (its boundary is a blocker: the refracted light would be
    a caustic) and its inside takes the lamp's refracted paths' shadows (lit pieces, none counted
    unshadowed: a convex box); index-matched boundaries are not blockers."""
    assert not shapes.blockers(outside_scene(tmp_path)).any()
    prep = outside_scene(tmp_path, 1.33)
    assert shapes.blockers(prep) is None and shapes.attenuators(prep) is None
    o, d = oracle.camera_ray(OUT_CAMERA, 5, 7)  # beside the box, below it
    assert box_clip(o, d, OUT_LO, OUT_HI) is None
    column = dict(threads=1, crop=(5, 0, 6, 8))  # its top pixels see the box
    on = render(prep, "quadrature", {}, RenderOptions(volumetric_shadows=True, **column))
    off = render(prep, "quadrature", {}, RenderOptions(**column))
    assert on.stats["inside: segments unshadowed (refractive or planar model)"] == 0
    assert on.stats["inside: lit pieces"] > 0
    assert np.all(on.image[7, 0] < 0.9 * off.image[7, 0])


def test_shadow_rays_per_sample_are_refused_with_interiors(tmp_path):
    """`--shadow-test samples` casts plain shadow rays, which would take every boundary for an
    occluder: refused in one line."""
    import raytrace

    (tmp_path / "s.toml").write_text(to_toml({
        "name": "fog under a box", "camera": OUT_CAMERA | {"width": 4, "height": 3},
        "medium": {"type": "homogeneous", "sigma_a": FOG_KA.tolist(), "sigma_s": FOG_KS.tolist()},
        "light": [{"type": "point", "position": LIGHT.tolist(), "intensity": INTENSITY}],
        "shape": [{"primitive": "box", "min": OUT_LO.tolist(), "max": OUT_HI.tolist(),
                   "interior": {"sigma_a": OUT_KA.tolist(), "sigma_s": OUT_KS.tolist()}}]}))
    with pytest.raises(raytrace.UserError, match="shadow-test samples.*inside shapes") as err:
        raytrace.render(tmp_path / "s.toml", "raymarch", shadow_test="samples", threads=1)
    assert "\n" not in str(err.value)


def test_another_index_matched_interior_attenuates_the_sun_inside(tmp_path):
    """Inside an index-matched shape the sun is attenuated by another index-matched interior on its
    way in (docs/bounded_media.md, volumetric shadows; values against a twin in
    tests/test_through_others.py): analytic's closed form does not hold it, so its segments go to the
    quadrature, counted, with a finite bound; alone, the box keeps its closed form."""
    sun = {"type": "directional", "direction": [0.2, -1.0, -0.1], "irradiance": 2.0}
    box = {"primitive": "box", "min": IN_LO.tolist(), "max": IN_HI.tolist(),
           "interior": {"sigma_a": IN_KA.tolist(), "sigma_s": IN_KS.tolist()}}
    above = {"primitive": "box", "min": [-0.6, 1.5, -0.6], "max": [0.6, 1.8, 0.6], "interior": {"sigma_a": 2.0}}
    base = {"name": "two boxes", "camera": IN_CAMERA, "light": [sun]}
    alone = render(write(tmp_path, base | {"shape": [box]}), "analytic", {}, SHADOWED)
    both = render(write(tmp_path, base | {"shape": [box, above]}), "analytic", {}, SHADOWED)
    inside = alone.image[..., 1] > 0
    assert inside.sum() >= 40
    assert np.all(np.isfinite(alone.error_bound[inside])) and np.all(np.isfinite(both.error_bound[inside]))
    assert alone.stats["inside: segments handed to quadrature"] == 0
    assert both.stats["inside: segments handed to quadrature"] >= inside.sum()
    assert np.count_nonzero(both.image[..., 1][inside] < 0.9 * alone.image[..., 1][inside]) >= 10


SUN = np.array([0.3, -1.0, -0.2]) / np.linalg.norm([0.3, -1.0, -0.2])
IRRADIANCE = 2.0


def sun_inside_twin(i, j):
    """inside_twin under the sun: lit where the ray from the point toward the sun misses the plate
    (its crossing of the plate's plane is linear in x), the light's path inside to the box's wall by
    the slab test (kinks where two walls' distances meet, linear in x too)."""
    o, d = oracle.camera_ray(IN_CAMERA, i, j)
    hit = box_clip(o, d, IN_LO, IN_HI)
    if hit is None:
        return np.zeros(3), False
    t_in, t_out = hit
    y0, (x_lo, x_hi), (z_lo, z_hi) = PLATE
    r = SUN / SUN[1]
    breaks = [(e - o[a] - (y0 - o[1]) * r[a]) / (d[a] - d[1] * r[a])
              for a, edges in ((0, (x_lo, x_hi)), (2, (z_lo, z_hi))) for e in edges]
    walls = [((IN_HI if -SUN[a] > 0 else IN_LO)[a], a) for a in range(3)]  # the walls the path back may meet
    for (b1, a1), (b2, a2) in [(walls[0], walls[1]), (walls[0], walls[2]), (walls[1], walls[2])]:
        # (b1 - o_a1 - x d_a1) / -s_a1 = (b2 - o_a2 - x d_a2) / -s_a2
        den = d[a1] * SUN[a2] - d[a2] * SUN[a1]
        if den != 0.0:
            breaks.append(((b1 - o[a1]) * SUN[a2] - (b2 - o[a2]) * SUN[a1]) / den)

    def blocked(x):
        p = o + x * d
        q = p + (y0 - p[1]) * r
        return x_lo < q[0] < x_hi and z_lo < q[2] < z_hi

    out = np.zeros(3)
    for c in range(3):
        kt = IN_KS[c] + IN_KA[c]

        def f(x):
            if blocked(x):
                return 0.0
            k = slab(o + x * d, -SUN, IN_LO, IN_HI)[1]
            return IN_KS[c] * IRRADIANCE / (4 * math.pi) * math.exp(-kt * (x - t_in) - kt * k)
        out[c] = quad(f, t_in, t_out, breaks)
    return out, True


def test_analytic_shadows_the_sun_inside_an_index_matched_box(tmp_path):
    """analytic's closed form over the lit pieces: within 1e-9 of the twin on every pixel whose ray
    meets the box, the error within its bound; unshadowed, the plate's shadow is missing."""
    prep = write(tmp_path, {"name": "sun shadow in a box", "camera": IN_CAMERA,
                            "light": [{"type": "directional", "direction": SUN.tolist(), "irradiance": IRRADIANCE}],
                            "shape": [{"primitive": "box", "min": IN_LO.tolist(), "max": IN_HI.tolist(),
                                       "interior": {"sigma_a": IN_KA.tolist(), "sigma_s": IN_KS.tolist()}},
                                      {"primitive": "quad", "reflectance": 0.5,
                                       "corners": [[0.1, 2.0, -1.5], [1.5, 2.0, -1.5], [1.5, 2.0, 1.5],
                                                   [0.1, 2.0, 1.5]]}]})
    twin = [[sun_inside_twin(i, j) for i in range(IN_CAMERA["width"])] for j in range(IN_CAMERA["height"])]
    ref = np.array([[v for v, _ in row] for row in twin])
    seen = np.array([[s for _, s in row] for row in twin])
    assert seen.sum() >= 40
    res = render(prep, "analytic", {}, SHADOWED)
    rel = relative(res.image, ref)[seen]
    print(f"analytic, sun shadow inside: worst relative error {rel.max():.2e}")
    assert rel.max() <= 1e-9
    assert res.stats["inside: lit pieces"] > 0 and res.stats["inside: segments unshadowed (refractive or planar model)"] == 0
    assert np.all(np.abs(res.image - ref)[seen] <= res.error_bound[seen])
    off = render(prep, "analytic", {}, UNSHADOWED).image
    assert np.max(relative(off, ref)[seen]) > 0.2
