"""gencyl.dask on a LocalCluster of 2 worker processes (loopback only): merged renders and ray
batches equal local ones bit for bit, workers load a scene once, and a worker killed in the
middle of a render has its tiles retried without changing the image."""

import os
import signal
import time

import numpy as np
import pytest

import gencyl
import gencyl.dask
from conftest import REPO, hard_rays

distributed = pytest.importorskip("distributed")

DEFAULT = str(REPO / "examples" / "default.toml")


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
        silence_logs=40,
    )
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


def bits(a):
    return a.view(np.uint32)


def test_tiles_cover_the_frame_once():
    for w, h, n in [(400, 300, 16), (7, 5, 35), (640, 480, 7), (3, 1000, 13), (1, 1, 4)]:
        cover = np.zeros((h, w), dtype=int)
        for x0, y0, x1, y1 in gencyl.dask.tiles_of(w, h, n):
            assert x0 < x1 and y0 < y1
            cover[y0:y1, x0:x1] += 1
        assert (cover == 1).all(), (w, h, n)
    with pytest.raises(ValueError):
        gencyl.dask.tiles_of(10, 10, 0)


def test_a_distributed_render_equals_a_local_one(client):
    settings = dict(width=120, spp=2)
    local, channels = gencyl.render(DEFAULT, **settings)
    image, got_channels = gencyl.dask.render(client, DEFAULT, tiles=9, **settings)
    assert got_channels == channels
    assert image.shape == local.shape == (90, 120, 4)
    assert np.array_equal(bits(image), bits(local))
    # Each worker loaded the scene at most once for all its tiles.
    loads = client.run(gencyl.dask.worker_loads)
    per_worker = [v.get(os.path.abspath(DEFAULT), 0) for v in loads.values()]
    assert sum(per_worker) >= 1 and max(per_worker) == 1, loads
    # Again: no more loads.
    gencyl.dask.render(client, DEFAULT, tiles=4, width=40, spp=1, integrator="depth")
    loads = client.run(gencyl.dask.worker_loads)
    assert max(v.get(os.path.abspath(DEFAULT), 0) for v in loads.values()) == 1, loads


def test_a_distributed_raycast_equals_a_local_one(client):
    scene = gencyl.Scene.load(DEFAULT)
    origins, directions = hard_rays(scene.bounds, 5000, seed=4)
    local = scene.raycast(origins, directions, all=True)
    got = gencyl.dask.raycast(client, DEFAULT, origins, directions, chunk=700, all=True)
    assert len(local["t"]) > 500
    for k in local:
        assert got[k].dtype == local[k].dtype and np.array_equal(got[k], local[k]), k
    with pytest.raises(ValueError, match="shape"):
        gencyl.dask.raycast(client, DEFAULT, origins[:, :2], directions[:, :2])


def test_a_killed_worker_changes_nothing(client):
    settings = dict(width=160, spp=24)
    local, _ = gencyl.render(DEFAULT, **settings)
    job = gencyl.dask.submit_render(client, DEFAULT, tiles=24, **settings)
    distributed.wait(job.futures, return_when="FIRST_COMPLETED")
    # A worker that is rendering a tile right now: kill its process outright (SIGKILL, no
    # clean shutdown); its nanny starts a new one and the scheduler hands its tiles on.
    busy = []
    for _ in range(200):
        busy = [w for w, keys in client.processing().items() if keys]
        if busy:
            break
        time.sleep(0.01)
    assert busy, "a worker is busy"
    pids = client.run(os.getpid)
    victim = busy[0]
    os.kill(pids[victim], signal.SIGKILL)
    image, _ = job.result()
    assert np.array_equal(bits(image), bits(local))
    done = sum(f.status == "finished" for f in job.futures)
    assert done == len(job.futures)
    # The worker really died and was replaced.
    client.wait_for_workers(2, timeout=60)
    assert pids[victim] not in client.run(os.getpid).values()


def test_ct_views_spread_over_workers_equal_a_local_scan(client, tmp_path):
    path = tmp_path / "ct.toml"
    path.write_text(
        '[[strand]]\npoints = [[0, 0, -1], [0.05, 0, 0], [0, 0.05, 1]]\nradius = [0.1, 0.1]\n'
        "ellipticity = 0.7\ntwist = [0, 2]\n"
        '[[sphere]]\ncenter = [0.3, 0, 0]\nradius = 0.1\n'
        '[ct]\nbeam = "cone"\ndetector = [20, 8]\npixel = [0.05, 0.2]\nviews = 11\n'
        "source_distance = 3\ndetector_distance = 1\nsamples = 4\n"
    )
    local, geometry = gencyl.ct(str(path))
    spread, g = gencyl.dask.ct(client, path, chunk=3)
    assert spread.shape == (11, 8, 20)
    assert np.array_equal(bits(spread), bits(local))
    assert g["vectors"] == geometry["vectors"] and g["views"] == [0, 11]
    assert local.max() > 0.1
