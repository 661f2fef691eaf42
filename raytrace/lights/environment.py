"""The environment light: radiance L(w) arriving from every direction w at infinity, constant or a
linear image, turned by `rotate` (degrees about x, y, z, as a shape's transform: world = Rz Ry Rx
local; `mirror` first negates the local x) and multiplied by `scale`. The image's `mapping`:

- "equirectangular" (default): the environment camera's mapping (camera.py: up +y, phi = 0 forward
  along -z, phi growing toward +x; row r spans theta in [pi r / H, pi (r + 1) / H] from up, column c
  phi in [2 pi (c / W - 1/2), 2 pi ((c + 1) / W - 1/2)]);
- "octahedral": pbrt-v4's equal-area square (octahedral.py), its centre up (+y), every texel 4 pi / N^2.

With `filter` "nearest" (default) the map is piecewise constant: each texel's value over its whole
solid angle (a constant is a 1 x 1 map). An equirectangular map may instead be interpolated
bilinearly between its texel centres ("bilinear") or as Mitsuba 3's envmap ("mitsuba": its first and
last rows on the poles): bilinear.py.

To the kernels it is COUNT directional rows. Directions are drawn by importance sampling of the map.
A piecewise constant map: a texel with probability proportional to its luminance times its solid
angle (equirectangular: Omega_r = (2 pi / W)(cos theta_r - cos theta_r+1), the exact sin(theta)
weight; octahedral: 4 pi / N^2), marginal in the row then conditional in the column, and uniformly
in solid angle inside it (uniform in cos theta and phi; in the octahedral square, which preserves
area), so pdf(w) = P_texel / Omega (a constant environment: the uniform sphere, 1 / 4 pi). An
interpolated map: pdf(w) = Y(w) / Z exactly, Y its interpolated luminance (bilinear.py). Row k
travels along -w_k with irradiance L(w_k) / pdf(w_k) / COUNT: the rows' sum over any smooth f is the
Monte Carlo estimate of the integral of L f over the sphere, so every method integrates each row as a
directional light's air-light and surface term, with its visibility (shadow rays, exact lit intervals).
For each pixel sample the COUNT points are GROUPS independent groups (`points`), each the lattice
((k + 1/2) / n, {k / golden}) shifted mod 1 by uniforms keyed by (the sample's index, the group, the seed)
(Cranley-Patterson) and folded by the tent u0 -> 1 - |2 u0 - 1| (the baker's transform): each group's rows
sum to an unbiased estimate of the integral, and the renderer reports their spread as the variance
(renderer.py `shade_groups`); its bound is none (Rows.cubature). Rows of a grey map (and a constant) have
the same ratio L / pdf, so the rows' total irradiance is exact, and the tent makes each group's cos theta
nodes symmetric about the horizon: an open horizontal ground under a constant sky is exact in every group.
Rays that leave the scene see L(w) (`radiance`).
"""
from __future__ import annotations

import dataclasses
import hashlib
import math
import warnings

import numpy as np

from ..geometry.vectors import rotation_matrix
from ..rng import uniform
from . import bilinear, octahedral
from .directional import CODE as DIRECTIONAL
from .light import NO_CONE, Light, Rows, power

NAME = "environment"
CODE = 6
KEYS = frozenset({"type", "radiance", "map", "rotate", "scale", "mapping", "filter", "mirror", "directions"})
MAPPINGS = ("equirectangular", "octahedral")
FILTERS = ("nearest", "bilinear", "mitsuba")
COUNT = 64  # directions of a pixel sample (docs/environment.md: the error against the count)
GROUPS = 2  # independent groups of directions: their spread is the variance
DIM_SHIFT = 1 << 51  # the random-number dimensions (rng.py) of the groups' shifts
LUMA = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709 luminance: the texels' sampling weight
GOLDEN = (1.0 + math.sqrt(5.0)) / 2.0
MIRROR = np.diag([-1.0, 1.0, 1.0])  # `mirror`: the local x negated


