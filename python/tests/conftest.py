"""Shared fixtures: the repository, the `gencyl` command to compare against, ray sets that
sample where intersection breaks (near-perpendicular, grazing, origins on the surface)."""

import os
import pathlib
import subprocess

import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


def cli_path() -> pathlib.Path:
    """The `gencyl` binary: $GENCYL_BIN, else target/release/gencyl (or $CARGO_TARGET_DIR's)."""
    if "GENCYL_BIN" in os.environ:
        return pathlib.Path(os.environ["GENCYL_BIN"])
    target = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    return target / "release" / "gencyl"


@pytest.fixture(scope="session")
def gencyl_cli():
    path = cli_path()
    if not path.exists():
        pytest.fail(f"{path} is missing: run `cargo build --release` (or set GENCYL_BIN)")

    def run(*args, check=True, **kw):
        return subprocess.run(
            [str(path), *map(str, args)], capture_output=True, text=True, check=check, **kw
        )

    return run


def write_rays(path, origins, directions):
    """A ray file with every number in shortest round-trip form (Python's repr)."""
    with open(path, "w") as f:
        f.write("ox,oy,oz,dx,dy,dz\n")
        for o, d in zip(origins.tolist(), directions.tolist()):
            f.write(",".join(repr(x) for x in (*o, *d)) + "\n")


def read_hits(text):
    """`gencyl raycast` CSV as the dict `Scene.raycast` returns."""
    lines = text.strip().splitlines()
    assert lines[0] == "ray,t,u,v,nx,ny,nz,object,part", lines[0]
    rows = [line.split(",") for line in lines[1:]]
    col = lambda i, f: np.array([f(r[i]) for r in rows])
    return {
        "ray": col(0, int).astype(np.int64),
        "t": col(1, float),
        "u": col(2, float),
        "v": col(3, float),
        "normal": np.array([[float(r[4]), float(r[5]), float(r[6])] for r in rows]).reshape(-1, 3),
        "object": col(7, int).astype(np.int64),
        "part": col(8, int).astype(np.int8),
    }


def hard_rays(bounds, n, seed):
    """Rays at the scene: through random points of the box from outside it, a third of them
    within 1e-15..1e-1 rad (log-uniform) of perpendicular to the box's long axis, some
    exactly perpendicular."""
    rng = np.random.default_rng(seed)
    lo, hi = bounds
    size = np.linalg.norm(hi - lo)
    targets = lo + rng.random((n, 3)) * (hi - lo)
    d = rng.normal(size=(n, 3))
    axis = np.zeros(3)
    axis[np.argmax(hi - lo)] = 1.0
    k = n // 3
    # Perpendicular to the axis, then tilted by a log-uniform angle (exactly 0 for some).
    d[:k] -= np.outer(d[:k] @ axis, axis)
    tilt = 10.0 ** rng.uniform(-15, -1, k)
    tilt[::7] = 0.0
    d[:k] += np.outer(tilt * np.linalg.norm(d[:k], axis=1), axis)
    d /= np.linalg.norm(d, axis=1)[:, None]
    origins = targets - d * size
    return origins, d
