"""Every note a command prints is one `warning:` line on stderr, the gallery's skipped scenes too
(through a real process: pytest would otherwise record the warnings instead of printing them)."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def test_a_scene_the_gallery_skips_is_a_warning_line(tmp_path):
    env = {**os.environ, "RAYTRACE_ASSETS": str(tmp_path / "no_meshes_here"),
           "PYTHONPATH": str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    proc = subprocess.run([sys.executable, str(REPO / "render.py"), "gallery", "--out", str(tmp_path / "g"),
                           "sibenik", "bridge"], capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stderr.splitlines()
    assert [line.split(":")[:3] for line in lines] == [["warning", " gallery", " skipped sibenik"],
                                                      ["warning", " gallery", " skipped bridge"]], proc.stderr
    assert proc.stdout.splitlines() == [f"wrote 0 images to {tmp_path / 'g'}"]
