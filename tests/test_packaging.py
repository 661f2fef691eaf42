"""A plain (non-editable) install carries every package and the bundled scenes (issue 8, defect 6:
table1 found its scenes relative to the source tree)."""
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

from raytrace.scene.assets import bundled_scenes

ROOT = Path(__file__).resolve().parents[1]


def test_the_package_list_names_every_package_folder():
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "raytrace").rglob("__init__.py")
             if "__pycache__" not in p.parts}
    assert listed == found | {"raytrace.scenes"}


def test_the_paper_scenes_are_bundled():
    from raytrace.experiments import table1

    names = bundled_scenes()
    assert {"box_room", "sibenik", "bridge", "conference"} <= set(names)
    assert all(table1.SCENES[n].is_file() for n in ("sibenik", "bridge", "conference"))


def test_the_wheel_holds_the_scenes_and_every_module(tmp_path):
    src = tmp_path / "src"  # a copy, so that the build leaves nothing in the checkout
    ignore = shutil.ignore_patterns("__pycache__")
    for name in ("raytrace", "scenes"):
        shutil.copytree(ROOT / name, src / name, ignore=ignore)
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, src / name)
    subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(tmp_path), str(src)],
                   check=True, capture_output=True)
    (wheel,) = tmp_path.glob("raytrace_media-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    for scene in ("box_room", "sibenik", "bridge", "conference"):
        assert f"raytrace/scenes/{scene}.toml" in names
    for module in (ROOT / "raytrace").rglob("*.py"):
        assert module.relative_to(ROOT).as_posix() in names
