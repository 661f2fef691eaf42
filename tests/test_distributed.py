"""Rendering on a Dask cluster (raytrace/rendering/distributed.py, issue 13), on real local clusters of worker
processes: the same image bit for bit as the threaded renderer whatever the number of workers,
a killed worker changes nothing, checkpoints resume across machine and cluster, bad input is one
line and exit status 2, and without --scheduler Dask is never imported."""
import os
import signal
import socket
import subprocess
import sys
import time
import weakref
from pathlib import Path

import numpy as np
import pytest

import raytrace
from raytrace.cli import main
from raytrace.rendering import renderer

from .conftest import box_room, to_toml

ROOT = Path(__file__).resolve().parents[1]
SMALL_TILES = 64  # rays per tile and per summed row here: many tasks, and sample ranges (a row has 24 x 4 rays)


def room(**camera):
    return box_room(camera={"position": [0.3, 0.2, 3.0], "look_at": [0.0, 0.0, -1.0], "fov": 70.0, "width": 24,
                            "height": 18, "spp": 4, **camera})


@pytest.fixture(scope="module")
def client():
    pytest.importorskip("distributed")
    from raytrace.rendering.distributed import connect

    with connect("local:2") as c:
        yield c


@pytest.fixture
def small_tiles(monkeypatch):
    monkeypatch.setattr(renderer, "RAYS_PER_TILE", SMALL_TILES)
    monkeypatch.setattr(renderer, "SUM_RAYS", SMALL_TILES)


def exr_channels(path):
    import OpenEXR

    with OpenEXR.File(str(path), separate_channels=True) as f:
        header = {k: v for k, v in f.header().items() if isinstance(v, str) and k not in ("render_seconds",
                  "compile_seconds", "created")}
        return {k: np.asarray(c.pixels).tobytes() for k, c in f.channels().items()}, header


def test_dask_is_not_imported_without_the_option(tmp_path):
    code = (f"import sys; sys.path.insert(0, {str(ROOT)!r}); import raytrace; from raytrace.cli import main; "
            f"from tests.conftest import box_room; raytrace.render(box_room(), method='analytic'); "
            f"assert main(['render', '--width', '8', '--height', '6', '--out', {str(tmp_path / 'a.exr')!r}, "
            "'--quiet']) == 0; "
            "bad = sorted(m for m in sys.modules if m.split('.')[0] in ('dask', 'distributed')); "
            "assert not bad, bad")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=tmp_path)


