"""Regenerate the tiny reference images of tests/test_regression_scenes.py.

    RAYTRACE_ASSETS=../shared/scenes python tests/make_refs.py

Each reference is the scene file of scenes/ at a small resolution, 1 spp, rendered with the
`quadrature` reference method (rtol 1e-12) and stored as float32 EXR under tests/refs/, with the
generator's parameters and the scene file's SHA-256 in the header (the test refuses a reference
whose scene file has changed since).
"""
import hashlib
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from raytrace.output.film import write_exr
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import load_scene  # noqa: E402

SIZES = {"sibenik": (48, 24), "bridge": (40, 40), "conference": (40, 40)}
RTOL = 1e-12


def overrides(name):
    w, h = SIZES[name]
    return [f"camera.width={w}", f"camera.height={h}", "camera.spp=1"]


def scene_hash(name):
    return hashlib.sha256((ROOT / "scenes" / f"{name}.toml").read_bytes()).hexdigest()


def main():
    for name in SIZES:
        scene = load_scene(ROOT / "scenes" / f"{name}.toml", overrides(name))
        res = render(prepare(scene), "quadrature", {"rtol": RTOL})
        out = ROOT / "tests" / "refs" / f"{name}.exr"
        write_exr(out, res.image, {"scene": name, "method": "quadrature", "rtol": RTOL, "spp": 1,
                                   "size": "x".join(map(str, SIZES[name])), "scene_sha256": scene_hash(name),
                                   "generator": "tests/make_refs.py"})
        print(f"wrote {out}")


if __name__ == "__main__":
    main()