def parse(read, key, raw) -> Light:
    """A constant `radiance` or a `map` (an EXR read by the scene reader, `read.image`) with its `mapping`
    and `filter`, `rotate`, `mirror`, `scale` (>= 0) and the `directions` of a pixel sample (default COUNT)."""
    if ("radiance" in raw) == ("map" in raw):
        read.fail(key, "give either radiance (a constant environment) or map (an EXR)" if "map" in raw
                  else "missing radiance", f"add {key}.radiance = [0.2, 0.3, 0.5] or {key}.map = \"sky.exr\"")
    scale = float(read.number(f"{key}.scale", raw.get("scale", 1.0), minimum=0.0))
    rotate = read.vec3(f"{key}.rotate", raw.get("rotate", [0.0, 0.0, 0.0]))
    mirror = raw.get("mirror", False)
    if not isinstance(mirror, bool):
        read.fail(f"{key}.mirror", f"expected true or false, got {mirror!r}", f"write {key}.mirror = true")
    directions = raw.get("directions")
    if directions is not None and (isinstance(directions, bool) or not isinstance(directions, int)
                                   or directions < 2 * GROUPS or directions % (2 * GROUPS)):
        read.fail(f"{key}.directions", f"expected a multiple of {2 * GROUPS} (the groups' even counts), got "
                  f"{directions!r}", f"write {key}.directions = {4 * COUNT}")
    mapping = read.string(f"{key}.mapping", raw.get("mapping", MAPPINGS[0]), MAPPINGS)
    filt = read.string(f"{key}.filter", raw.get("filter", FILTERS[0]), FILTERS)
    if "radiance" in raw:
        for k in ("mapping", "filter"):
            if k in raw:
                read.fail(f"{key}.{k}", "applies to a map, not a constant radiance", f"remove {key}.{k}")
        image, source = read.rgb(f"{key}.radiance", raw["radiance"]).reshape(1, 1, 3), None
    else:
        if not isinstance(raw["map"], str):
            read.fail(f"{key}.map", f"expected a file name, got {raw['map']!r}", f'write {key}.map = "sky.exr"')
        image, source = read.image(f"{key}.map", raw["map"], "environment map")
        if not (np.all(np.isfinite(image)) and np.all(image >= 0.0)):
            read.fail(f"{key}.map", f"{source} holds negative or non-finite values",
                      "give a linear map of radiances >= 0")
        _check_shape(read, key, image, source, mapping, filt)
    image = power(read, f"{key}.{'radiance' if 'radiance' in raw else 'map'}", image * scale)
    rotation = rotation_matrix(rotate) @ (MIRROR if mirror else np.eye(3))  # as a shape's transform: Rz Ry Rx
    digest = hashlib.sha256(np.ascontiguousarray(image).tobytes()).hexdigest()  # (checkpoints' fingerprint)
    return Light(np.zeros(3), integral(image, mapping, filt) / (4.0 * math.pi), CODE,
                 emitter={"map": image, "rotation": rotation, "file": source and str(source), "digest": digest,
                          "mapping": mapping, "filter": filt, "directions": directions})


def _check_shape(read, key, image, source, mapping, filt):
    """Refuse a map its mapping and filter cannot take."""
    H, W = image.shape[:2]
    if mapping == "octahedral" and H != W:
        read.fail(f"{key}.map", f"{source} is {W} x {H}: an octahedral map is square", "give a square map "
                  "(pbrt-v4's equal-area octahedral), or mapping = \"equirectangular\"")
    if mapping == "octahedral" and filt != "nearest":
        read.fail(f"{key}.filter", f"an octahedral map is looked up nearest (as pbrt-v4), not {filt!r}",
                  f"remove {key}.filter")
    if filt == "mitsuba" and H < 3:  # (Mitsuba pads such a map, repeating its last row: Bitmap::pad_to)
        read.fail(f"{key}.map", f"{source} has {H} row{'s' * (H > 1)}: the mitsuba filter needs at least 3",
                  "give a taller map, or filter = \"bilinear\"")


def rotate_keys(matrix) -> dict:
    """The keys `rotate` (and `mirror` when it is improper) of an orthogonal local-to-world `matrix`
    (world = R local): the inverse of `parse`'s rotation, for the importers."""
    from scipy.spatial.transform import Rotation

    mirror = bool(np.linalg.det(matrix) < 0.0)
    turn = Rotation.from_matrix(np.asarray(matrix, float) @ (MIRROR if mirror else np.eye(3)))
    with warnings.catch_warnings():  # gimbal lock: scipy still returns angles of the same rotation
        warnings.simplefilter("ignore", UserWarning)
        angles = turn.as_euler("xyz", degrees=True) + 0.0  # extrinsic x, y, z: a shape's `rotate` (Rz Ry Rx)
    return {"rotate": [0.0 if abs(a) < 1e-12 else float(a) for a in angles], **({"mirror": True} if mirror else {})}


def describe(light) -> str:
    image, em = light.emitter["map"], light.emitter
    kinds = "".join(f", {em[k]}" for k, default in (("mapping", MAPPINGS[0]), ("filter", FILTERS[0]))
                    if em[k] != default)
    what = (f"map {em['file']} ({image.shape[1]} x {image.shape[0]}{kinds})" if em["file"] else
            f"constant radiance {image[0, 0].tolist()}")
    count = em["directions"] or COUNT
    turned = ("" if np.allclose(em["rotation"], np.eye(3)) else
              ", mirrored" if np.linalg.det(em["rotation"]) < 0.0 else ", rotated")
    return (f"{NAME}, {what}{turned}, mean radiance {light.intensity.tolist()}; {count} directions in {GROUPS} "
            "groups a pixel sample (importance-sampled, shifted by the seed and the sample; their spread is the "
            "variance)")


