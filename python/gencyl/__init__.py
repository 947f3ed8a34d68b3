"""gencyl: exact ray tracing of generalized cylinders (hair and textile fibers).

Scenes are loaded from TOML scene files or ``.hair`` models, or made from numpy arrays;
rays and images come back as numpy arrays. Every result is the command line's
(``gencyl raycast``, ``gencyl render``) to the bit: the package calls the same Rust code.

>>> import numpy as np, gencyl
>>> scene = gencyl.Scene.from_cylinders(
...     np.array([[[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]]], dtype=np.float64),
...     np.array([[0.1, 0.1]]))
>>> hits = scene.raycast(np.array([[1.5, 0.0, 1.0]]), np.array([[0.0, 0.0, -1.0]]))
>>> float(hits["t"][0]), int(hits["part"][0])
(0.9, 0)

``gencyl.dask`` spreads renders and ray batches over a Dask cluster.
"""

from os import PathLike
from typing import Optional, Tuple, Union

import numpy as np

from ._gencyl import Scene, __version__
from ._gencyl import render as _render

__all__ = ["Scene", "render", "xray", "__version__"]


def render(
    scene: Union[Scene, str, "PathLike[str]"],
    integrator: Optional[str] = None,
    spp: Optional[int] = None,
    width: Optional[int] = None,
    crop: Optional[Tuple[int, int, int, int]] = None,
    seed: Optional[int] = None,
    threads: Optional[int] = None,
    max_depth: Optional[int] = None,
    max_pixels: Optional[int] = None,
    radius: Optional[float] = None,
) -> Tuple[np.ndarray, list]:
    """Render ``scene`` (a :class:`Scene` or the path of a scene file or ``.hair`` model).

    Returns ``(image, channels)``: a float32 array of shape (H, W, C), linear values, and the
    channel names (``R, G, B, A``, plus ``Z`` for ``depth`` or ``L`` for ``xray``). The pixels
    are those ``gencyl render`` computes with the same settings, bit for bit, and do not
    depend on ``threads``; ``crop = (x0, y0, x1, y1)`` renders that window of the frame (x1
    and y1 excluded), equal to the same pixels of the whole frame. Settings left ``None`` come
    from the scene's ``[render]`` table, else the defaults (path tracing, 16 spp, depth 16,
    seed 1). The GIL is released while rendering; Ctrl-C stops it between bands of rows.
    """
    return _render(
        scene,
        integrator=integrator,
        spp=spp,
        width=width,
        max_depth=max_depth,
        crop=crop,
        seed=seed,
        threads=threads,
        max_pixels=max_pixels,
        radius=radius,
    )


def xray(
    scene: Union[Scene, str, "PathLike[str]"],
    origins: np.ndarray,
    directions: np.ndarray,
    threads: Optional[int] = None,
) -> dict:
    """Path lengths of rays through the solids of ``scene`` (a :class:`Scene` or a path).

    Returns a dict of (M,) float64 arrays: ``length`` (in units of ``|d|``, world units for
    unit directions) and ``optical_depth`` (weighted by each material's ``mu``).
    """
    if not isinstance(scene, Scene):
        scene = Scene.load(scene)
    return scene.xray(origins, directions, threads=threads)
