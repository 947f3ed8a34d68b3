"""Type stubs of the native module (``gencyl.Scene`` and ``gencyl.render`` come from here)."""

from os import PathLike
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

_Pair = Union[float, Tuple[float, float], Sequence[float]]
_Path = Union[str, "PathLike[str]"]

class Scene:
    """A scene ready for ray queries and renders: cylinders under a BVH, with their
    materials, lights, camera and ``[render]`` settings."""

    @staticmethod
    def load(path: _Path, radius: Optional[float] = None) -> "Scene":
        """Load a TOML scene file or a ``.hair`` model (``radius``: ``.hair`` only)."""
    @staticmethod
    def from_cylinders(
        bezier: npt.NDArray[np.float64],
        major_radius: npt.NDArray[np.float64],
        minor_radius: Optional[npt.NDArray[np.float64]] = None,
        rotation: Optional[npt.NDArray[np.float64]] = None,
        caps: bool = True,
        normal_hint: Optional[npt.NDArray[np.float64]] = None,
    ) -> "Scene":
        """Cylinders from (N, 4, 3) control points and (N, 2) radii and rotations."""
    @staticmethod
    def from_strands(
        points: Sequence[npt.NDArray[np.float64]],
        radius: _Pair,
        ellipticity: Optional[float] = None,
        twist: Optional[_Pair] = None,
        frame: str = "minimal",
        control_points: bool = False,
    ) -> "Scene":
        """Strands through (K, 3) point arrays, as ``[[strand]]`` tables."""
    def __len__(self) -> int: ...
    @property
    def bounds(self) -> Optional[npt.NDArray[np.float64]]:
        """``[min, max]`` as a (2, 3) array, or None without geometry."""
    def frame(
        self, width: Optional[int] = None, integrator: Optional[str] = None
    ) -> Tuple[int, int, List[str]]:
        """``(width, height, channels)`` of a render with these settings."""
    def raycast(
        self,
        origins: npt.NDArray[np.float64],
        directions: npt.NDArray[np.float64],
        tmin: float = 0.0,
        all: bool = False,
        threads: Optional[int] = None,
    ) -> Dict[str, np.ndarray]:
        """Hits as arrays: ray, t, u, v, normal (H, 3), object, part."""
    def labels(
        self,
        origin: Tuple[float, float, float],
        voxel: float,
        size: Tuple[int, int, int],
        threads: Optional[int] = None,
    ) -> npt.NDArray[np.uint32]:
        """Cylinder number + 1 at each voxel centre (0 outside), (nz, ny, nx)."""
    def ct_geometry(self) -> Dict[str, Any]:
        """The [ct] scan's geometry (ASTRA vectors), as the sidecar of gencyl ct."""
    def xray(
        self,
        origins: npt.NDArray[np.float64],
        directions: npt.NDArray[np.float64],
        threads: Optional[int] = None,
    ) -> Dict[str, npt.NDArray[np.float64]]:
        """Path lengths: length and optical_depth, (M,) each."""

def render(
    scene: Union[Scene, _Path],
    integrator: Optional[str] = None,
    spp: Optional[int] = None,
    width: Optional[int] = None,
    max_depth: Optional[int] = None,
    crop: Optional[Tuple[int, int, int, int]] = None,
    seed: Optional[int] = None,
    threads: Optional[int] = None,
    max_pixels: Optional[int] = None,
    radius: Optional[float] = None,
) -> Tuple[npt.NDArray[np.float32], List[str]]: ...

def ct(
    scene: Union[Scene, _Path],
    views: Optional[Tuple[int, int]] = None,
    quantity: Optional[str] = None,
    material: Optional[str] = None,
    threads: Optional[int] = None,
) -> Tuple[npt.NDArray[np.float32], Dict[str, Any]]:
    """CT projections (views, rows, columns) and the geometry (ASTRA vectors)."""

def phantom(kind: str, **spec: Any) -> Tuple[str, Dict[str, Any]]:
    """A yarn or ply phantom: (scene TOML text, ground truth dict)."""

def scatter(
    aspect: float = 1.0,
    profile: Optional[npt.NDArray[np.float64]] = None,
    rotation: float = 0.0,
    eta: float = 1.55,
    sigma_a: float = 0.0,
    tilt: float = 0.0,
    theta_i: float = 0.0,
    phi_i: float = 0.0,
    rays: int = 100_000,
    max_order: int = 3,
    bins: int = 90,
    seed: int = 1,
    threads: Optional[int] = None,
) -> Dict[str, Any]:
    """The goniometer: values (orders, bins, bins), theta_deg, phi_deg, lost, absorbed, hits."""
