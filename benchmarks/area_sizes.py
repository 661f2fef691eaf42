"""How the occluded area light's speed against Mitsuba 3 depends on the image size (docs/area_lights.md,
"Time to 1e-2 against Mitsuba 3"): benchmarks/area_peers.py's scene and settings at several sizes,
without its 2^20-spp reference (which grows with the pixels: about 9 minutes at 32 x 24 on 2 cores).

    pip install mitsuba                  # >= 3.5; exits 0 with a skip message without it
    python benchmarks/area_sizes.py [--sizes 32x24 64x48 128x96] [--rounds 1]

Per size (the scene's camera at that width and height, Mitsuba exported from it, `llvm_ad_rgb` at our
pixel centres where libLLVM >= 16 is found, as area_peers.py):
- Mitsuba at 256, 1024 and 4096 spp, two independent runs per round (seeds none of the others use);
  its mean relative error at each spp from the pair alone: mean |X1 - X2| / R / sqrt(2) (for
  independent unbiased estimates of Gaussian error E|X1 - X2| = sqrt(2) E|X - truth|), over
  area_peers.py's mask (R above 1e-3 of its max); its time to 1e-2 by vs_mitsuba.time_to_error on
  that ladder (extrapolated, `~`, past 4096 spp as area_peers.py extrapolates past 16384);
- ours: `analytic` (precision 1e-1) and `quadrature` (rtol 1e-1), area_peers.py's cheapest settings,
  their error against R; the ratio, Mitsuba's time to 1e-2 over ours, where ours is within 1e-2 (an
  upper bound of our time to it, as area_peers.py's `<=`), else `-`.
R, the denominator and ours' reference: `analytic` at precision 1e-3 with another seed (its sampled
penumbrae independent of the timed renders'; at 32 x 24 within 1.7e-3 of area_peers.py's Mitsuba
reference, that reference's own 1.4e-3 included), so ours' errors include R's. Times: process CPU
seconds of one render (all threads), compilation excluded by a warm-up of every setting, the median
over rounds; the machine's load average is printed before and after.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.area_peers import SCENE, TARGET, exported, mitsuba, size, timed  # noqa: E402
from benchmarks.vs_mitsuba import machine, mre, time_to_error  # noqa: E402

LADDER = (256, 1024, 4096)  # Mitsuba's spp
OURS = (("analytic", {"precision": 1e-1}), ("quadrature", {"rtol": 1e-1}))
REFERENCE = ("analytic", {"precision": 1e-3, "seed": 1})


def pair_error(a, b, ref) -> float:
    """The mean relative error of either of two independent unbiased estimates a, b from their
    difference: mean |a - b| / ref / sqrt(2) over vs_mitsuba.mre's mask."""
    mask = ref > 1e-3 * ref.max()
    return float(np.mean(np.abs(a[mask] - b[mask]) / ref[mask])) / np.sqrt(2.0)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=size, nargs="+", default=[(32, 24), (64, 48), (128, 96)], help="WxH ...")
    ap.add_argument("--rounds", type=int, default=1)
    args = ap.parse_args(argv)
    ready = mitsuba()
    if ready is None:
        return 0
    mi, dr, why = ready
    import raytrace

    load_before = os.getloadavg()
    info = machine()
    rows = []
    for w, h in args.sizes:
        with tempfile.TemporaryDirectory() as tmp:
            theirs, _ = exported(mi, dr, Path(tmp), w, h)

        def ours(method, params, w=w, h=h):
            return raytrace.render(str(SCENE), method, volumetric_shadows=True, width=w, height=h, **params).array

        ref = ours(*REFERENCE)
        for spp in LADDER:  # warm-up: Dr.Jit's and numba's kernels compiled
            theirs.render(spp, spp)
        for method, params in OURS:
            ours(method, params)
        cpu = {k: [] for k in LADDER + tuple(m for m, _ in OURS)}
        err = {k: [] for k in cpu}
        for r in range(args.rounds):
            for spp in LADDER:
                (a, _, ca), (b, _, cb) = (timed(lambda k=k: theirs.render(spp, 10**5 * (r + 1) + 2 * spp + k))
                                          for k in (0, 1))
                cpu[spp] += [ca, cb]
                err[spp].append(pair_error(a, b, ref))
            for method, params in OURS:
                img, _, c = timed(lambda: ours(method, params))
                cpu[method].append(c)
                err[method].append(mre(img, ref))
        med = {k: (statistics.median(cpu[k]), statistics.median(err[k])) for k in cpu}
        mits, how = time_to_error([(n, *med[n]) for n in LADDER], TARGET)
        rows.append((w, h, med, mits, how))
        print(f"{w} x {h}: " + ", ".join(f"{k}: {c:.3f} s cpu, error {e:.2e}" for k, (c, e) in med.items()) +
              f"; Mitsuba to {TARGET:g}: {how} {mits:.2f} s cpu", flush=True)
    load_after = os.getloadavg()

    print(f"# occluded quad light at several sizes, target mean relative error {TARGET:g}")
    print(f"machine: {info['cpu']}, {info['usable_cores']} usable cores, raytrace {info['raytrace_commit']}, "
          f"{info['date']}; load average before {load_before[0]:.2f} {load_before[1]:.2f}, after "
          f"{load_after[0]:.2f} {load_after[1]:.2f} (1 and 5 min)")
    print(f"Mitsuba {mi.__version__}: {why}; {'pixel centres' if theirs.vectorised else 'film (box filter)'}; "
          f"{args.rounds} round(s), medians of CPU seconds")
    print(f"{'size':>8} {'Mitsuba s':>10} " + " ".join(f"{m + ' s':>13} {'error':>8} {'ratio':>6}" for m, _ in OURS))
    for w, h, med, mits, how in rows:
        cells = []
        for m, _ in OURS:
            c, e = med[m]
            cells.append(f"{c:13.3f} {e:8.2e} " + (f"{mits / c:6.1f}" if e <= TARGET else f"{'-':>6}"))
        print(f"{f'{w}x{h}':>8} {how:>2}{mits:8.2f} " + " ".join(cells))
    return 0


if __name__ == "__main__":
    sys.exit(main())
