"""The package against the command line (same rows, same pixels), against closed forms, and
on bad input."""

import _thread
import signal
import threading
import time

import numpy as np
import pytest

import gencyl
from conftest import REPO, hard_rays, read_hits, write_rays

DEFAULT = REPO / "examples" / "default.toml"
PONYTAIL = REPO / "examples" / "ponytail.toml"


def same_rows(got, want):
    """Equal row for row, every value; the CSV writes -0 as 0, so zeros of either sign match."""
    assert set(got) == {"ray", "t", "u", "v", "normal", "object", "part"}, set(got)
    for k in want:
        assert got[k].dtype == want[k].dtype, (k, got[k].dtype, want[k].dtype)
        assert got[k].shape == want[k].shape, (k, got[k].shape, want[k].shape)
        assert np.array_equal(got[k], want[k]), k
        if got[k].dtype.kind == "f":
            assert np.isfinite(got[k]).all(), k


@pytest.mark.parametrize("scene_file", [DEFAULT, PONYTAIL])
@pytest.mark.parametrize("all_hits", [False, True])
def test_raycast_equals_the_command_line(tmp_path, gencyl_cli, scene_file, all_hits):
    scene = gencyl.Scene.load(scene_file)
    origins, directions = hard_rays(scene.bounds, 3000, seed=len(str(scene_file)))
    # Origins on the surface: the first hits of some rays, cast again from there.
    first = scene.raycast(origins[:300], directions[:300])
    on = first["ray"]
    o2 = origins[on] + first["t"][:, None] * directions[on]
    origins = np.concatenate([origins, o2])
    directions = np.concatenate([directions, directions[on]])
    rays = tmp_path / "rays.csv"
    write_rays(rays, origins, directions)
    args = ["raycast", scene_file, rays] + (["--all"] if all_hits else [])
    want = read_hits(gencyl_cli(*args).stdout)
    got = scene.raycast(origins, directions, all=all_hits)
    assert len(got["t"]) > 500, "the rays hit the scene"
    same_rows(got, want)
    # The thread count changes nothing.
    same_rows(scene.raycast(origins, directions, all=all_hits, threads=1), want)


def test_tmin_equals_the_command_line(tmp_path, gencyl_cli):
    scene = gencyl.Scene.load(DEFAULT)
    origins, directions = hard_rays(scene.bounds, 500, seed=3)
    rays = tmp_path / "rays.csv"
    write_rays(rays, origins, directions)
    want = read_hits(gencyl_cli("raycast", DEFAULT, rays, "--all", "--tmin", "1.5").stdout)
    same_rows(scene.raycast(origins, directions, tmin=1.5, all=True), want)
    assert (want["t"] > 1.5).all()


def cylinder_table(b, a, bmin, rot, hint):
    f = lambda v: "[" + ", ".join(repr(float(x)) for x in v) + "]"
    return (
        "[[cylinder]]\n"
        f"bezier = [{', '.join(f(p) for p in b)}]\n"
        f"major_radius = {f(a)}\nminor_radius = {f(bmin)}\nrotation = {f(rot)}\nnormal_hint = {f(hint)}\n"
    )


def test_from_cylinders_equals_the_same_tables(tmp_path):
    rng = np.random.default_rng(7)
    n = 40
    start = rng.uniform(-1, 1, (n, 1, 3))
    bezier = start + np.cumsum(rng.uniform(-0.3, 0.3, (n, 4, 3)), axis=1)
    major = rng.uniform(0.01, 0.05, (n, 2))
    minor = major * rng.uniform(0.3, 1.0, (n, 2))
    rotation = rng.uniform(-3, 3, (n, 2))
    hint = rng.normal(size=(n, 3))
    scene = gencyl.Scene.from_cylinders(bezier, major, minor, rotation, normal_hint=hint)
    path = tmp_path / "c.toml"
    path.write_text("".join(cylinder_table(*x) for x in zip(bezier, major, minor, rotation, hint)))
    twin = gencyl.Scene.load(path)
    assert len(scene) == len(twin) == n
    assert np.array_equal(scene.bounds, twin.bounds)
    origins, directions = hard_rays(scene.bounds, 4000, seed=8)
    a = scene.raycast(origins, directions, all=True)
    assert len(a["t"]) > 200
    same_rows(a, twin.raycast(origins, directions, all=True))


