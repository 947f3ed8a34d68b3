"""The goniometer from Python: the command line's table bit for bit, and its physics."""

import numpy as np
import pytest

import gencyl


def test_scatter_equals_the_command_line(gencyl_cli, tmp_path):
    args = dict(aspect=0.8, rotation=25.0, theta_i=12.0, rays=3000, bins=36, max_order=2, seed=5)
    got = gencyl.scatter(**args)
    assert got["values"].shape == (3, 36, 36)
    out = tmp_path / "s.csv"
    gencyl_cli(
        "scatter", "--aspect", 0.8, "--rotation", 25, "--theta-i", 12, "--rays", 3000,
        "--bins", 36, "--max-order", 2, "--seed", 5, "-o", out,
    )
    rows = np.loadtxt(out, delimiter=",", skiprows=1)
    assert rows.shape == (3 * 36 * 36, 4)
    assert np.array_equal(rows[:, 3], got["values"].ravel())
    assert np.array_equal(rows[:36 * 36:36, 1], got["theta_deg"])
    assert np.array_equal(rows[:36, 2], got["phi_deg"])
    # Without absorption the table holds all the power but the cut-off branches.
    assert abs(got["values"].sum() + got["lost"] - 1.0) < 1e-12 and got["lost"] < 1e-5


def test_scatter_profile_and_errors():
    # A Bezier-loop square with rounded corners (the scene format's profile points).
    square = np.array(
        [[1, 0], [1, 0.5], [1, 1], [0, 1], [-0.5, 1], [-1, 1], [-1, 0], [-1, -0.5], [-1, -1],
         [0, -1], [0.5, -1], [1, -1]], dtype=np.float64)
    got = gencyl.scatter(profile=square, theta_i=10.0, rays=1000, bins=18)
    assert got["hits"] > 900 and abs(got["values"].sum() + got["lost"] - 1.0) < 1e-12
    with pytest.raises(ValueError, match="eta must be"):
        gencyl.scatter(eta=0.5)
    with pytest.raises(ValueError, match="profile"):
        gencyl.scatter(profile=np.zeros((2, 2)))
