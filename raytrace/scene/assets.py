"""Where mesh files are looked up: beside the scene file, then the RAYTRACE_ASSETS folders (or, when
it is unset, the user's data folder, where `render.py assets` puts the paper's meshes)."""
import os
from pathlib import Path

from ..errors import UserError
from .catalogue import ARCHIVES, NOT_DOWNLOADED

ENV = "RAYTRACE_ASSETS"
APP = "raytrace-media"


def bundled_scenes() -> dict[str, Path]:
    """The scene files shipped with the package (the repository's scenes/, package `raytrace.scenes`):
    name -> path, usable as `render.py render NAME`."""
    from importlib.resources import files

    folder = Path(str(files("raytrace.scenes")))
    return {p.stem: p for p in sorted(folder.glob("*.toml"))}


def data_folder() -> Path:
    """The user's data folder for this package (platformdirs: ~/.local/share/raytrace-media on Linux,
    ~/Library/Application Support/raytrace-media on macOS, %LOCALAPPDATA%\\raytrace-media on Windows)."""
    import platformdirs

    return platformdirs.user_data_path(APP, appauthor=False)


def asset_folders() -> list[Path]:
    """The RAYTRACE_ASSETS folders (an os.pathsep-separated list), or the user's data folder when it is
    unset or empty; `render.py assets` downloads into the first."""
    folders = [Path(p) for p in os.environ.get(ENV, "").split(os.pathsep) if p]
    return folders or [data_folder()]


def search_folders(scene_path: Path | None) -> list[Path]:
    return ([scene_path.parent] if scene_path is not None else []) + asset_folders()


def _paper_mesh_fix(name: str) -> str | None:
    """What to do about a missing mesh of the paper's scenes, or None for any other file."""
    key = Path(name).as_posix()
    for archive in ARCHIVES.values():
        if key in archive.files:
            return (f"it is one of the paper's meshes: `render.py assets {archive.name}` downloads it into "
                    f"{asset_folders()[0]}, the first {ENV} folder or else the user's data folder (docs/assets.md)")
    if key in NOT_DOWNLOADED:
        return f"{NOT_DOWNLOADED[key]}; put a mesh of your own by that name in one of those folders or in {ENV}"
    return None


def find_asset(name: str, scene_path: Path | None, key: str, what: str = "mesh file") -> Path:
    """Resolve a mesh file name (or another `what`), or raise a UserError listing every folder searched."""
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
        searched = [str(f) for f in folders]
    source = str(scene_path) if scene_path else "scene"
    fix = _paper_mesh_fix(name) or (f"put it in one of those folders or add its folder to {ENV} "
                                    f"(an {os.pathsep!r}-separated list)")
    raise UserError(f"{source}: {key}: {what} {name!r} not found in {', '.join(searched)}; {fix}")