def test_from_strands_equals_the_same_tables(tmp_path):
    rng = np.random.default_rng(9)
    strands = [np.cumsum(rng.uniform(-0.2, 0.2, (k, 3)) + [0, 0.3, 0], axis=0) for k in (2, 3, 6, 11)]
    scene = gencyl.Scene.from_strands(strands, radius=(0.03, 0.01), ellipticity=0.6, twist=(0.0, 2.0))
    f = lambda p: "[" + ", ".join(repr(float(x)) for x in p) + "]"
    text = "".join(
        f"[[strand]]\npoints = [{', '.join(f(p) for p in s)}]\nradius = [0.03, 0.01]\n"
        "ellipticity = 0.6\ntwist = [0.0, 2.0]\n"
        for s in strands
    )
    path = tmp_path / "s.toml"
    path.write_text(text)
    twin = gencyl.Scene.load(path)
    assert len(scene) == len(twin) == 1 + 2 + 5 + 10, "a segment between each pair of points"
    origins, directions = hard_rays(scene.bounds, 3000, seed=10)
    a = scene.raycast(origins, directions)
    assert len(a["t"]) > 100
    same_rows(a, twin.raycast(origins, directions))


def test_xray_lengths_are_chords_of_a_round_fiber():
    # A straight round fiber of radius r along x: a ray across the axis at offset b crosses
    # a chord of 2 sqrt(r^2 - b^2); grazing offsets down to 1e-9 of r below the radius.
    r = 0.1
    bezier = np.array([[[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]]], dtype=np.float64)
    scene = gencyl.Scene.from_cylinders(bezier, np.array([[r, r]]))
    depth = np.concatenate([[0.0], 10.0 ** np.linspace(-9, 0, 40)]) * r
    b = r - depth
    origins = np.stack([np.full_like(b, 1.5), b, np.full_like(b, 1.0)], axis=1)
    directions = np.tile([0.0, 0.0, -1.0], (len(b), 1))
    out = gencyl.xray(scene, origins, directions)
    want = 2 * np.sqrt(np.maximum(r * r - b * b, 0.0))
    err = np.abs(out["length"] - want)
    # The chord's own rounding: d(chord)/db = -2b / chord grows as the ray grazes.
    tol = 1e-14 + 4e-16 * r * r / np.maximum(want, 1e-300)
    assert (err <= np.maximum(tol, 1e-12 * r)).all(), (err, want)
    assert np.isfinite(out["optical_depth"]).all()


def render_cli(gencyl_cli, tmp_path, *args):
    import OpenEXR

    out = tmp_path / "cli.exr"
    gencyl_cli("render", *args, "-o", out, "--quiet")
    with OpenEXR.File(str(out), separate_channels=True) as f:
        channels = f.channels()
        return {name: np.asarray(c.pixels) for name, c in channels.items()}


def test_render_equals_the_command_line(tmp_path, gencyl_cli):
    for integrator, extra in [("path", ["--spp", "2"]), ("depth", []), ("xray", ["--spp", "2"])]:
        want = render_cli(gencyl_cli, tmp_path, DEFAULT, "--width", "48", "--integrator", integrator, *extra)
        kw = {"spp": 2} if extra else {}
        image, channels = gencyl.render(DEFAULT, width=48, integrator=integrator, **kw)
        assert image.dtype == np.float32 and image.shape == (36, 48, len(channels)), image.shape
        want_channels = ["R", "G", "B", "A"] + {"depth": ["Z"], "xray": ["L"]}.get(integrator, [])
        assert channels == want_channels
        for k, c in enumerate(channels):
            a = image[:, :, k]
            b = want[c].astype(np.float32)
            assert np.array_equal(a.view(np.uint32), b.view(np.uint32)), (integrator, c)
        assert image[:, :, 3].max() > 0, "something is seen"


def test_render_crops_threads_and_settings():
    scene = gencyl.Scene.load(DEFAULT)
    assert scene.frame() == (400, 300, ["R", "G", "B", "A"]), "the scene's camera"
    assert scene.frame(width=80, integrator="depth") == (80, 60, ["R", "G", "B", "A", "Z"])
    full, _ = gencyl.render(scene, width=80, spp=2, threads=2)
    part, _ = gencyl.render(scene, width=80, spp=2, crop=(10, 7, 51, 33), threads=1)
    assert np.array_equal(part.view(np.uint32), full[7:33, 10:51].view(np.uint32))
    other, _ = gencyl.render(scene, width=80, spp=2, seed=2)
    assert not np.array_equal(other, full), "the seed changes the samples"


