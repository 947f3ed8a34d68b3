"""The docstring examples run, and every public name has a docstring and a stub."""

import doctest
import pathlib

import gencyl
import gencyl.dask


def test_docstring_examples_run():
    for module in (gencyl, gencyl.dask):
        result = doctest.testmod(module, optionflags=doctest.ELLIPSIS)
        assert result.failed == 0, module
    assert doctest.testmod(gencyl).attempted >= 3


def test_public_names_are_documented_and_stubbed():
    stub = (pathlib.Path(__file__).parents[1] / "gencyl" / "_gencyl.pyi").read_text()
    for name in ["load", "from_cylinders", "from_strands", "bounds", "frame", "raycast", "xray"]:
        assert getattr(gencyl.Scene, name).__doc__, name
        assert f"def {name}(" in stub, name
    for f in (gencyl.render, gencyl.xray, gencyl.dask.render, gencyl.dask.raycast, gencyl.dask.submit_render):
        assert f.__doc__, f
