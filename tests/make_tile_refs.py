"""Regenerate tests/data/tiles_9596215.npz: the renders of tests/test_tiles.py made by the code of
main at 9596215 (tiles of 16,384 rays in bands of rows), which the interleaved tiles must match
bit for bit. Run it on that commit's tree, never on this one's:

    git archive 9596215 | tar -x -C /tmp/main9596215
    python tests/make_tile_refs.py /tmp/main9596215

Each case renders a box room with a plate below its light (conftest.box_room) through the API;
one has more rays a row than 16,384 (its pixels' samples are summed in two ranges), one is a crop.
"""
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
DATA = HERE / "data" / "tiles_9596215.npz"
PLATE = {"primitive": "quad", "corners": [[-1.0, 1.2, -2.0], [1.0, 1.2, -2.0], [1.0, 1.2, 0.0], [-1.0, 1.2, 0.0]],
         "reflectance": 0.3}
CASES = {  # name: (method, render options and method parameters)
    "analytic_shadows": ("analytic", dict(width=24, height=16, spp=4, volumetric_shadows=True)),
    "analytic_crop": ("analytic", dict(width=24, height=16, spp=4, volumetric_shadows=True, crop=(3, 2, 17, 11))),
    "montecarlo": ("montecarlo", dict(width=20, height=14, spp=2, seed=3, volumetric_shadows=True)),
    "two_sample_ranges": ("analytic", dict(width=128, height=2, spp=144, volumetric_shadows=False)),
}


def scene() -> dict:
    from tests.conftest import box_room  # plain data: no import of raytrace

    s = box_room()
    s["shape"].append(dict(PLATE))
    return s


def render_case(raytrace, name: str, **extra):
    """The case's image, variance (zeros if none), error bound and statistics, rendered by `raytrace`."""
    method, options = CASES[name]
    img = raytrace.render(scene(), method, **options, **extra)
    variance = img.variance if img.variance is not None else np.zeros_like(img.array)
    return img.array, variance, img.error_bound, img.stats


def main(tree: str):
    sys.path.insert(0, str(Path(tree).resolve()))
    sys.path.insert(1, str(HERE.parent))
    import raytrace

    assert Path(raytrace.__file__).resolve().is_relative_to(Path(tree).resolve()), raytrace.__file__
    arrays = {}
    for name in CASES:
        image, variance, bound, stats = render_case(raytrace, name, threads=1)
        arrays.update({f"{name}/image": image, f"{name}/variance": variance, f"{name}/bound": bound,
                       f"{name}/stats": np.array(json.dumps(stats, sort_keys=True))})
    np.savez(DATA, **arrays)
    print(f"wrote {DATA} from {raytrace.__file__}")


if __name__ == "__main__":
    main(sys.argv[1])
