"""The notebook-style example runs from start to end."""

import pathlib
import runpy

import numpy as np

EXAMPLE = pathlib.Path(__file__).resolve().parents[2] / "examples" / "python" / "fibers.py"


def test_the_example_runs(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    runpy.run_path(str(EXAMPLE), run_name="__main__")
    out = capsys.readouterr().out
    assert "90000 rays" in out and "crossings per ray" in out
    image = np.load(tmp_path / "fibers.npy")
    assert image.shape == (120, 160, 4) and np.isfinite(image).all()


CT_EXAMPLE = EXAMPLE.parent / "ct_yarn.py"


def test_the_ct_example_reconstructs_its_yarn(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr("sys.argv", ["ct_yarn.py", str(tmp_path)])
    runpy.run_path(str(CT_EXAMPLE), run_name="__main__")
    out = capsys.readouterr().out
    dice = float(out.split("Dice ")[1].split(";")[0])
    assert dice >= 0.9, out
    assert (tmp_path / "ct-yarn.png").stat().st_size > 1000
