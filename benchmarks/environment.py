"""The environment light: what it costs against a directional light of the same irradiance, and its error
against the number of directions (docs/environment.md).

    RAYTRACE_ASSETS=../shared/scenes python benchmarks/environment.py [--quick] [--seeds N]

Cost: 16 x 12 pixels of a height fog over a 6 x 6 ground quad, `quadrature`, volumetric shadows on, one
thread, lit by a constant environment L of N directions or by a directional light straight down of
irradiance pi L (what the sky gives the open ground). CPU seconds of each render after a warm-up (compilation
excluded), the lights interleaved, best of `rounds`.
Error: the twins of tests/test_environment.py (rays up through a height fog, 2 x 2 pixels at rtol 1e-10; a ground
point under an opaque plate) against `quadrature` with N `directions`, over `seeds` seeds (each render's directions
are its seed's: the error is random). Per count: the mean relative error (0 within its standard error: unbiased)
and the rms relative error, each +- its standard error over the seeds, and mean e^2 / the mean variance the render
reports (1 where the variance is the expected square error).
Sampling error: the fog twin's relative error per count over `--sampling-seeds` seeds (default 4096) from the closed
form of each seed's directions (tests/test_environment.py `fog_by_directions`, which a render equals to 1e-13:
tests/test_environment_directions.py), the same three figures without rendering: with 32 seeds a mean 5 of its
standard errors from 0 came from seeds 0 ... 31 alone (their mean at 1024 directions is the largest of 625 blocks
of 32 seeds).
"""
import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import raytrace  # noqa: E402
from raytrace.camera import generate_rays  # noqa: E402
from raytrace.lights import environment  # noqa: E402
from raytrace.rendering import renderer  # noqa: E402
from tests import test_environment as twins  # noqa: E402

L = [0.2, 0.3, 0.5]
SKY = {"type": "environment", "radiance": L}
SUN = {"type": "directional", "direction": [0.0, -1.0, 0.0], "irradiance": [math.pi * v for v in L]}


def fog_scene(light):
    return raytrace.load({
        "camera": {"position": [0.0, 1.0, 5.0], "look_at": [0.0, 0.5, 0.0], "fov": 60.0, "width": 16, "height": 12},
        "shape": [{"primitive": "quad", "corners": [[-3.0, 0.0, 3.0], [3.0, 0.0, 3.0], [3.0, 0.0, -3.0],
                                                     [-3.0, 0.0, -3.0]], "reflectance": 0.5}],
        "light": [light], "medium": twins.FOG})


def cpu_seconds(light, count):
    environment.COUNT = count
    start = time.process_time()
    raytrace.render(fog_scene(light), "quadrature", threads=1)
    return time.process_time() - start


def relative_errors(sc, exact, seeds):
    """(seeds, values) relative errors of `sc`'s renders with seeds 0 ... seeds - 1 against `exact` (H, W, 3),
    and their reported variances relative to exact^2."""
    prep = renderer.prepare(sc)
    imgs = [raytrace.render(prepared=prep, method="quadrature", rtol=1e-10, seed=seed) for seed in range(seeds)]
    e = np.array([(img.array / exact - 1.0).ravel() for img in imgs])
    return e, np.array([(img.variance / exact**2).ravel() for img in imgs])


def figures(e, v) -> str:
    """mean and rms relative error e over the seeds (rows) and values, each +- its standard error (the rms by the
    delta method from the seeds' mean squares), and mean e^2 / the mean reported relative variance v."""
    per_seed, squares = e.mean(axis=1), (e**2).mean(axis=1)
    n = len(e)
    rms = math.sqrt(squares.mean())
    rms_se = squares.std(ddof=1) / math.sqrt(n) / (2.0 * rms)
    return (f"mean {per_seed.mean():+.2e} +- {per_seed.std(ddof=1) / math.sqrt(n):.1e}, "
            f"rms {rms:.2e} +- {rms_se:.1e}, e^2 / variance {squares.mean() / v.mean():.2f}")


