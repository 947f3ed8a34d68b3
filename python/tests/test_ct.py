"""CT projections from Python: equal to `gencyl ct`'s TIFF pages bit for bit, and checked by
reconstruction with a tool nobody here wrote: scikit-image's filtered back-projection of a
parallel-beam sinogram of a fiber bundle against the bundle's exact cross section."""

import json

import numpy as np
import pytest

import gencyl

skimage_transform = pytest.importorskip("skimage.transform")
tifffile = pytest.importorskip("tifffile")

# The slice: 129 detector columns (odd, so that the detector's centre column lies on the
# rotation axis as it does in scikit-image's radon/iradon), 180 views over 180 degrees.
COLUMNS = 129
PIXEL = 1.0 / 128
VIEWS = 180


def bundle(seed=3, n=14):
    """Straight elliptical fibers along z, disjoint, inside a disc of radius 0.42: (x, y,
    major, minor, angle) each, the major axis at `angle` from x toward y."""
    rng = np.random.default_rng(seed)
    fibers = []
    while len(fibers) < n:
        a = rng.uniform(0.035, 0.055)
        b = a * rng.uniform(0.6, 1.0)
        r = rng.uniform(0.0, 0.42 - a)
        phi = rng.uniform(0, 2 * np.pi)
        x, y = r * np.cos(phi), r * np.sin(phi)
        if all(np.hypot(x - f[0], y - f[1]) > a + f[2] + 0.01 for f in fibers):
            fibers.append(tuple(float(v) for v in (x, y, a, b, rng.uniform(0, np.pi))))
    return fibers


def scene_text(fibers, ct):
    out = ['[material.glass]\ntype = "dielectric"\nxray_mu = 1.0\n']
    for x, y, a, b, angle in fibers:
        out.append(
            f"[[cylinder]]\nbezier = [[{x!r}, {y!r}, -1], [{x!r}, {y!r}, -0.3], "
            f"[{x!r}, {y!r}, 0.3], [{x!r}, {y!r}, 1]]\n"
            f"major_radius = [{a!r}, {a!r}]\nminor_radius = [{b!r}, {b!r}]\n"
            f"rotation = [{angle!r}, {angle!r}]\nnormal_hint = [1, 0, 0]\nmaterial = \"glass\"\n"
        )
    out.append("[ct]\n" + ct)
    return "\n".join(out)


def inside(fibers, x, y):
    """The exact cross section at z = 0: which points lie in a fiber (the straight axis' normal
    is x, so a section's major axis is at its angle from x toward y)."""
    mask = np.zeros(np.broadcast(x, y).shape, dtype=bool)
    for fx, fy, a, b, angle in fibers:
        c, s = np.cos(angle), np.sin(angle)
        dx, dy = x - fx, y - fy
        p, q = c * dx + s * dy, -s * dx + c * dy
        mask |= (p / a) ** 2 + (q / b) ** 2 <= 1.0
    return mask


@pytest.fixture(scope="module")
def slice_scan(tmp_path_factory):
    fibers = bundle()
    ct = (
        f'beam = "parallel"\ndetector = [{COLUMNS}, 1]\npixel = [{PIXEL!r}, {PIXEL!r}]\n'
        f'views = {VIEWS}\narc = 180\nsamples = 4\nquantity = "absorbance"\n'
    )
    path = tmp_path_factory.mktemp("ct") / "bundle.toml"
    path.write_text(scene_text(fibers, ct))
    projections, geometry = gencyl.ct(str(path))
    return fibers, path, projections, geometry


