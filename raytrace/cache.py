"""Where the renderer keeps what it computes once: `$RAYTRACE_CACHE` (default ~/.cache/raytrace).

Compiled numba kernels go to a folder named after the package version and a hash of every source
file of the package (`source_key`): numba only checks the timestamp of the file that defines a
cached function, not of the functions it calls from other files, so an edit or an upgrade must
change the folder, never reuse old machine code.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent


def cache_dir() -> Path:
    return Path(os.environ.get("RAYTRACE_CACHE") or Path.home() / ".cache" / "raytrace")


def source_key(package_dir: Path = PACKAGE_DIR) -> str:
    """Hash of the relative path and content of every .py file under `package_dir`."""
    h = hashlib.sha256()
    for path in sorted(package_dir.rglob("*.py")):
        h.update(str(path.relative_to(package_dir)).encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()[:16]


def kernel_cache_dir() -> Path:
    from . import __version__

    return cache_dir() / "numba" / f"{__version__}-{source_key()}"