@pytest.mark.parametrize("per_row, ranges", [(SMALL_TILES, 4), (1 << 14, 1)])
def test_the_tiles_cover_every_ray_once_and_split_samples_when_a_row_is_long(monkeypatch, per_row, ranges):
    monkeypatch.setattr(renderer, "SUM_RAYS", per_row)
    cam = raytrace.load(room(spp=7)).camera  # 64 rays a row: ranges of 64 // 24 = 2 samples, 7 = 2+2+2+1
    for box in ((0, 0, 24, 18), (3, 2, 9, 5)):
        x0, y0, x1, y1 = box
        hits = np.zeros((y1 - y0, x1 - x0, cam.spp), dtype=int)
        work = renderer.tiles(cam, box)
        for t in work:
            q = np.arange(t.pixels.start, t.pixels.stop, t.pixels.step)
            hits[t.rows.start - y0 + q // (x1 - x0), q % (x1 - x0), t.samples] += 1
        assert np.all(hits == 1) and len({(t.samples.start, t.samples.stop) for t in work}) == ranges


@pytest.mark.parametrize("method, params", [("analytic", {"precision": 1e-6}),
                                            ("montecarlo", {"samples": 2, "seed": 7})])
def test_the_cluster_gives_the_threaded_image_bit_for_bit(client, small_tiles, method, params):
    scene = room()
    one = raytrace.render(scene, method=method, threads=2, **params)
    many = raytrace.render(scene, method=method, client=client, **params)
    assert one.array.tobytes() == many.array.tobytes() and one.stats == many.stats
    if one.variance is not None:
        assert one.variance.tobytes() == many.variance.tobytes()
    shafts = dict(volumetric_shadows=True, crop=(2, 3, 20, 15))
    assert (raytrace.render(scene, method=method, threads=1, **shafts, **params).array.tobytes()
            == raytrace.render(scene, method=method, client=client, **shafts, **params).array.tobytes())


def test_local_workers_keep_the_dynamic_mmap_threshold(client):
    """Dask's MALLOC_TRIM_THRESHOLD_ would make every tile 25-40 % slower (distributed.WORKER_CONFIG)."""
    assert set(client.run(os.environ.get, "MALLOC_TRIM_THRESHOLD_").values()) == {None}


def test_the_exr_is_the_same_on_one_machine_one_worker_and_two(client, small_tiles, tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text(to_toml(room()))
    common = ["render", str(path), "--method", "montecarlo", "--samples", "2", "--seed", "3"]
    assert main(common + ["--out", str(tmp_path / "threads.exr"), "--quiet"]) == 0
    assert main(common + ["--out", str(tmp_path / "one.exr"), "--scheduler", "local:1"]) == 0
    assert "dask local:1: 1 worker, " in capsys.readouterr().err
    assert main(common + ["--out", str(tmp_path / "two.exr"), "--quiet", "--scheduler", client.scheduler.address]) == 0
    want = exr_channels(tmp_path / "threads.exr")
    assert set(want[0]) == {"R", "G", "B", "variance.R", "variance.G", "variance.B",
                            "error_bound.R", "error_bound.G", "error_bound.B"}
    assert exr_channels(tmp_path / "one.exr") == want
    assert exr_channels(tmp_path / "two.exr") == want


def test_checkpoints_resume_on_the_cluster_or_on_one_machine(client, small_tiles, tmp_path):
    scene = room()
    opts = dict(method="montecarlo", samples=2, seed=11)
    want = raytrace.render(scene, passes=3, **opts)
    a, b = tmp_path / "a.ckpt.npz", tmp_path / "b.ckpt.npz"
    raytrace.render(scene, passes=1, checkpoint=a, **opts)  # one machine, then the cluster
    got_a = raytrace.render(scene, passes=3, checkpoint=a, client=client, **opts)
    raytrace.render(scene, passes=2, checkpoint=b, client=client, **opts)  # the cluster, then one machine
    got_b = raytrace.render(scene, passes=3, checkpoint=b, **opts)
    for got in (got_a, got_b):
        assert got.array.tobytes() == want.array.tobytes() and got.variance.tobytes() == want.variance.tobytes()
        assert got.stats["passes"] == 3


def test_sweep_and_compare_on_the_cluster(client, tmp_path, capsys):
    import csv
    import json

    path = tmp_path / "s.toml"
    path.write_text(to_toml(room(spp=1)))
    sweep = ["sweep", str(path), "--grid", "medium.sigma_s=0.1,0.3", "--grid", 'medium.phase="isotropic",'
             '{type="hg",g=0.5}', "--methods", "analytic,raymarch:steps=8", "--reference", "quadrature"]
    assert main(sweep + ["--out", str(tmp_path / "sw"), "--scheduler", client.scheduler.address]) == 0
    rows = list(csv.DictReader((tmp_path / "sw" / "sweep.csv").open()))
    assert len(rows) == 8 and {r["medium.sigma_s"] for r in rows} == {"0.1", "0.3"}
    assert all(float(r["seconds"]) > 0 and float(r["mean_rel"]) >= 0 for r in rows)
    assert len(json.loads((tmp_path / "sw" / "sweep.json").read_text())["rows"]) == 8
    assert len(list((tmp_path / "sw").glob("p*.exr"))) == 4 * 3
    assert main(sweep + ["--out", str(tmp_path / "local")]) == 0
    for name in ("p000_analytic.exr", "p003_raymarch_steps_8.exr", "p002_reference.exr"):
        assert exr_channels(tmp_path / "sw" / name)[0] == exr_channels(tmp_path / "local" / name)[0]
    assert main(["compare", str(path), "--methods", "analytic,sun", "--out", str(tmp_path / "cmp"),
                 "--scheduler", client.scheduler.address]) == 0
    assert (tmp_path / "cmp" / "compare.md").is_file() and (tmp_path / "cmp" / "sun.exr").is_file()
    capsys.readouterr()


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _refused(args, tmp_path, capsys, limit):
    out = tmp_path / "o.exr"
    start = time.perf_counter()
    assert main(["render", "--width", "8", "--height", "6", "--out", str(out), "--quiet"] + args) == 2
    assert time.perf_counter() - start < limit
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--scheduler" in err and not out.exists()
    return err


def test_an_unreachable_scheduler_is_one_line_within_the_timeout(tmp_path, capsys, monkeypatch):
    pytest.importorskip("distributed")
    from raytrace.rendering import distributed

    monkeypatch.setattr(distributed, "CONNECT_TIMEOUT", 2.0)
    err = _refused(["--scheduler", f"tcp://127.0.0.1:{_free_port()}"], tmp_path, capsys, 15)
    assert "no scheduler answered within 2 s" in err and "dask scheduler" in err
    assert "local:N" in _refused(["--scheduler", "local:0"], tmp_path, capsys, 5)


def test_a_scheduler_without_workers_is_one_line(tmp_path, capsys, monkeypatch):
    distributed = pytest.importorskip("distributed")
    from raytrace.rendering import distributed as ours

    monkeypatch.setattr(ours, "WORKER_TIMEOUT", 2.0)
    with distributed.LocalCluster(n_workers=0, processes=False, protocol="tcp://", dashboard_address=None) as c:
        err = _refused(["--scheduler", c.scheduler_address], tmp_path, capsys, 15)
    assert "has no workers after 2 s" in err and "dask worker" in err


def test_workers_that_cannot_find_the_meshes_are_one_line(client, tmp_path, capsys, monkeypatch):
    (tmp_path / "assets").mkdir()
    (tmp_path / "assets" / "plate.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "scenes").mkdir()
    scene = room()
    scene["shape"].append({"mesh": "plate.obj"})
    path = tmp_path / "scenes" / "s.toml"
    path.write_text(to_toml(scene))
    monkeypatch.setenv("RAYTRACE_ASSETS", str(tmp_path / "assets"))  # here, not on the workers started before
    err = _refused([str(path), "--scheduler", client.scheduler.address], tmp_path, capsys, 30)
    assert "plate.obj" in err and "RAYTRACE_ASSETS" in err and "worker" in err


_alive: list = []  # in a worker process: weak references to the pixel samples' environment frusta built there
_peak = [0]  # the most of them alive at a build


def _count_frusta():
    """client.run target: count the pixel samples' environment frusta this worker builds from now on."""
    _alive.clear()
    _peak[0] = 0
    build = getattr(renderer.build_frusta, "uncounted", renderer.build_frusta)

    def counted(accel, lights, *args, rows=None, **kw):
        out = build(accel, lights, *args, rows=rows, **kw)
        if rows is not None:  # a pixel sample's view (`Prepared.base`)
            _alive.append(weakref.ref(out[np.flatnonzero(rows)[0]]))
            _peak[0] = max(_peak[0], sum(r() is not None for r in _alive))
        return out

    counted.uncounted = build
    renderer.build_frusta = counted


def _frusta_counts():
    """client.run target: (built, most alive at once, alive now), the counting stopped."""
    renderer.build_frusta = getattr(renderer.build_frusta, "uncounted", renderer.build_frusta)
    return len(_alive), _peak[0], sum(r() is not None for r in _alive)


def _min_tile_rays(n):
    """client.run target (and here): renderer.MIN_TILE_RAYS = n; returns the value it had."""
    old, renderer.MIN_TILE_RAYS = renderer.MIN_TILE_RAYS, n
    return old


def test_a_worker_keeps_only_the_samples_in_flight(client, monkeypatch):
    """With an environment light every pixel sample has its own directions and shadow frusta (`renderer.seeded`):
    a worker builds each sample's once and drops it when it starts a tile of another sample, and the rest when the
    render is over, so that its memory does not grow with spp (on 2b62f87 a worker kept every sample it saw,
    spp 8 here: 8 alive at once). The image is the threaded render's bit for bit."""
    from .test_environment import ENV, FOG, GROUND, PLATE, scene as env_scene
    from .test_environment_stats import LAMP

    camera = {"position": [0.0, 0.6, 3.0], "look_at": [0.0, 0.4, 0.0], "fov": 40.0, "width": 8, "height": 6, "spp": 8}
    scene = env_scene([ENV, LAMP], medium=FOG, camera=camera, shapes=[GROUND, PLATE])
    opts = dict(method="quadrature", rtol=1e-6, volumetric_shadows=True, seed=3)
    want = raytrace.render(scene, threads=2, **opts)
    monkeypatch.setattr(renderer, "MIN_TILE_RAYS", 8)  # 6 tiles a sample (the workers' the same)
    assert len(renderer.tiles(raytrace.load(scene).camera, (0, 0, 8, 6), by_sample=True)) == 6 * camera["spp"]
    old = client.run(_min_tile_rays, 8)
    client.run(_count_frusta)
    try:
        got = raytrace.render(scene, client=client, **opts)
    finally:
        counts = client.run(_frusta_counts)
        for address, n in old.items():
            client.run(_min_tile_rays, n, workers=[address])
    assert got.array.tobytes() == want.array.tobytes() and got.variance.tobytes() == want.variance.tobytes()
    built = sum(n for n, _, _ in counts.values())
    assert built >= camera["spp"], counts  # every sample built on some worker
    assert all(peak <= 2 and alive == 0 for _, peak, alive in counts.values()), counts  # one thread a worker


def test_a_killed_worker_loses_only_its_tasks_in_flight(client, small_tiles):
    """Runs last: the module's cluster comes back with a new worker process (its nanny restarts it)."""
    scene = room(width=32, height=24)
    opts = dict(method="montecarlo", samples=4, seed=5)
    want = raytrace.render(scene, threads=2, **opts)
    pids = client.run(os.getpid)
    killed = {}

    def kill_one(done, total):
        if not killed:
            address, pid = sorted(pids.items())[0]
            os.kill(pid, signal.SIGKILL)
            killed.update(address=address, done=done, total=total)

    got = raytrace.render(scene, client=client, progress=kill_one, **opts)
    assert killed["done"] < killed["total"] and pids[killed["address"]] not in client.run(os.getpid).values()
    assert got.array.tobytes() == want.array.tobytes() and got.variance.tobytes() == want.variance.tobytes()
