"""Image files: linear float32 RGB EXR (with metadata in the header) and PNG previews (through
output/view.py's PBR Neutral or ACES 2.0 view, or a plain sRGB encode).

Files are written to a temporary name beside the target and renamed, so a failed or interrupted
write never leaves a partial image behind. Several files written together (an EXR and its PNG) are
renamed under an exclusive lock, so that concurrent writers of the same files leave one writer's set.
"""
from __future__ import annotations

import contextlib
import fcntl
import os
import tempfile
import threading
from pathlib import Path

import numpy as np

from ..errors import UserError
from . import view as views

_UMASK = threading.Lock()


def _umask() -> int:
    """The process's umask (read by setting it, so under a lock: concurrent writers in threads)."""
    with _UMASK:
        umask = os.umask(0)
        os.umask(umask)
    return umask


@contextlib.contextmanager
def _locked(path: Path):
    """An exclusive flock on `.<name>.lock` beside `path`, held for the block and then removed. A
    writer that locked a lock file another one removed meanwhile locks the new one instead, so
    exactly one writer holds the lock of a path at any time."""
    lock = path.with_name(f".{path.name}.lock")
    while True:
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
        except OSError as exc:
            raise UserError(f"{path}: cannot write there ({exc.strerror}); choose a writable path") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
            try:
                current = os.path.samestat(os.fstat(fd), os.stat(lock))  # not removed meanwhile
            except FileNotFoundError:
                current = False
        except BaseException:
            os.close(fd)
            raise
        if current:
            break
        os.close(fd)
    try:
        yield
    finally:
        os.unlink(lock)  # while still held: a waiter then sees it removed and locks a new one
        os.close(fd)


def write_together(jobs):
    """Write every (path, write) of `jobs`, all or nothing: `write(tmp)` fills a temporary file beside
    its path, and the temporaries are renamed onto their paths only once all are written, holding the
    lock of the first path (`_locked`): concurrent writers of the same paths leave one writer's files.
    On any failure (or Ctrl-C) no temporary stays and no path is touched. UserError names the path."""
    jobs = [(Path(path), write) for path, write in jobs]
    temporaries = []
    try:
        for path, write in jobs:
            folder = path.parent if str(path.parent) else Path(".")
            if not folder.is_dir():
                raise UserError(f"{path}: folder {folder} does not exist; create it or choose another --out")
            try:
                fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=folder)
            except OSError as exc:
                raise UserError(f"{path}: cannot write there ({exc.strerror}); choose a writable --out path") from None
            os.close(fd)
            temporaries.append(tmp)
            try:
                write(tmp)
            except OSError as exc:
                raise UserError(f"{path}: cannot write ({exc.strerror}); choose a writable path") from None
        umask = _umask()
        with _locked(jobs[0][0]) if jobs else contextlib.nullcontext():
            for (path, _), tmp in zip(jobs, temporaries):
                try:
                    os.chmod(tmp, 0o666 & ~umask)
                    os.replace(tmp, path)
                except OSError as exc:
                    raise UserError(f"{path}: cannot write ({exc.strerror}); choose a writable path") from None
    finally:
        for tmp in temporaries:
            if os.path.exists(tmp):
                os.unlink(tmp)


def _atomic_write(path: Path, write):
    write_together([(path, write)])


def check_writable(path: Path, flag: str = "--out"):
    """Fail early (before a long render) when `path` (given as `flag`) cannot be written: its folder,
    or where that is missing its nearest existing ancestor (the missing folders are created only
    when writing: `folders_for`), must be a folder that takes a new file (tried: permission bits do
    not tell for root or for /proc)."""
    path = Path(path)
    folder = path.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise UserError(f"{flag} {path}: {folder} is a file, not a folder; choose another output path")
    if not os.access(folder, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)) or path.is_dir():
        raise UserError(f"{flag} {path}: not writable; choose a writable output path")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=folder)
    except OSError as exc:
        raise UserError(f"{flag} {path}: not writable ({exc.strerror}); choose a writable output path") from None
    os.close(fd)
    os.unlink(tmp)


@contextlib.contextmanager
def folders_for(paths):
    """Create the missing folders of `paths` (checked by `check_writable`); if the block fails (or
    is interrupted), remove again the ones created here that are still empty."""
    created = []
    try:
        for path in paths:
            for folder in reversed([f for f in Path(path).parents if not f.exists()]):
                try:
                    folder.mkdir()
                except OSError as exc:
                    raise UserError(f"{path}: cannot create the folder {folder} ({exc.strerror}); choose a "
                                    "writable output path") from None
                created.append(folder)
        yield
    except BaseException:
        for folder in reversed(created):
            with contextlib.suppress(OSError):
                folder.rmdir()
        raise


def write_exr(path, image: np.ndarray, header: dict | None = None, extra: dict | None = None):
    """Write (H, W, 3) linear RGB as float32 EXR; `header` values become string attributes,
    `extra` maps channel names (e.g. "variance.R") to (H, W) arrays."""
    _atomic_write(Path(path), exr_writer(image, header, extra))


