"""`render.py assets` and `raytrace.assets()`: the paper's meshes downloaded from their public
archives (catalogue.py), checked against pinned SHA-256 sums, converted into the files the bundled
scenes load (convert.py) and put in the assets folder (docs/assets.md).

Everything happens in a staging folder inside the assets folder and is moved into place only once
the archive's sum matched and the conversion succeeded: a refused archive, a failed download or a
failed conversion leaves nothing behind. Each archive is kept in `<folder>/archives/`, where one
downloaded by other means can also be put.
"""
from __future__ import annotations

import os
import shutil
import tempfile
import zipfile
from collections.abc import Callable, Iterable
from pathlib import Path

from ..errors import UserError, counted
from .assets import asset_folders
from .catalogue import ARCHIVES, NOT_DOWNLOADED, Archive
from .convert import pbrt_to_obj, split_obj

MIRROR_ENV = "RAYTRACE_ASSETS_MIRROR"  # a server holding the archives under their file names
USER_AGENT = "raytrace-media (render.py assets)"
TIMEOUT = 60  # seconds without an answer before a download counts as failed


def assets(names: Iterable[str] | None = None, *, folder: str | Path | None = None, mirror: str | None = None,
           trust_unpinned: bool = False, archives: Iterable[Archive] | None = None, progress: bool = True,
           note: Callable[[str], None] = print) -> list[Path]:
    """Download, check and convert the paper's meshes (all, or the archives `names`) into `folder`
    (default: the first RAYTRACE_ASSETS folder, else the user's data folder); returns the files the
    bundled scenes load. An archive already converted there is left as it is.

    `mirror` (or $RAYTRACE_ASSETS_MIRROR): a base URL to fetch the archives from instead, under
    their file names. An archive without a pinned sum is refused unless `trust_unpinned`; its sum
    is then printed. `archives` replaces the catalogue's entries of the same names (another URL or
    sum: a mirror, a test); `note` receives the progress lines."""
    catalogue = {**ARCHIVES, **{a.name: a for a in archives or ()}}
    chosen = _select(names, catalogue)
    target = _target(folder)
    mirror = mirror or os.environ.get(MIRROR_ENV) or None
    todo = [a for a in chosen if not all((target / f).is_file() for f in a.files)]
    for a in chosen:
        if a not in todo:
            note(f"{a.name}: already in {target} (delete {target / a.folder} to fetch it again)")
    unpinned = [a.name for a in todo if a.sha256 is None]
    if unpinned and not trust_unpinned:
        pinned = [a.name for a in todo if a.sha256 is not None]
        raise UserError(f"{', '.join(unpinned)}: no pinned SHA-256 sum for the archive (docs/assets.md says why); "
                        "`render.py assets --trust-unpinned` (trust_unpinned=True) downloads it unchecked and prints "
                        "its sum" + (f", `render.py assets {' '.join(pinned)}` only the pinned ones" if pinned else ""))
    for a in todo:
        _install(a, target, mirror, progress, note)
        note(f"{a.name}: {a.credit}. Licence: {a.licence}")
    return [target / f for a in chosen for f in a.files]


def describe(folder: str | Path | None = None) -> list[str]:
    """One paragraph per archive: files, source, sum, credit, licence and whether it is installed."""
    target = _target(folder)
    lines = []
    for a in ARCHIVES.values():
        state = "installed" if all((target / f).is_file() for f in a.files) else "not installed"
        lines += [f"{a.name} ({state} in {target}): {', '.join(a.files)}",
                  f"    from {a.url}",
                  f"    SHA-256 {a.sha256 or 'not pinned (needs --trust-unpinned)'}",
                  f"    {a.credit}", f"    Licence: {a.licence}"]
    lines += [f"{name}: not downloaded: {why}" for name, why in NOT_DOWNLOADED.items()]
    return lines


def _target(folder) -> Path:
    return Path(folder).expanduser() if folder is not None else asset_folders()[0]


def _select(names, catalogue: dict) -> list[Archive]:
    names = list(names or catalogue)
    unknown = [n for n in names if n not in catalogue or n not in INSTALLERS]
    if unknown:
        raise UserError(f"render.py assets: unknown archive {', '.join(map(repr, unknown))}; "
                        f"choose from {', '.join(catalogue)}")
    return [catalogue[n] for n in dict.fromkeys(names)]


def _new_folders(path: Path) -> list[Path]:
    """The folders `path.mkdir(parents=True)` would create, outermost first."""
    missing = []
    while not path.exists():
        missing.append(path)
        path = path.parent
    return missing[::-1]


