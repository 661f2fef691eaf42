"""Single scattering in participating media with the closed-form air-light of Pegoraro & Parker 2009.

`raytrace.render(scene, method=..., **params)` returns an `Image` (see raytrace/api.py);
`raytrace.assets()` downloads the paper's meshes (docs/assets.md)."""

__version__ = "0.1.0"

from .api import Image, load, render  # noqa: E402
from .errors import UserError  # noqa: E402
from .scene.download import assets  # noqa: E402

__all__ = ["Image", "UserError", "assets", "load", "render", "__version__"]
