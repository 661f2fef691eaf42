"""The pbrt round trip of a sphere that holds a medium (benchmarks/sphere_in_fog.toml: in fog, under a
point light): the scene with its sphere exact, the same sphere as a mesh of 64 segments, and the exact
scene exported to pbrt-v4 and read back, rendered with quadrature, with and without volumetric
shadows, one thread: the CPU seconds of each render, the best of `--rounds` interleaved runs after one
run of each to compile the kernels.

    python benchmarks/sphere_round_trip.py [--rounds 3]     # at the scene's 64 x 48
"""
import argparse
import pathlib
import tempfile
import time
import tomllib

import raytrace
from raytrace.io import pbrt

SCENE = pathlib.Path(__file__).with_name("sphere_in_fog.toml")


def variants(folder: pathlib.Path) -> dict:
    """name -> scene path: the exact sphere, its 64-segment mesh, and the exact one through pbrt and back."""
    raw = tomllib.loads(SCENE.read_text())
    sphere = raw["shape"][1]
    out = {}
    for name, extra in (("exact", {"exact": True}), ("mesh 64", {"segments": 64})):
        path = folder / f"{name.replace(' ', '_')}.toml"
        path.write_text(SCENE.read_text().replace('radius = 1.0\n', 'radius = 1.0\n' + "".join(
            f"{k} = {str(v).lower()}\n" for k, v in extra.items()), 1))
        out[name] = path
    assert "exact" not in sphere and "segments" not in sphere
    back = folder / "back.pbrt"
    pbrt.export(tomllib.loads(out["exact"].read_text()), back, str(out["exact"]), False)
    out["pbrt round trip"] = back
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=3)
    rounds = ap.parse_args().rounds
    with tempfile.TemporaryDirectory() as tmp:
        scenes = variants(pathlib.Path(tmp))
        best = {}
        for run in range(rounds + 1):
            for name, path in scenes.items():
                for shadows in (False, True):
                    start = time.process_time()
                    raytrace.render(str(path), "quadrature", volumetric_shadows=shadows, threads=1)
                    if run:  # the first round compiles
                        best[name, shadows] = min(best.get((name, shadows), float("inf")), time.process_time() - start)
    print(f"{'sphere':16s} {'unshadowed':>11s} {'shadowed':>9s}")
    for name in scenes:
        print(f"{name:16s} {best[name, False]:10.3f}s {best[name, True]:8.3f}s")


if __name__ == "__main__":
    main()