def solid_angles(height: int, width: int, mapping: str = MAPPINGS[0]) -> np.ndarray:
    """(H,) the solid angle of one texel of each row: (2 pi / W)(cos theta_r - cos theta_r+1), or 4 pi / N^2
    (octahedral)."""
    if mapping == "octahedral":
        return np.full(height, 4.0 * np.pi / (height * width))
    c = np.cos(np.pi * np.arange(height + 1) / height)
    return 2.0 * np.pi / width * (c[:-1] - c[1:])


def integral(image, mapping: str = MAPPINGS[0], filt: str = FILTERS[0]) -> np.ndarray:
    """The integral of L over the sphere per channel (exact for the piecewise-constant or interpolated map)."""
    if filt != "nearest":
        return bilinear.integral(image, filt)
    return np.einsum("rcx,r->x", image, solid_angles(*image.shape[:2], mapping))


def _weights(light):
    """(texel weights luminance x solid angle (H, W), solid angles (H,)) of a piecewise constant map."""
    image = light.emitter["map"]
    omega = solid_angles(*image.shape[:2], light.emitter["mapping"])
    return (image @ LUMA) * omega[:, None], omega


def directions(light, u) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(world directions (n, 3), their pdf (n,) per steradian, L (n, 3) there) of the points u (n, 2) in [0, 1)^2
    through the inverse distribution: u0 picks the row (marginal) and then cos theta inside it (the
    octahedral square's v), u1 the column (conditional) and then phi inside it (u). The map must not be
    black."""
    image, em = light.emitter["map"], light.emitter
    if em["filter"] != "nearest":
        local, density, value = bilinear.sample(image, em["filter"], LUMA, u)
        return local @ em["rotation"].T, density, value
    w, omega = _weights(light)
    H, W = w.shape
    rows = np.cumsum(w.sum(axis=1))
    total = rows[-1]
    r = np.minimum(np.searchsorted(rows, u[:, 0] * total, side="right"), H - 1)
    start = np.concatenate([[0.0], rows])[r]
    v = np.clip((u[:, 0] * total - start) / np.maximum(rows[r] - start, 1e-300), 0.0, 1.0)
    cols = np.cumsum(w[r], axis=1)
    c = np.minimum((cols <= (u[:, 1] * cols[:, -1])[:, None]).sum(axis=1), W - 1)  # skips texels of weight 0
    before = np.where(c > 0, cols[np.arange(len(c)), c - 1], 0.0)
    s = np.clip((u[:, 1] * cols[:, -1] - before) / np.maximum(w[r, c], 1e-300), 0.0, 1.0)
    if em["mapping"] == "octahedral":
        local = octahedral.directions((c + s) / W, (r + v) / H)
    else:
        edges = np.cos(np.pi * np.arange(H + 1) / H)
        cos_t = edges[r] + v * (edges[r + 1] - edges[r])
        phi = 2.0 * np.pi * ((c + s) / W - 0.5)
        sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
        local = np.stack([sin_t * np.sin(phi), cos_t, -sin_t * np.cos(phi)], axis=1)
    return local @ em["rotation"].T, w[r, c] / total / omega[r], image[r, c]


def texels(light, dirs) -> tuple[np.ndarray, np.ndarray]:
    """(row, column) of the texels the world directions (n, 3) fall in (a piecewise constant map)."""
    local = np.asarray(dirs, float) @ light.emitter["rotation"]
    H, W = light.emitter["map"].shape[:2]
    if light.emitter["mapping"] == "octahedral":
        return octahedral.texels(local, H)
    theta = np.arccos(np.clip(local[:, 1], -1.0, 1.0))
    phi = np.arctan2(local[:, 0], -local[:, 2])
    return (np.minimum((theta / np.pi * H).astype(np.int64), H - 1),
            np.floor((phi / (2.0 * np.pi) + 0.5) * W).astype(np.int64) % W)


def pdf(light, dirs) -> np.ndarray:
    """The sampling density (n,) per steradian of the world directions (n, 3)."""
    em = light.emitter
    if em["filter"] != "nearest":
        return bilinear.pdf(em["map"], em["filter"], LUMA, np.asarray(dirs, float) @ em["rotation"])
    w, omega = _weights(light)
    r, c = texels(light, dirs)
    return w[r, c] / w.sum() / omega[r]


def radiance(light, dirs) -> np.ndarray:
    """L (n, 3) toward the world directions (n, 3): what a ray leaving the scene along them sees."""
    em = light.emitter
    if em["filter"] != "nearest":
        return bilinear.radiance(em["map"], em["filter"], np.asarray(dirs, float) @ em["rotation"])
    r, c = texels(light, dirs)
    return em["map"][r, c]


def lattice(n: int) -> np.ndarray:
    """The n points ((k + 1/2) / n, {k / golden}) of [0, 1)^2 (the spherical Fibonacci lattice's)."""
    k = np.arange(n)
    return np.stack([(k + 0.5) / n, np.mod(k / GOLDEN, 1.0)], axis=1)


def points(count: int, seed: int = 0, sample: int = 0) -> list[np.ndarray]:
    """The GROUPS groups (count // GROUPS points or one more; count >= GROUPS) of points of [0, 1)^2 of a pixel
    sample, each uniform on its own: the lattice shifted by the group's uniforms (s0, s1) mod 1, keyed by
    (sample GROUPS + group, seed) (rng.py), then u0 -> 1 - |2 u0 - 1| (the tent: a midpoint-like rule in u0
    whose nodes pair about the horizon)."""
    assert count >= GROUPS, count
    out = []
    for g in range(GROUPS):
        size = count * (g + 1) // GROUPS - count * g // GROUPS
        key = np.uint64(sample) * np.uint64(GROUPS) + np.uint64(g)
        shift = np.array([uniform(key, np.uint64(DIM_SHIFT + k), np.uint64(seed)) for k in range(2)])
        u = np.mod(lattice(size) + shift, 1.0)
        out.append(np.stack([1.0 - np.abs(2.0 * u[:, 0] - 1.0), u[:, 1]], axis=1))
    return out


def rows(light, count: int | None = None, seed: int = 0, sample: int = 0) -> Rows:
    """`count` (default the light's `directions`, else COUNT; a multiple of GROUPS) directional rows of a pixel
    sample, the GROUPS groups of `points` one after another: axis -w_k, irradiance L(w_k) / pdf(w_k) / (GROUPS n),
    n its group's size (each group's sum an unbiased estimate of the integral / GROUPS); none for a black
    environment."""
    count = count or light.emitter["directions"] or COUNT
    em = light.emitter
    if not integral(em["map"], em["mapping"], em["filter"]) @ LUMA > 0.0:
        count = 0
    u = points(count, seed, sample) if count else []
    dirs, density, value = (directions(light, np.concatenate(u)) if count else
                            (np.zeros((0, 3)), np.ones(0), np.zeros((0, 3))))
    share = np.repeat([GROUPS * len(g) for g in u], [len(g) for g in u]) if count else np.ones(0)
    return Rows(np.zeros((count, 3)), value / (density * share)[:, None],
                np.full(count, DIRECTIONAL, dtype=np.int64), np.ascontiguousarray(-dirs),
                np.tile([*NO_CONE, 0.0], (count, 1)), cubature=True)


def owned(lights) -> np.ndarray:
    """(L,) whether each row of `lights` (Lights) is one of the scene's environment light's directions."""
    return np.isin(lights.owner, [o for o, kind in enumerate(lights.scene_kinds) if kind == NAME])


def _rows_of(lights) -> np.ndarray:
    """The indices of the rows of the scene's environment light among `lights` (Lights; none without one)."""
    return np.flatnonzero(owned(lights))


def seeded(lights, scene_lights, seed: int, sample: int):
    """`lights` (Lights of `scene_lights`) with the environment's rows of the pixel sample `sample` for `seed`
    (`rows`); `lights` itself where they are the same."""
    at = _rows_of(lights)
    if not len(at):
        return lights
    new = rows(scene_lights[int(lights.owner[at[0]])], len(at), seed, sample)
    if np.array_equal(new.intensity, lights.intensity[at]) and np.array_equal(new.axis, lights.axis[at]):
        return lights
    intensity, axis = lights.intensity.copy(), lights.axis.copy()
    intensity[at], axis[at] = new.intensity, new.axis
    return dataclasses.replace(lights, intensity=intensity, axis=axis)


def groups(lights) -> list[np.ndarray]:
    """(L,) masks of the environment's rows among `lights` (Lights), one per group of `points`; [] without
    an environment. Each group's rows sum to an unbiased estimate of the environment's light / GROUPS."""
    at = _rows_of(lights)
    if not len(at):
        return []
    masks = np.zeros((GROUPS, len(lights)), dtype=bool)
    for g in range(GROUPS):
        masks[g, at[len(at) * g // GROUPS:len(at) * (g + 1) // GROUPS]] = True
    return list(masks)
