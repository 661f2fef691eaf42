"""The render options: one frozen record that the API builds and checks once (`api.render_options`)
and the renderer, its progressive passes and the experiments read.

The method's own parameters (precision, steps, shadow_test, ...) are not render options: each method
declares and checks them (raytrace/methods). Where the tiles run is not an option either: it is the
executor given beside the options (`renderer.Threads`, or the Dask cluster of raytrace/rendering/distributed.py).
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable


@dataclass(frozen=True)
class RenderOptions:
    """Every option of one render, with its value resolved (the scene's [render] table and the
    defaults applied by `api.render_options`, which also checks every value)."""
    spp: int | None = None  # samples per pixel, width, height: override the camera's when given
    width: int | None = None
    height: int | None = None
    seed: int = 0  # of the stochastic methods' random numbers
    threads: int | None = None  # of the thread pool (None: every core this process may use)
    crop: tuple[int, int, int, int] | None = None  # (x0, y0, x1, y1), end exclusive: the same samples
    volumetric_shadows: bool = False  # the air-light over each light's lit intervals (shadows/frusta.py);
    # off in this record (the renderer's and experiments' own calls), on by default in api.render
    passes: int | None = None  # stochastic methods' progressive rendering (rendering/progressive.py): stop after
    time_budget: float | None = None  # this many passes, seconds of rendering, or at this estimated
    target_error: float | None = None  # mean relative standard error, whichever comes first
    checkpoint: Path | None = None  # resumed when it exists, written after passes
    checkpoint_interval: float = 0.0  # least seconds between checkpoint writes
    max_memory: float | None = None  # GiB the image's arrays must fit (None: 80 % of physical memory)
    progress: Callable[[int, int], None] | None = None  # (tiles done, tiles) of the render or pass in flight
    on_pass: Callable[[int, float], None] | None = None  # (passes done, estimated mean relative error)
    observer: Callable | None = None  # (y0, y1, x0, x1, radiance (y1-y0, x1-x0, 3)) of every finished block
    aov: tuple = ()  # output layers beside the image (aov.NAMES, checked by aov.check)
    notice: Callable[[str], None] | None = None  # one-line notes (the kernels' compile when it is slow)

    @property
    def shadows(self) -> bool:
        """Whether the air-light is shadowed (volumetric shadows)."""
        return bool(self.volumetric_shadows)

    @property
    def progressive(self) -> bool:
        """Whether a progressive option (passes, budget, target, checkpoint) is given."""
        return bool(self.passes or self.time_budget or self.target_error or self.checkpoint)

    def apply_camera(self, cam):
        """Set `cam`'s spp, width and height to the ones given here."""
        cam.spp, cam.width, cam.height = self.spp or cam.spp, self.width or cam.width, self.height or cam.height


MEMORY_SHARE = 0.8  # of the machine's physical memory a render (or an importer's buffers) may plan to use


def physical_memory() -> int:
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