def _install(a: Archive, target: Path, mirror: str | None, progress: bool, note) -> None:
    created = _new_folders(target / "archives")
    try:
        (target / "archives").mkdir(parents=True, exist_ok=True)
        stage = Path(tempfile.mkdtemp(prefix=f".{a.name}-", dir=target))
    except OSError as exc:
        raise UserError(f"{target}: cannot write there ({exc.strerror or exc}); choose another folder with --folder "
                        "(or RAYTRACE_ASSETS)") from None
    try:
        archive = _archive(a, target, stage, mirror, progress, note)
        out = stage / "out"
        (out / a.folder).mkdir(parents=True)
        INSTALLERS[a.name](archive, out / a.folder, a)
        for f in sorted(p for p in out.rglob("*") if p.is_file()):
            dest = target / f.relative_to(out)
            dest.parent.mkdir(parents=True, exist_ok=True)
            os.replace(f, dest)
        if archive.parent == stage:
            os.replace(archive, target / "archives" / a.filename)
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        for d in reversed(created):
            if d.is_dir() and not any(d.iterdir()):
                d.rmdir()
        raise
    shutil.rmtree(stage)


def _archive(a: Archive, target: Path, stage: Path, mirror: str | None, progress: bool, note) -> Path:
    """The archive's file, from `<target>/archives/` or downloaded into `stage`, its sum checked."""
    import pooch

    placed = target / "archives" / a.filename
    if placed.is_file():
        path, source = placed, str(placed)
    else:
        source = f"{mirror.rstrip('/')}/{a.filename}" if mirror else a.url
        path = stage / a.filename
        note(f"{a.name}: downloading {source}")
        try:
            pooch.HTTPDownloader(progressbar=progress, headers={"User-Agent": USER_AGENT}, timeout=TIMEOUT)(
                source, str(path), None)
        except OSError as exc:  # requests' errors are OSErrors too
            response = getattr(exc, "response", None)
            reason = f"HTTP {response.status_code}" if response is not None else type(exc).__name__
            raise UserError(f"{a.name}: cannot download {source} ({reason}); offline, get that file another way and "
                            f"put it at {placed}, then run `render.py assets {a.name}` again") from None
    got = pooch.file_hash(str(path), alg="sha256")
    if a.sha256 is None:
        note(f"{a.name}: {a.filename} has no pinned sum; its SHA-256 is {got} (docs/assets.md lists the sum "
             "others recorded)")
    elif got != a.sha256:
        fix = (f"delete it and run `render.py assets {a.name}` again" if path == placed else
               "nothing was kept; the archive changed upstream or was damaged on the way (docs/assets.md)")
        raise UserError(f"{source}: SHA-256 {got} is not the pinned {a.sha256}; refused: {fix}")
    return path


def _credits(a: Archive) -> str:
    return f"{a.credit}.\nLicence: {a.licence}\nSource: {a.url}\nConverted by `render.py assets` (docs/assets.md).\n"


def _unzip(archive: Path, dest: Path) -> None:
    """Extract a zip archive into `dest`, without the one top folder it may wrap everything in
    (zipfile drops absolute paths and `..` from member names)."""
    unpacked = dest.parent / f"{dest.name}.unzipped"
    try:
        with zipfile.ZipFile(archive) as z:
            z.extractall(unpacked)
    except zipfile.BadZipFile as exc:
        raise UserError(f"{archive}: not a zip archive ({exc}); delete it and run `render.py assets` again") from None
    entries = [e for e in unpacked.iterdir() if e.name != "__MACOSX"]  # a macOS zip tool's resource forks
    root = entries[0] if len(entries) == 1 and entries[0].is_dir() else unpacked
    for entry in root.iterdir():
        if entry.name != "__MACOSX":
            os.replace(entry, dest / entry.name)
    shutil.rmtree(unpacked)


def _install_sibenik(archive: Path, dest: Path, a: Archive) -> None:
    """McGuire's zip; its clear window panes (material staklo) go to sibenik_staklo.obj, as the
    bundled scene loads them as a shape of their own."""
    _unzip(archive, dest)
    obj = dest / "sibenik.obj"
    if not obj.is_file():
        raise UserError(f"{archive}: holds no sibenik.obj; this is not the archive docs/assets.md describes")
    header = f"{a.credit}\nfrom {a.url}, split by `render.py assets`"
    rest, panes = split_obj(obj, "staklo", obj, dest / "sibenik_staklo.obj", header)
    (dest / "CREDITS.txt").write_text(_credits(a) + f"sibenik.obj: {counted(rest, 'face')}; sibenik_staklo.obj: "
                                                    f"{counted(panes, 'face')} of material staklo.\n", encoding="utf-8")


def _install_conference(archive: Path, dest: Path, a: Archive) -> None:
    """Jan Walter's pbrt-v2 export of the LBL model, converted to OBJ + MTL."""
    header = (f"{a.credit}\nconverted from {a.url} by `render.py assets`\n"
              "units: meters, Z up. cylinders/disks/spheres tessellated with 16 segments.")
    pbrt_to_obj(archive, dest / "conference_lbl.obj", dest / "conference_lbl.mtl", header)
    (dest / "CREDITS.txt").write_text(_credits(a), encoding="utf-8")


INSTALLERS = {"sibenik": _install_sibenik, "conference": _install_conference}
