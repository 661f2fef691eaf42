"""`render --display-server HOST:PORT`: the image shown in tev as it renders (raytrace/output/tev.py), against
the stand-in tev of tests/test_tev.py on the loopback; an unreachable viewer is one warning line."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import raytrace
from raytrace.cli import main
from raytrace.output import film

from .conftest import box_room, to_toml
from .test_tev import StandIn, assemble, free_port

REPO = Path(__file__).resolve().parents[1]


def _scene(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(to_toml(box_room()))
    return str(path)


@pytest.fixture(scope="module", autouse=True)
def compiled():
    """The kernels compiled before a stand-in starts: it waits at most 5 s between packets."""
    raytrace.render(box_room(), width=2, height=2, threads=1)


def test_every_pixel_reaches_tev_as_in_the_exr(tmp_path, capsys):
    server = StandIn()
    out = tmp_path / "room.exr"
    assert main([_scene(tmp_path), "--width", "9", "--height", "7", "--out", str(out), "--quiet",
                 "--display-server", server.address]) == 0
    assert capsys.readouterr().err == ""
    create, *updates = server.packets()
    assert create == dict(type="create", focus=1, name="room", width=9, height=7, channels=["R", "G", "B"])
    image, count = assemble(updates, 9, 7)
    assert (count == 1).all()
    exr, _ = film.read_exr(out)
    np.testing.assert_array_equal(image, exr.astype(np.float32))


def test_a_crop_paints_only_its_block(tmp_path):
    server = StandIn()
    assert main([_scene(tmp_path), "--width", "9", "--height", "7", "--crop", "2,1,5,4", "--quiet",
                 "--out", str(tmp_path / "a.exr"), "--display-server", server.address]) == 0
    create, *updates = server.packets()
    _, count = assemble(updates, 9, 7)
    want = np.zeros((7, 9), int)
    want[1:4, 2:5] = 1
    np.testing.assert_array_equal(count, want)


def test_an_unreachable_viewer_is_one_warning_line_and_the_render_goes_on(tmp_path):
    """End to end (a pytest run records warnings instead of printing them): exit 0, the EXR written,
    and stderr exactly one line."""
    address = f"127.0.0.1:{free_port()}"
    out = tmp_path / "a.exr"
    proc = subprocess.run([sys.executable, str(REPO / "render.py"), _scene(tmp_path), "--width", "4", "--height", "3",
                           "--out", str(out), "--quiet", "--display-server", address],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.count("\n") == 1
    assert proc.stderr.startswith(f"warning: display server {address} (tev): cannot connect")
    assert out.is_file()


def test_a_badly_formed_address_is_refused_before_rendering(tmp_path, capsys):
    assert main([_scene(tmp_path), "--out", str(tmp_path / "a.exr"), "--display-server", "localhost"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: --display-server 'localhost': expected HOST:PORT")
    assert not (tmp_path / "a.exr").exists()