def exr_writer(image: np.ndarray, header: dict | None = None, extra: dict | None = None):
    """`write(tmp)` of `write_exr`'s file, for `write_together`."""
    import OpenEXR

    hdr = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    for k, v in (header or {}).items():
        hdr[str(k)] = str(v)
    img = np.ascontiguousarray(image, dtype=np.float32)
    channels = {"R": img[..., 0].copy(), "G": img[..., 1].copy(), "B": img[..., 2].copy()}
    for k, v in (extra or {}).items():
        channels[k] = np.ascontiguousarray(v, dtype=np.float32)

    def write(tmp):
        with OpenEXR.File(hdr, channels) as f:
            f.write(tmp)

    return write


def read_exr(path) -> tuple[np.ndarray, dict]:
    """(H, W, 3) float64 RGB and the header's string attributes."""
    import OpenEXR

    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: no such image; check the path")
    try:
        with OpenEXR.File(str(path), separate_channels=True) as f:
            ch = f.channels()
            img = np.stack([np.asarray(ch[c].pixels, dtype=np.float64) for c in "RGB"], axis=-1)
            header = {k: v for k, v in f.header().items() if isinstance(v, str)}
    except Exception as exc:  # OpenEXR raises plain Exceptions for unreadable files
        raise UserError(f"{path}: not a readable RGB EXR image ({exc}); give a file written by render") from None
    return img, header


def read_exr_channels(path, prefix: str) -> np.ndarray | None:
    """(H, W, 3) float64 of the channels `prefix`.R, .G, .B of an EXR `read_exr` has read (e.g.
    "error_bound"), or None if it has none."""
    import OpenEXR

    with OpenEXR.File(str(path), separate_channels=True) as f:
        ch = f.channels()
        if not all(f"{prefix}.{c}" in ch for c in "RGB"):
            return None
        return np.stack([np.asarray(ch[f"{prefix}.{c}"].pixels, dtype=np.float64) for c in "RGB"], axis=-1)


def read_exr_layer(path, name: str) -> np.ndarray:
    """(H, W, 3) float64 of the output layer `name` of an EXR (rendering/aov.py's channels: name.R/G/B, name.X/Y/Z,
    or name.Z repeated in all three); UserError naming the layers it has when it lacks that one."""
    import OpenEXR

    with OpenEXR.File(str(path), separate_channels=True) as f:
        ch = f.channels()
        for suffixes in ("RGB", "XYZ", "Z"):
            if all(f"{name}.{c}" in ch for c in suffixes):
                planes = [np.asarray(ch[f"{name}.{c}"].pixels, dtype=np.float64) for c in suffixes]
                return np.stack(planes * (3 // len(planes)), axis=-1)
        have = sorted({k.split(".")[0] for k in ch if "." in k} - {"error_bound", "variance"})
    raise UserError(f"{path}: no layer {name!r}; it has {', '.join(have) or 'none'} (render with --aov to write them)")


TONEMAP_VALUES = 1 << 20  # float64 values per band of `srgb_encode` (a few 8 MB temporaries)
VIEWS = ("neutral", "aces", "standard")  # preview views: output/view.py's PBR Neutral and ACES 2.0, or a plain sRGB encode


def check_view(name, what: str = "view") -> str:
    """`name` if it is one of VIEWS; UserError naming `what` otherwise."""
    if name not in VIEWS:
        raise UserError(f"{what}: unknown view {name!r}; choose one of: {', '.join(VIEWS)} (neutral keeps "
                        "lamps' hues, aces greys them, standard is the exact sRGB encode that clips at 1)")
    return name


def tonemap(image: np.ndarray, exposure: float | None = None, view: str = "neutral") -> np.ndarray:
    """8-bit sRGB preview of linear radiance through `view` (VIEWS), `exposure` in stops (None:
    automatic): "neutral" and "aces" are `view.to_display`; "standard" is `srgb_encode`."""
    check_view(view)
    exposure = views.check_exposure(exposure)
    return srgb_encode(image, exposure) if view == "standard" else views.to_display(image, exposure, view)


def srgb_encode(image: np.ndarray, exposure: float | None = None) -> np.ndarray:
    """8-bit sRGB (IEC 61966-2-1) of radiance x 2^exposure clipped to [0, 1]; exposure None scales
    the 99.5th percentile of luminance to 1."""
    lum = image @ np.array([0.2126, 0.7152, 0.0722])
    if exposure is None:
        ref = np.percentile(lum, 99.5) if lum.size else 0.0
        scale = 1.0 / ref if ref > 0 and np.isfinite(ref) else 1.0
    else:
        scale = 2.0 ** exposure
    out = np.empty(image.shape, np.uint8)
    rows = max(1, TONEMAP_VALUES // max(1, image[0].size)) if image.ndim == 3 and len(image) else 1
    for r in range(0, len(image), rows):  # in bands: the temporaries stay small
        out[r:r + rows] = views.srgb8(np.nan_to_num(image[r:r + rows] * scale, nan=0.0, posinf=1.0))
    return out


def write_png(path, rgb8: np.ndarray):
    _atomic_write(Path(path), png_writer(rgb8))


def png_writer(rgb8: np.ndarray):
    """`write(tmp)` of `write_png`'s file, for `write_together`."""
    from PIL import Image

    return lambda tmp: Image.fromarray(rgb8, "RGB").save(tmp, format="PNG")
