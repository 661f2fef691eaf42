"""docs/example.ipynb runs top to bottom in a fresh kernel (nbclient, ipykernel: the `test` extra) and
shows what it promises: no cell fails (its own asserts included: the analytic image within the error
bounds of the quadrature reference, the EXR read back equal), the image and the march appear as PNG
previews with their captions, and the files are written."""
from __future__ import annotations

import base64
import io
from pathlib import Path

import nbclient
import nbformat
import numpy as np
from PIL import Image as Picture

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOK = ROOT / "docs" / "example.ipynb"


def _run(monkeypatch):
    monkeypatch.setenv("PYTHONPATH", str(ROOT))  # the kernel imports this checkout's raytrace
    nb = nbformat.read(NOTEBOOK, as_version=4)
    # in docs/, as Jupyter opens it; a failing cell raises CellExecutionError with its traceback
    nbclient.NotebookClient(nb, timeout=900, kernel_name="python3",
                            resources={"metadata": {"path": str(NOTEBOOK.parent)}}).execute()
    return [c for c in nb.cells if c.cell_type == "code"]


def _outputs(cell, kind):
    return [o for o in cell.outputs if o.output_type == kind]


def test_the_example_notebook_runs_and_shows_its_images(monkeypatch):
    cells = _run(monkeypatch)
    assert not [o for c in cells for o in _outputs(c, "error")]
    shown = [o.data for c in cells for o in _outputs(c, "execute_result") if "image/png" in o.data]
    assert len(shown) == 3  # the analytic image, the 16-step march, then the first light's layer
    for data, method in zip(shown, ("analytic", "raymarch", "analytic")):
        with Picture.open(io.BytesIO(base64.b64decode(data["image/png"]))) as picture:
            assert picture.format == "PNG" and picture.size == (192, 96)
            assert len(np.unique(np.asarray(picture.convert("RGB")).reshape(-1, 3), axis=0)) > 100  # not a flat fill
        assert f"box_room: 192x96, method {method}" in data["text/html"] or f"box_room (light0): 192x96, method {method}" in data["text/html"]
    printed = "".join(o.text for c in cells for o in _outputs(c, "stream") if o.name == "stdout")
    assert "100% of pixel channels bounded" in printed
    assert "['box_room.exr', 'box_room.png'] analytic box_room" in printed
    assert "['depth', 'light0', 'emission'] the light layers and emission sum to the image" in printed


def test_the_committed_notebook_carries_its_outputs():
    """Saved executed (where it is browsed, the images show): every code cell ran, in order, without an
    error, and the three previews are there as PNG."""
    cells = [c for c in nbformat.read(NOTEBOOK, as_version=4).cells if c.cell_type == "code"]
    assert [c.execution_count for c in cells] == list(range(1, len(cells) + 1))
    assert all(c.outputs for c in cells) and not [o for c in cells for o in _outputs(c, "error")]
    shown = [o.data for c in cells for o in _outputs(c, "execute_result") if "image/png" in o.data]
    assert len(shown) == 3 and all(d["text/plain"].startswith(("Image(box_room: 192x96, method ",
                                                               "Image(box_room (light0): 192x96, method ")) for d in shown)