def errors(counts, seeds):
    """The fog twin's pixels' and the plate twin's relative errors per count, over `seeds` seeds."""
    up = twins.scene([SKY], medium=twins.FOG, camera=twins.UP_CAMERA)
    origins, dirs = generate_rays(up.camera)
    fog_ref = np.array([twins.fog_twin(o, d, L, L, 0.02, 0.1, 2.0) for o, d in zip(origins, dirs)])
    fog_ref = fog_ref.reshape(up.camera.height, up.camera.width, 3)
    F = 4 * (2 / math.sqrt(2) * math.atan(1 / math.sqrt(2)) / (2 * math.pi))  # the plate's form factor
    plate_ref = (0.5 * np.array(L) * (1 - F)).reshape(1, 1, 3)
    print(f"relative error over {seeds} seeds (mean, rms, each +- its standard error; mean e^2 / the mean "
          "reported variance)")
    for n in counts:
        sky = {**SKY, "directions": n}
        fog = twins.scene([sky], medium=twins.FOG, camera=twins.UP_CAMERA)
        plate = twins.scene([sky], camera=twins.POINT_CAMERA, shapes=[twins.GROUND, twins.PLATE])
        print(f"N = {n}: fog {figures(*relative_errors(fog, fog_ref, seeds))}")
        print(f"N = {n}: plate {figures(*relative_errors(plate, plate_ref, seeds))}")


def sampling_errors(counts, seeds):
    """The fog twin's relative errors per count over `seeds` seeds from its directions' closed form, with the
    variance the render reports (the groups' spread: renderer.py `shade_groups`)."""
    up = twins.scene([SKY], medium=twins.FOG, camera=twins.UP_CAMERA)
    rays = list(zip(*generate_rays(up.camera)))
    exact = np.array([twins.fog_twin(o, d, L, L, 0.02, 0.1, 2.0) for o, d in rays])
    G = environment.GROUPS
    print(f"sampling error over {seeds} seeds (closed form of each seed's directions)")
    for n in counts:
        e, v = [], []
        for seed in range(seeds):
            rows = environment.rows(up.lights[0], n, seed, 0)
            parts = np.array([[twins.fog_by_directions(o, d, L if g == 0 else [0.0] * 3, rows.axis[mask],
                                                       rows.intensity[mask], 0.02, 0.1, 2.0)
                               for g, mask in enumerate(np.array_split(np.arange(n), G))] for o, d in rays])
            e.append((parts.sum(axis=1) / exact - 1.0).ravel())
            own = parts.copy()
            own[:, 0] -= np.array([twins.fog_by_directions(o, d, L, np.zeros((0, 3)), np.zeros((0, 3)), 0.02, 0.1,
                                                           2.0) for o, d in rays])  # a group's light only
            v.append((G / (G - 1) * ((own - own.sum(axis=1, keepdims=True) / G) ** 2).sum(axis=1) / exact**2).ravel())
        print(f"N = {n}: fog {figures(np.array(e), np.array(v))}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--seeds", type=int, default=None, help="seeds of each error figure (default 64; --quick 16)")
    ap.add_argument("--sampling-seeds", type=int, default=4096, help="seeds of the closed-form sampling error")
    args = ap.parse_args()
    counts, rounds = ((16, 64), 1) if args.quick else ((16, 64, 256), 2)
    seeds = args.seeds or (16 if args.quick else 64)
    cpu_seconds(SUN, environment.COUNT), cpu_seconds(SKY, 4)  # compile
    best = {}
    for _ in range(rounds):
        for name, light, n in [("directional", SUN, environment.COUNT)] + [(f"environment N = {n}", SKY, n)
                                                                           for n in counts]:
            best[name] = min(best.get(name, math.inf), cpu_seconds(light, n))
    for name, s in best.items():
        print(f"{name}: {s:.2f} CPU s, {s / best['directional']:.1f} x directional")
    errors(counts + (1024,), seeds)
    sampling_errors(counts + (1024,), args.sampling_seeds)


if __name__ == "__main__":
    main()
