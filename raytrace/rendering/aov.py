"""Output layers (AOVs): what a render writes beside its image when asked (`aov` in [render],
`--aov`), each averaged over its pixel's samples as the image is:

- `depth` (`depth.Z`): the distance along the camera ray to its first hit, inf where it leaves the scene;
- `normal` (`normal.X/Y/Z`): the world-space shading normal there, turned toward the camera (the normal
  of the surface term, eq. 5), 0 where nothing is hit;
- `albedo` (`albedo.R/G/B`): the Lambertian reflectance there, 0 on shapes that hold a medium and
  where nothing is hit;
- `lights`: `light0.R/G/B`, ... the radiance each light of the scene alone gives the pixel (its rays
  shaded again with the other lights' intensities zero, renderer.Prepared.only: air-light, surface
  term and media inside shapes), the [[light]] tables in order, then the shapes with `emission`
  (lights/: `Lights.owner`), and `emission.R/G/B`, what no light gives: the background (or the
  environment light's radiance, seen by rays that leave the scene) and the emitters seen directly, through shapes that hold a medium and in their Fresnel mirrors. The light
  layers and emission sum to the image (to rounding: the same terms added in another order).
"""
from __future__ import annotations

import numpy as np

from ..errors import UserError
from ..interiors import shapes
from ..shading import facing_normals, shading_normals

NAMES = ("depth", "normal", "albedo", "lights")
HITS = {"depth": ("Z",), "normal": ("X", "Y", "Z"), "albedo": ("R", "G", "B")}  # from the first hits
RGB = ("R", "G", "B")


def check(names, source: str) -> tuple[str, ...]:
    """The layers `names` (a list of NAMES, or one comma-separated string) in NAMES' order; UserError
    naming `source` (the key or flag) for anything else."""
    if isinstance(names, str):
        names = [n.strip() for n in names.split(",") if n.strip()]
    if not isinstance(names, (list, tuple)) or not all(isinstance(n, str) for n in names):
        raise UserError(f"{source}: must be a list of layer names, e.g. [\"depth\", \"lights\"]; "
                        f"choose from {', '.join(NAMES)}")
    unknown = [n for n in names if n not in NAMES]
    if unknown:
        raise UserError(f"{source}: unknown layer {unknown[0]!r}; choose from {', '.join(NAMES)}")
    return tuple(n for n in NAMES if n in names)


def layers(names, n_lights: int) -> list[tuple[str, tuple[str, ...]]]:
    """(layer, its channel suffixes) of the requested `names` (checked), in the order their columns
    are stored: the first-hit layers, then light0 ... and emission."""
    out = [(n, HITS[n]) for n in names if n in HITS]
    if "lights" in names:
        out += [(f"light{i}", RGB) for i in range(n_lights)] + [("emission", RGB)]
    return out


def width(names, n_lights: int) -> int:
    """The number of columns of the layers `names`."""
    return sum(len(c) for _, c in layers(names, n_lights))


def hit_columns(prep, names, origins, dirs, hits) -> np.ndarray:
    """(N, k) columns of the first-hit layers among `names` (depth, normal, albedo, in that order) of
    the camera rays origins + t dirs, from their `hits` (shading.first_hits: the renderer's own)."""
    wanted = [n for n in names if n in HITS]
    t, prim, ground = hits
    medium = prep.scene.medium
    normal, albedo = np.zeros((len(t), 3)), np.zeros((len(t), 3))
    hit = prim >= 0
    if hit.any() and {"normal", "albedo"} & set(wanted):
        p = prim[hit]
        points = origins[hit] + t[hit, None] * dirs[hit]
        normal[hit] = shading_normals(prep.accel, prep.corner_normals, p, points,
                                      facing_normals(prep.accel.hit_normals(p, points), dirs[hit]))
        albedo[hit] = np.where(shapes.enters(prep, p)[:, None], 0.0, prep.reflectance[p])
    if ground.any() and {"normal", "albedo"} & set(wanted):
        normals, refl = medium.ground_surface(origins[ground] + t[ground, None] * dirs[ground])
        normal[ground], albedo[ground] = facing_normals(normals, dirs[ground]), refl
    columns = {"depth": t[:, None], "normal": normal, "albedo": albedo}
    return np.concatenate([columns[n] for n in wanted], axis=1) if wanted else np.zeros((len(t), 0))


def sources(lights) -> int:
    """The number of light layers of `lights` (lights.Lights): its scene lights and emissive shapes."""
    return int(lights.owner.max()) + 1 if len(lights) else 0


def light_masks(lights) -> list[np.ndarray]:
    """The rows of each light layer (boolean masks over the `Lights` rows: one scene light's, an area
    light's emitter points together), then none (emission)."""
    return [lights.owner == i for i in range(sources(lights))] + [np.zeros(len(lights), dtype=bool)]


def split(names, n_lights: int, columns: np.ndarray) -> dict[str, np.ndarray]:
    """The layers of an (H, W, width) array of columns: name -> (H, W, channels)."""
    out, start = {}, 0
    for name, suffixes in layers(names, n_lights):
        out[name] = columns[..., start:start + len(suffixes)]
        start += len(suffixes)
    return out


def exr_channels(arrays: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """EXR channels "layer.suffix" -> (H, W) of the layers `arrays` (`split`'s)."""
    out = {}
    for name, array in arrays.items():
        suffixes = HITS.get(name, RGB)
        out.update({f"{name}.{s}": array[..., i] for i, s in enumerate(suffixes)})
    return out
