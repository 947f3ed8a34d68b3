"""Renders and ray batches spread over a Dask cluster (``dask.distributed``).

A frame is split into crop windows, each rendered as a task on a worker and merged; because
every pixel's samples depend only on its place in the full frame, the merged image equals a
local render of the whole frame bit for bit, whatever the split, the workers or the retries.
Ray batches are split into chunks the same way and come back in input order; a CT scan's views
are split into runs of views (as ``gencyl ct --views a..b``), concatenated in order.

Workers load a scene once each: tasks name the scene by path, and each worker process keeps
the scenes it has loaded (keyed by the file's path, size and modification time, so an edited
file is loaded again). The scene file (and any ``.hair`` files it names) must be readable at
the same path on every worker, as on a shared file system.

>>> from distributed import Client, LocalCluster             # doctest: +SKIP
>>> client = Client(LocalCluster(n_workers=2, threads_per_worker=1))  # doctest: +SKIP
>>> image, channels = gencyl.dask.render(client, "scene.toml", tiles=8, spp=64)  # doctest: +SKIP

On a cluster, ``Client("tcp://scheduler:8786")``, or ``dask_jobqueue.SLURMCluster``, take the
place of the LocalCluster; nothing else changes.
"""

import os
import threading
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

from . import Scene
from . import ct as _ct_local
from . import render as _render_local

__all__ = ["render", "submit_render", "raycast", "ct", "TiledRender", "tiles_of", "worker_loads"]

_SCENES: Dict[Tuple[str, Optional[float], int, int], Scene] = {}
_LOADS: Dict[str, int] = {}
_LOCK = threading.Lock()


def _scene(path: str, radius: Optional[float] = None) -> Scene:
    """The scene at ``path``, loaded at most once per worker process (per file version)."""
    full = os.path.abspath(path)
    st = os.stat(full)
    key = (full, radius, st.st_size, st.st_mtime_ns)
    with _LOCK:
        scene = _SCENES.get(key)
        if scene is None:
            scene = Scene.load(full, radius=radius)
            # Older versions of the file are dropped.
            for k in [k for k in _SCENES if k[0] == full and k[1] == radius]:
                del _SCENES[k]
            _SCENES[key] = scene
            _LOADS[full] = _LOADS.get(full, 0) + 1
        return scene


def worker_loads() -> Dict[str, int]:
    """How many times this process has loaded each scene file (run it on workers with
    ``client.run(gencyl.dask.worker_loads)``)."""
    with _LOCK:
        return dict(_LOADS)


def tiles_of(width: int, height: int, tiles: int) -> List[Tuple[int, int, int, int]]:
    """``tiles`` crop windows ``(x0, y0, x1, y1)`` covering a ``width x height`` frame: a
    grid of about ``tiles`` cells, as square as the frame allows, none empty."""
    if tiles < 1:
        raise ValueError(f"tiles must be at least 1, got {tiles}")
    tiles = min(tiles, width * height)
    # The grid with cols * rows = tiles whose cells are closest to square.
    best = None
    for cols in range(1, tiles + 1):
        if tiles % cols or cols > width or tiles // cols > height:
            continue
        rows = tiles // cols
        ratio = (width / cols) / (height / rows)
        score = abs(np.log(ratio))
        if best is None or score < best[0]:
            best = (score, cols, rows)
    if best is None:  # a prime count that fits neither way: rows of the frame
        cols, rows = 1, min(tiles, height)
    else:
        _, cols, rows = best
    xs = [round(i * width / cols) for i in range(cols + 1)]
    ys = [round(j * height / rows) for j in range(rows + 1)]
    return [(xs[i], ys[j], xs[i + 1], ys[j + 1]) for j in range(rows) for i in range(cols)]


def _frame_task(path: str, radius: Optional[float], width: Optional[int], integrator: Optional[str]):
    """On a worker: the frame's width, height and channel names for these settings."""
    return _scene(path, radius).frame(width=width, integrator=integrator)


def _tile_task(path: str, radius: Optional[float], crop: Tuple[int, int, int, int], settings: Dict[str, Any]):
    """On a worker: one window of the frame."""
    scene = _scene(path, radius)
    image, _ = _render_local(scene, crop=crop, **settings)
    return crop, image


class TiledRender:
    """A render in flight on a cluster: its tile futures, and :meth:`result` to merge them."""

    def __init__(self, client, frame: Tuple[int, int], channels: List[str], futures: list):
        self.client = client
        self.frame = frame
        self.channels = channels
        self.futures = futures

    def result(self) -> Tuple[np.ndarray, List[str]]:
        """Waits for every tile (Dask retries those of workers that die) and merges them into
        the (H, W, C) float32 frame."""
        width, height = self.frame
        out = np.zeros((height, width, len(self.channels)), dtype=np.float32)
        for crop, image in self.client.gather(self.futures):
            x0, y0, x1, y1 = crop
            out[y0:y1, x0:x1, :] = image
        return out, list(self.channels)