def test_render_releases_the_gil():
    scene = gencyl.Scene.load(DEFAULT)
    counts = []
    stop = threading.Event()

    def count():
        n = 0
        while not stop.is_set():
            n += 1
            if n % 1000 == 0:
                counts.append(time.perf_counter())

    t = threading.Thread(target=count)
    t.start()
    try:
        start = time.perf_counter()
        gencyl.render(scene, width=200, spp=4, threads=1)
        end = time.perf_counter()
    finally:
        stop.set()
        t.join()
    during = [c for c in counts if start < c < end]
    # Held GIL: the counter would run only at the band boundaries (a few times); released, it
    # runs all along.
    assert len(during) > 100, (len(during), end - start)


def test_ctrl_c_stops_a_render():
    scene = gencyl.Scene.load(DEFAULT)
    # Python's own Ctrl-C handler, whatever the process inherited: a shell starts background
    # jobs with SIGINT ignored, and then `interrupt_main` does nothing.
    inherited = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        timer = threading.Timer(0.3, _thread.interrupt_main)
        timer.start()
        start = time.perf_counter()
        with pytest.raises(KeyboardInterrupt):
            # About a minute of work: interrupted long before.
            gencyl.render(scene, width=400, spp=256, threads=1)
        timer.cancel()
        assert time.perf_counter() - start < 30
    finally:
        signal.signal(signal.SIGINT, inherited)


def test_scene_errors_are_the_command_lines(tmp_path, gencyl_cli):
    bad = tmp_path / "bad.toml"
    bad.write_text("[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, -0.1]\n")
    with pytest.raises(ValueError) as e:
        gencyl.Scene.load(bad)
    cli = gencyl_cli("render", bad, "-o", tmp_path / "x.png", check=False)
    assert cli.returncode != 0
    assert str(e.value) in cli.stderr, (str(e.value), cli.stderr)
    assert "bad.toml:3" in str(e.value) and "positive" in str(e.value)
    with pytest.raises(FileNotFoundError, match="missing.toml"):
        gencyl.Scene.load(tmp_path / "missing.toml")
    with pytest.raises(OSError, match="cannot read"):
        gencyl.Scene.load("/dev/zero")
    with pytest.raises(ValueError, match="syntax|expected|invalid"):
        (tmp_path / "syntax.toml").write_text("[[cylinder]\n")
        gencyl.Scene.load(tmp_path / "syntax.toml")
    with pytest.raises(ValueError, match="radius applies to .hair"):
        gencyl.Scene.load(DEFAULT, radius=0.1)
    with pytest.raises(ValueError, match="not a .hair|magic|HAIR|too short|hair"):
        (tmp_path / "x.hair").write_bytes(b"HAIR" + b"\xff" * 20)
        gencyl.Scene.load(tmp_path / "x.hair")


def test_bad_arrays_get_clear_errors():
    scene = gencyl.Scene.load(DEFAULT)
    o = np.zeros((4, 3))
    d = np.tile([0.0, 0.0, 1.0], (4, 1))
    cases = [
        ((o.astype(np.float32), d), TypeError, "origins must be a float64 array.*float32"),
        ((o.astype(np.int64), d), TypeError, "dtype int64"),
        ((o.tolist(), d), TypeError, "origins must be a numpy float64 array.*list"),
        ((o[:, :2], d), ValueError, r"origins must have shape \(N, 3\), got \[4, 2\]"),
        ((np.zeros((4, 3, 1)), d), ValueError, "origins must have shape"),
        ((o, d[:3]), ValueError, "origins has 4 rows and directions 3"),
        ((np.asfortranarray(np.zeros((4, 3))), d), ValueError, "origins must be C-contiguous"),
        ((np.zeros((3, 4)).T, d), ValueError, "C-contiguous"),
        ((o, np.zeros((4, 3))), ValueError, r"ray 0: the direction \(dx, dy, dz\) is zero"),
    ]
    nan = o.copy()
    nan[2, 1] = np.nan
    cases.append(((nan, d), ValueError, "ray 2: oy is not finite"))
    inf = d.copy()
    inf[3, 2] = np.inf
    cases.append(((o, inf), ValueError, "ray 3: dz is not finite"))
    for (origins, directions), exc, pattern in cases:
        with pytest.raises(exc, match=pattern):
            scene.raycast(origins, directions)
    with pytest.raises(ValueError, match="tmin must be a number"):
        scene.raycast(o, d, tmin=float("nan"))
    with pytest.raises(ValueError, match="threads"):
        scene.raycast(o, d, threads=0)
    # A C-contiguous array at an odd address (as rebuilt from a byte stream) is copied.
    raw = np.zeros(4 * 3 * 8 + 1, dtype=np.uint8)
    odd = np.frombuffer(raw.data, dtype=np.float64, count=12, offset=1).reshape(4, 3)
    assert not odd.flags.aligned and odd.flags.c_contiguous
    assert np.array_equal(scene.raycast(odd, d)["t"], scene.raycast(o, d)["t"])
    # Empty batches are fine.
    assert len(scene.raycast(np.zeros((0, 3)), np.zeros((0, 3)))["t"]) == 0


