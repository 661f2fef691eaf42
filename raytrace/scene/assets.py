"""Where mesh files are looked up: beside the scene file, then the RAYTRACE_ASSETS folders."""
import os
from pathlib import Path

from ..errors import UserError

ENV = "RAYTRACE_ASSETS"


def bundled_scenes() -> dict[str, Path]:
    """The scene files shipped with the package (the repository's scenes/, package `raytrace.scenes`):
    name -> path, usable as `render.py render NAME`."""
    from importlib.resources import files

    folder = Path(str(files("raytrace.scenes")))
    return {p.stem: p for p in sorted(folder.glob("*.toml"))}


def search_folders(scene_path: Path | None) -> list[Path]:
    folders = [scene_path.parent] if scene_path is not None else []
    folders += [Path(p) for p in os.environ.get(ENV, "").split(os.pathsep) if p]
    return folders


def find_asset(name: str, scene_path: Path | None, key: str) -> Path:
    """Resolve a mesh file name, or raise a UserError listing every folder searched."""
    p = Path(name).expanduser()
    if p.is_absolute():
        if p.is_file():
            return p
        searched = [str(p.parent)]
    else:
        folders = search_folders(scene_path)
        for folder in folders:
            if (folder / p).is_file():
                return folder / p
        searched = [str(f) for f in folders] or ["(no folders)"]
    source = str(scene_path) if scene_path else "scene"
    raise UserError(
        f"{source}: {key}: mesh file {name!r} not found in {', '.join(searched)}; put it there or add its "
        f"folder to {ENV} (an {os.pathsep!r}-separated list); the paper's meshes come from ../shared/scenes "
        f"(see its SOURCES.md)")
