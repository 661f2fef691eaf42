"""Images of every bundled scene rendered with kernels loaded from the cache, to compare two checkouts bit for bit.

    RAYTRACE_ASSETS=../shared/scenes python benchmarks/warm_images.py DIR [--tree TREE] [--methods analytic,quadrature]
    python benchmarks/warm_images.py --compare DIR_A DIR_B

Renders every bundled scene (and the built-in default scene) at `--width` pixels with each of
`--methods` through the command line, in two processes sharing one empty kernel cache: the first
compiles the kernels (and renders), the second renders again with every kernel loaded from that cache
and writes its images to DIR. Kernels compiled in a process can differ in their last bits from
those loaded from the cache (which compilation a helper called from several kernels keeps), so
two checkouts are compared like with like: both warm. `--compare` prints, per image, whether the
pixels are equal bit for bit (NaNs in the same places), and exits 1 when any differs or is missing.
"""
import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from compile_time import DEFAULT, scene_names  # noqa: E402


def render_all(out: Path, width: int, methods: list[str], names: list[str]) -> None:
    """In this process: every scene with every method into `out` (a failure is written as NAME.err)."""
    from raytrace.cli import main

    for name in names:
        for method in methods:
            stem = f"{name.strip('()')}-{method}"
            args = ([] if name == DEFAULT else [name]) + ["--width", str(width), "--threads", "1", "--quiet",
                                                         "--method", method, "--out", str(out / f"{stem}.exr")]
            try:
                status = main(args)
            except SystemExit as e:
                status = e.code
            if status != 0:
                (out / f"{stem}.err").write_text(str(status))


def compare(a: Path, b: Path) -> int:
    import numpy as np

    from raytrace.output.film import read_exr

    bad = 0
    for pa in sorted(a.glob("*.exr")):
        pb = b / pa.name
        if not pb.exists():
            print(f"{pa.stem}: missing in {b}")
            bad += 1
            continue
        ia, ib = read_exr(pa)[0], read_exr(pb)[0]
        same = ia.shape == ib.shape and np.array_equal(ia.view(np.uint8), ib.view(np.uint8))
        diff = "" if same else f" (max |difference| {np.nanmax(np.abs(ia - ib)):.3g} of {np.nanmax(np.abs(ia)):.3g})"
        print(f"{pa.stem}: {'identical' if same else 'DIFFERENT'}{diff}")
        bad += not same
    for err in sorted(set(p.name for p in a.glob("*.err")) ^ set(p.name for p in b.glob("*.err"))):
        print(f"{err}: failed in one checkout only")
        bad += 1
    return 1 if bad else 0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", type=Path, nargs="?")
    ap.add_argument("--tree", type=Path, default=Path(__file__).resolve().parents[1])
    ap.add_argument("--methods", default="analytic,quadrature")
    ap.add_argument("--scenes", help="comma-separated scene names (default: every bundled scene and the default)")
    ap.add_argument("--width", type=int, default=24)
    ap.add_argument("--compare", nargs=2, type=Path, metavar=("DIR_A", "DIR_B"))
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.compare:
        sys.exit(compare(*args.compare))
    names = args.scenes.split(",") if args.scenes else scene_names(bool(os.environ.get("RAYTRACE_ASSETS")))
    methods = args.methods.split(",")
    if args.worker:
        return render_all(args.out, args.width, methods, names)
    args.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="warm_images_") as tmp:
        env = dict(os.environ, RAYTRACE_CACHE=str(Path(tmp) / "cache"), PYTHONPATH=str(args.tree))
        cold = Path(tmp) / "cold"
        cold.mkdir()
        for out in (cold, args.out):  # compile, then render warm
            subprocess.run([sys.executable, __file__, str(out), "--worker", "--width", str(args.width), "--methods",
                            args.methods, "--scenes", ",".join(names)], env=env, check=True)


if __name__ == "__main__":
    main()