def test_bad_geometry_and_settings_get_clear_errors(tmp_path):
    bez = np.array([[[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]]] * 3, dtype=np.float64)
    ok = np.full((3, 2), 0.1)
    with pytest.raises(ValueError, match=r"cylinder 1: major_radius must be positive.*\(major_radius\)"):
        r = ok.copy()
        r[1, 0] = -1
        gencyl.Scene.from_cylinders(bez, r)
    with pytest.raises(ValueError, match=r"cylinder 2: bezier control point 3 is not finite"):
        b = bez.copy()
        b[2, 3, 0] = np.nan
        gencyl.Scene.from_cylinders(b, ok)
    with pytest.raises(ValueError, match="major_radius has 2 rows and bezier 3"):
        gencyl.Scene.from_cylinders(bez, ok[:2])
    with pytest.raises(ValueError, match=r"bezier must have shape \(N, 4, 3\)"):
        gencyl.Scene.from_cylinders(bez[:, :3], ok)
    with pytest.raises(ValueError, match="strand 1: point 1 repeats point 0"):
        gencyl.Scene.from_strands([np.eye(3), np.zeros((2, 3))], radius=0.1)
    with pytest.raises(ValueError, match="strand 0: a strand needs at least 2 points"):
        gencyl.Scene.from_strands([np.zeros((1, 3))], radius=0.1)
    with pytest.raises(ValueError, match=r"ellipticity must be in \(0, 1\]"):
        gencyl.Scene.from_strands([np.eye(3)], radius=0.1, ellipticity=1.5)
    with pytest.raises(ValueError, match="frame must be"):
        gencyl.Scene.from_strands([np.eye(3)], radius=0.1, frame="spiral")
    scene = gencyl.Scene.from_cylinders(bez, ok)
    with pytest.raises(ValueError, match="unknown integrator `fancy`"):
        gencyl.render(scene, integrator="fancy")
    with pytest.raises(ValueError, match=r"spp must be in 1..=1000000, got 0"):
        gencyl.render(scene, spp=0)
    with pytest.raises(ValueError, match="crop: crop window 0,0,700,10 reaches past the 640x480 frame"):
        gencyl.render(scene, crop=(0, 0, 700, 10))
    with pytest.raises(ValueError, match="crop: crop window 5,0,5,10 is empty"):
        gencyl.render(scene, crop=(5, 0, 5, 10))
    with pytest.raises(ValueError, match="more than the limit of 1000.*max_pixels"):
        gencyl.render(scene, max_pixels=1000)
    tall = tmp_path / "tall.toml"
    tall.write_text("[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\nresolution = [100, 400]\n")
    with pytest.raises(ValueError, match="width=65536: the height would be 262144 pixels"):
        gencyl.render(tall, width=65536)
    with pytest.raises(TypeError, match="scene must be a gencyl.Scene or the path"):
        gencyl.render(42)
    empty = gencyl.Scene.from_cylinders(np.zeros((0, 4, 3)), np.zeros((0, 2)))
    assert len(empty) == 0 and empty.bounds is None
    with pytest.warns(UserWarning, match="has no geometry"):
        gencyl.render(empty, width=8, spp=1)