def submit_render(
    client,
    scene_path,
    tiles: int = 16,
    radius: Optional[float] = None,
    threads: int = 1,
    **settings,
) -> TiledRender:
    """Starts a render of the scene file at ``scene_path`` as ``tiles`` window tasks and
    returns at once; :meth:`TiledRender.result` waits and merges. ``settings`` are those of
    :func:`gencyl.render` (``integrator``, ``spp``, ``width``, ``max_depth``, ``seed``,
    ``max_pixels``); ``threads`` is per task (default 1: a worker runs one task per thread)."""
    if "crop" in settings:
        raise ValueError("crop: gencyl.dask.render splits the whole frame itself")
    path = os.fspath(scene_path)
    fw, fh, channels = client.submit(
        _frame_task, path, radius, settings.get("width"), settings.get("integrator"), pure=False
    ).result()
    settings = dict(settings, threads=threads)
    futures = [
        client.submit(_tile_task, path, radius, crop, settings, pure=False)
        for crop in tiles_of(fw, fh, tiles)
    ]
    return TiledRender(client, (fw, fh), channels, futures)


def render(client, scene_path, tiles: int = 16, **settings) -> Tuple[np.ndarray, List[str]]:
    """Renders the scene file at ``scene_path`` on the cluster of ``client``, split into
    ``tiles`` windows; returns ``(image, channels)`` as :func:`gencyl.render` does, the same
    image bit for bit. See :func:`submit_render` for the settings."""
    return submit_render(client, scene_path, tiles=tiles, **settings).result()


def _raycast_task(path, radius, origins, directions, tmin, all, threads):
    return _scene(path, radius).raycast(origins, directions, tmin=tmin, all=all, threads=threads)


def raycast(
    client,
    scene_path,
    origins: np.ndarray,
    directions: np.ndarray,
    chunk: int = 1 << 18,
    tmin: float = 0.0,
    all: bool = False,
    radius: Optional[float] = None,
    threads: int = 1,
) -> Dict[str, np.ndarray]:
    """:meth:`gencyl.Scene.raycast` of the scene file at ``scene_path`` on the cluster:
    the rays split into chunks of ``chunk``, cast as tasks, the rows joined in input order
    (``ray`` numbers the input rows), equal to a local raycast's."""
    origins = np.asarray(origins)
    directions = np.asarray(directions)
    if origins.shape != directions.shape or origins.ndim != 2 or origins.shape[1:] != (3,):
        raise ValueError(
            f"origins and directions must both have shape (M, 3), got {origins.shape} and {directions.shape}"
        )
    if chunk < 1:
        raise ValueError(f"chunk must be at least 1, got {chunk}")
    path = os.fspath(scene_path)
    starts = list(range(0, len(origins), chunk)) or [0]
    futures = [
        client.submit(
            _raycast_task,
            path,
            radius,
            origins[s : s + chunk],
            directions[s : s + chunk],
            tmin,
            all,
            threads,
            pure=False,
        )
        for s in starts
    ]
    parts = client.gather(futures)
    for s, part in zip(starts, parts):
        part["ray"] += s
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def _ct_views_task(path: str) -> int:
    """On a worker: how many views the scene's scan has."""
    return _scene(path).ct_geometry()["total_views"]


def _ct_task(path, views, quantity, material, threads):
    return _ct_local(_scene(path), views=views, quantity=quantity, material=material, threads=threads)


def ct(
    client,
    scene_path,
    chunk: int = 8,
    quantity: Optional[str] = None,
    material: Optional[str] = None,
    threads: int = 1,
) -> Tuple[np.ndarray, Dict[str, Any]]:
    """:func:`gencyl.ct` of the scene file at ``scene_path`` on the cluster: its views in runs
    of ``chunk``, projected as tasks, concatenated in order; equal to a local ``gencyl.ct`` bit
    for bit (each view depends on nothing else). Returns ``(projections, geometry)`` with the
    geometry of the whole scan."""
    if chunk < 1:
        raise ValueError(f"chunk must be at least 1, got {chunk}")
    path = os.fspath(scene_path)
    total = client.submit(_ct_views_task, path, pure=False).result()
    runs = [(a, min(a + chunk, total)) for a in range(0, total, chunk)]
    futures = [
        client.submit(_ct_task, path, run, quantity, material, threads, pure=False) for run in runs
    ]
    parts = client.gather(futures)
    geometry = dict(parts[0][1])
    geometry["vectors"] = [v for _, g in parts for v in g["vectors"]]
    geometry["views"] = [0, total]
    return np.concatenate([p for p, _ in parts]), geometry