def test_filtered_back_projection_recovers_the_bundle(slice_scan):
    fibers, _, projections, geometry = slice_scan
    assert projections.shape == (VIEWS, 1, COLUMNS) and projections.dtype == np.float32
    assert geometry["type"] == "parallel3d_vec" and len(geometry["vectors"]) == VIEWS
    # scikit-image's sinogram: detector position by angle, in pixel units of path length.
    sinogram = projections[:, 0, :].T.astype(np.float64) / PIXEL
    theta = np.arange(VIEWS) * 180.0 / VIEWS
    recon = skimage_transform.iradon(sinogram, theta=theta, filter_name="ramp", circle=True)
    n = recon.shape[0]
    assert n == COLUMNS
    # radon's projection at angle a of the image point (column X, row Y) from the centre is
    # X cos a - Y sin a (it warps the image by the rotation and sums rows); gencyl's view at
    # a projects world (x, y) to x cos a + y sin a along u = (cos a, sin a, 0). So image
    # column X is x and row Y is -y, in units of the pixel, about the centre pixel n // 2.
    idx = np.arange(n) - n // 2
    x = idx[None, :] * PIXEL
    y = -idx[:, None] * PIXEL
    truth = inside(fibers, x, y)
    disc = idx[None, :] ** 2 + idx[:, None] ** 2 <= (n // 2) ** 2
    # mu = 1: fiber pixels reconstruct near 1, background near 0.
    fiber = recon > 0.5
    dice = 2 * np.sum(fiber & truth & disc) / (np.sum(fiber & disc) + np.sum(truth & disc))
    # Exact fiber area fraction of the disc (pi a b each) against the reconstruction's.
    area = sum(np.pi * a * b for _, _, a, b, _ in fibers)
    exact = area / (np.pi * ((n // 2) * PIXEL) ** 2)
    measured = np.sum(fiber & disc) / np.sum(disc)
    print(f"Dice {dice:.4f}, fiber fraction {measured:.4f} vs exact {exact:.4f}")
    smallest = 2 * min(b for _, _, _, b, _ in fibers) / PIXEL
    assert smallest >= 6, f"fibers at least 6 pixels across: {smallest:.1f}"
    assert dice >= 0.9, dice
    assert abs(measured - exact) <= 0.02, (measured, exact)
    # A scan of another bundle reconstructs to it, not to this one (the check can fail).
    other = inside(bundle(seed=11), x, y)
    wrong = 2 * np.sum(fiber & other & disc) / (np.sum(fiber & disc) + np.sum(other & disc))
    assert wrong < 0.5, wrong


def test_python_equals_the_command_line_bit_for_bit(slice_scan, gencyl_cli, tmp_path):
    _, path, projections, geometry = slice_scan
    out = tmp_path / "p.tif"
    gencyl_cli("ct", path, "-o", out, "-q", "--views", "20..50")
    pages = tifffile.imread(out)
    assert pages.shape == (30, 1, COLUMNS) and pages.dtype == np.float32
    assert np.array_equal(pages.view(np.uint32), projections[20:50].view(np.uint32))
    sidecar = json.loads(out.with_suffix(".json").read_text())
    assert sidecar["vectors"] == geometry["vectors"][20:50]
    part, g = gencyl.ct(str(path), views=(20, 50))
    assert np.array_equal(part.view(np.uint32), pages.view(np.uint32))
    assert g["views"] == [20, 50]


def test_quantities_and_errors(slice_scan):
    _, path, projections, _ = slice_scan
    scene = gencyl.Scene.load(str(path))
    length, _ = gencyl.ct(scene, views=(0, 10), quantity="length", material="glass")
    transmission, _ = gencyl.ct(scene, views=(0, 10), quantity="transmission")
    # mu = 1: absorbance is the path length (one ray's or the pixel's alike only where the
    # pixel's rays agree; in general -ln mean exp(-L) <= mean L).
    assert np.all(projections[:10] <= length * (1 + 1e-6) + 1e-7)
    assert np.allclose(transmission, np.exp(-projections[:10]), rtol=1e-6, atol=1e-7)
    assert scene.ct_geometry()["total_views"] == VIEWS
    with pytest.raises(ValueError, match=r"views = \(5, 5\)"):
        gencyl.ct(scene, views=(5, 5))
    with pytest.raises(ValueError, match="unknown quantity `dose`"):
        gencyl.ct(scene, quantity="dose")
    with pytest.raises(ValueError, match="material applies to the length quantity only"):
        gencyl.ct(scene, material="glass")
    plain = gencyl.Scene.from_cylinders(
        np.array([[[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]]], dtype=np.float64),
        np.array([[0.1, 0.1]]),
    )
    with pytest.raises(ValueError, match="has no \\[ct\\] table"):
        gencyl.ct(plain)


def test_phantom_and_labels(tmp_path):
    scene_toml, truth = gencyl.phantom("yarn", fibers=12, radius=0.02, packing=0.4, twist_deg=15, seed=4)
    assert truth["fiber_count"] == 12
    assert abs(truth["fiber_volume_fraction"] - 0.4) < 1e-6
    path = tmp_path / "yarn.toml"
    path.write_text(scene_toml)
    scene = gencyl.Scene.load(str(path))
    assert scene.ct_geometry()["type"] == "parallel3d_vec"
    # Voxel labels against the truth's volume: the labelled fraction of a thin slab of voxels
    # through the yarn's middle approaches the fiber area fraction there (a coarse check; the
    # exact comparison is the Rust test of the label volume).
    r = truth["envelope"]["radius"]
    v = r / 60
    n = int(2.2 * r / v)
    labels = scene.labels(origin=(-n * v / 2, -n * v / 2, 0.5 - 2 * v), voxel=v, size=(n, n, 4))
    assert labels.shape == (4, n, n) and labels.dtype == np.uint32
    fraction = np.count_nonzero(labels) * v**3 / (np.pi * r * r * 4 * v)
    assert abs(fraction - truth["fiber_volume_fraction"]) < 0.03, fraction
    # Cylinder numbers + 1: the strands' segments, within range.
    assert labels.max() <= len(scene)
    ply_toml, ply = gencyl.phantom("ply", fibers=30, seed=2)
    assert ply["fiber_count"] == 30 and "[ct]" in ply_toml
    with pytest.raises(ValueError, match="packing"):
        gencyl.phantom("yarn", fibers=100, packing=0.95)
    with pytest.raises(ValueError, match="unknown field"):
        gencyl.phantom("yarn", fibres=3)
    with pytest.raises(ValueError, match="unknown phantom"):
        gencyl.phantom("rope")
    with pytest.raises(ValueError, match="voxel"):
        scene.labels(origin=(0, 0, 0), voxel=-1.0, size=(2, 2, 2))
