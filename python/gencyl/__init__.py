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

``gencyl.ct`` gives a scene's X-ray CT projections (its ``[ct]`` table) as a (views, rows,
columns) array with the geometry in ASTRA's vector form. ``gencyl.dask`` spreads renders,
ray batches and CT views over a Dask cluster.
"""

from os import PathLike
from typing import Optional, Union

import numpy as np

from ._gencyl import Scene, __version__, ct, phantom, render, scatter

__all__ = ["Scene", "ct", "phantom", "render", "scatter", "xray", "__version__"]


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
