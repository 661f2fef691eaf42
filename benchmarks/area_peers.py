"""An occluded area light against Mitsuba 3 (issue 36, Speed): the time each needs to reach 1e-2 mean
relative error on the same scene and machine (docs/area_lights.md, "Against Mitsuba 3").

    pip install mitsuba                  # >= 3.5; exits 0 with a skip message without it
    python benchmarks/area_peers.py [--quick] [--rounds N] [--reference-spp N] [--size WxH]

The scene: tests/data/area_peers/occluded.toml (32 x 24 pixels, or --size: a 1 x 1 quad light over a
plate, its penumbra on a floor, a homogeneous isotropic fog), exported by us to Mitsuba (`volpath`,
max_depth 2). The reference's cost grows with the pixels (benchmarks/area_sizes.py compares sizes
without it).
Mitsuba: `llvm_ad_rgb` where libLLVM >= 16 is found, else `scalar_rgb` (said in the output;
benchmarks/vs_mitsuba.py's `choose_variant`), at our pixel centres (its integrator's `sample()` on the
sensor's ray of each centre; with `scalar_rgb`, `mi.render` through its box-filtered film, which is
not the same estimand at the plate's edges), climbing an spp ladder. Ours: `quadrature` and `analytic`
at the tolerances 1e-1, 1e-2 and 1e-3 (`rtol`, `precision`: the cubature's order and the penumbrae's
strata follow them), `montecarlo` climbing a ladder of distance samples per ray.

Reference, sharing no sample with any measured render: Mitsuba at our pixel centres, --reference-spp
(default 2^20) in independent batches of BATCH spp (seeds none of the timed runs use), cached under
CACHE (about 9 minutes on 2 cores; a later run reuses it); its own mean relative error, from the
batches' spread, is printed, and every measured error includes it. Error: mean relative error over
pixels and channels where the reference exceeds 1e-3 of its max (vs_mitsuba.mre). Times: wall
and process CPU seconds (all threads) of one render, compilation excluded by a warm-up of every
setting; every setting runs once per round, the rounds interleaved, the median over rounds (the
machine may be shared: its load average is printed before and after). The time to the target error
is interpolated on a log-log line between the ladder's bracketing points, or extrapolated (~), or an
upper bound (<=) when the cheapest setting already beats it (vs_mitsuba.time_to_error).
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.vs_mitsuba import Mitsuba, choose_variant, machine, mre, time_to_error  # noqa: E402

SCENE = ROOT / "tests" / "data" / "area_peers" / "occluded.toml"
TARGET = 1e-2
TOLERANT = ("quadrature", "analytic")  # their settings are tolerances (rtol, precision): the ladder in 1 / tol
CACHE = Path(tempfile.gettempdir()) / "raytrace-area-peers"  # the Mitsuba reference, outside the repository
BATCH = 8192  # reference spp per independent batch


def reference(theirs, mi, xml: Path, spp: int):
    """(image (H, W, 3), its per-pixel standard error, spp, wall seconds of its batches): Mitsuba's
    estimate at our pixel centres, the mean of independent batches of BATCH spp (seeds 10^6 + k, none
    of the timed runs'), its standard error from their spread. Cached under CACHE, keyed by the
    exported scene and Mitsuba's version and variant; a larger `spp` adds batches to the cache."""
    import hashlib

    key = hashlib.sha256(xml.read_bytes() + f"{mi.__version__} {mi.variant()}".encode()).hexdigest()[:16]
    path = CACHE / f"mitsuba-{key}.npz"
    batches, seconds = [], 0.0
    if path.exists():
        with np.load(path) as f:
            batches, seconds = list(f["batches"]), float(f["seconds"])
    while len(batches) * BATCH < spp:
        img, wall, _ = timed(lambda: theirs.render(BATCH, 10**6 + len(batches)))
        batches.append(img)
        seconds += wall
        CACHE.mkdir(parents=True, exist_ok=True)
        np.savez(path.with_suffix(".tmp.npz"), batches=np.array(batches), seconds=seconds)
        os.replace(path.with_suffix(".tmp.npz"), path)
        print(f"  reference: {len(batches) * BATCH} spp, {seconds:.0f} s", flush=True)
    b = np.array(batches[:-(-spp // BATCH)])
    return b.mean(axis=0), b.std(axis=0, ddof=1) / np.sqrt(len(b)), len(b) * BATCH, seconds * len(b) / len(batches)


def reference_error(ref, se):
    """The reference's own expected mean relative error (vs_mitsuba.mre's mask): E|N(0, se)| / ref."""
    mask = ref > 1e-3 * ref.max()
    return float(np.mean(np.sqrt(2.0 / np.pi) * se[mask] / ref[mask]))


def mitsuba():
    """(mi, dr, why) with Mitsuba's variant set (vs_mitsuba.choose_variant, `why` its reason), or None
    (said) without mitsuba."""
    if importlib.util.find_spec("mitsuba") is None:
        print("mitsuba is not installed (pip install mitsuba): skipped")
        return None
    import drjit as dr
    import mitsuba as mi

    variant, why = choose_variant("auto")
    mi.set_variant(variant)
    return mi, dr, why


def exported(mi, dr, folder: Path, width=None, height=None):
    """(Mitsuba's scene, its XML file in `folder`): SCENE exported by us (at `width` x `height` where given)."""
    import raytrace
    from raytrace.io import mitsuba as mitsuba_io

    raw, source, _ = raytrace.api.scene_dict(str(SCENE))
    if width is not None:
        raw["camera"].update(width=width, height=height)
    xml = folder / "occluded.xml"
    mitsuba_io.export(raw, xml, source, False)
    return Mitsuba.from_file(mi, dr, xml), xml


def size(text: str) -> tuple[int, int]:
    """(width, height) of "WxH"."""
    w, h = text.lower().split("x")
    return int(w), int(h)


def timed(fn):
    """(result, wall seconds, process CPU seconds) of fn()."""
    w, c = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w, time.process_time() - c


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one round, shorter ladders")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--reference-spp", type=int, default=1 << 20, help="Mitsuba's spp for the reference")
    ap.add_argument("--size", type=size, default=None, help="WxH: the image's width and height (default the scene's)")
    args = ap.parse_args(argv)
    ready = mitsuba()
    if ready is None:
        return 0
    mi, dr, why = ready
    import raytrace

    rounds = 1 if args.quick else args.rounds
    load_before = os.getloadavg()
    info = machine()
    width, height = args.size or (None, None)
    with tempfile.TemporaryDirectory() as tmp:
        theirs, xml = exported(mi, dr, Path(tmp), width, height)
        width, height = theirs.W, theirs.H
        ref, ref_se, ref_spp, ref_s = reference(theirs, mi, xml, args.reference_spp)

        def ours(method, **params):
            return lambda: raytrace.render(str(SCENE), method, volumetric_shadows=True, width=width, height=height,
                                           **params).array

        settings = {}
        for tol in (1e-1, 1e-2, 1e-3):
            settings[("quadrature", tol)] = ours("quadrature", rtol=tol)
            settings[("analytic", tol)] = ours("analytic", precision=tol)
        for n in ((4, 16, 64) if args.quick else (4, 8, 16, 32, 64, 128)):
            settings[("montecarlo", n)] = (lambda n=n: ours("montecarlo", samples=n, seed=7 + n)())
        for spp in ((256, 1024, 4096) if args.quick else (256, 1024, 4096, 16384)):
            settings[("mitsuba", spp)] = (lambda spp=spp: theirs.render(spp, spp))
        for fn in settings.values():  # warm-up: numba and Dr.Jit kernels compiled
            fn()
        walls = {k: [] for k in settings}
        cpus = {k: [] for k in settings}
        errors = {k: [] for k in settings}
        for r in range(rounds):
            for key, fn in settings.items():
                if key[0] == "mitsuba":  # a new seed each round
                    fn = (lambda spp=key[1], r=r: theirs.render(spp, 1000 * r + spp + 1))
                img, wall, cpu = timed(fn)
                walls[key].append(wall)
                cpus[key].append(cpu)
                errors[key].append(mre(img, ref))
    load_after = os.getloadavg()

    print(f"# occluded quad light, {width} x {height} pixels, target mean relative error {TARGET:g}")
    print(f"machine: {info['cpu']}, {info['usable_cores']} usable cores, raytrace {info['raytrace_commit']}, "
          f"{info['date']}; load average before {load_before[0]:.2f} {load_before[1]:.2f}, after "
          f"{load_after[0]:.2f} {load_after[1]:.2f} (1 and 5 min)")
    print(f"Mitsuba {mi.__version__}: {why}; {'pixel centres' if theirs.vectorised else 'film (box filter)'}")
    print(f"reference: Mitsuba, {ref_spp} spp at our pixel centres ({ref_s:.0f} s wall, cached in {CACHE}), its "
          f"own mean relative error {reference_error(ref, ref_se):.1e}; {rounds} round(s), medians")
    print(f"{'method':<12} {'setting':>8} {'wall s':>8} {'cpu s':>8} {'error':>9}")
    ladders = {}
    for key in settings:
        w, c, e = (statistics.median(x[key]) for x in (walls, cpus, errors))
        print(f"{key[0]:<12} {key[1]:>8g} {w:8.3f} {c:8.3f} {e:9.2e}")
        ladders.setdefault(key[0], []).append((1.0 / key[1] if key[0] in TOLERANT else key[1], w, c, e))
    print(f"time to {TARGET:g}:")
    reached = {}
    for name, ladder in ladders.items():
        wall, how = time_to_error([(n, w, e) for n, w, _, e in ladder], TARGET)
        cpu, _ = time_to_error([(n, c, e) for n, _, c, e in ladder], TARGET)
        reached[name] = (wall, cpu, how)
        print(f"  {name:<12} " + ("not reached" if wall is None else f"{how:>6} {wall:8.3f} s wall, {cpu:8.3f} s cpu"))
    mits = reached["mitsuba"]
    for name in ("quadrature", "analytic", "montecarlo"):
        w, c, _ = reached[name]
        if w is not None and mits[0] is not None:
            print(f"  Mitsuba / {name}: {mits[0] / w:.1f}x wall, {mits[1] / c:.1f}x cpu")
    return 0


if __name__ == "__main__":
    sys.exit(main())
