"""The Python API of docs/python.md: its example runs as written, and the functions at the
top of the package do what their commands do."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import microsim
from microsim.errors import InputError

DOC = Path(__file__).resolve().parent.parent / "docs" / "python.md"


def python_blocks() -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", DOC.read_text(encoding="utf-8"),
                      flags=re.S | re.M)


def test_the_documented_example_runs(tmp_path, monkeypatch, capsys):
    """Every python block of docs/python.md, in order, in a temporary folder: it prints
    what the doc shows it printing (the same seeds give the same numbers) and writes the
    files it says."""
    blocks = python_blocks()
    assert len(blocks) == 2
    monkeypatch.chdir(tmp_path)
    # as a fresh interpreter prints (a test that imported colour-science directly has set
    # numpy's legacy printing in this process)
    with np.printoptions(legacy=False):
        exec(compile(blocks[0], str(DOC), "exec"), {"__name__": "__docs__"})
    printed = capsys.readouterr().out.strip().splitlines()
    shown = re.search(r"What it printed once.*?```\n(.*?)```", DOC.read_text(encoding="utf-8"),
                      flags=re.S).group(1).strip().splitlines()
    assert printed == shown
    assert (tmp_path / "gaussian.exr").stat().st_size > 0
    assert (tmp_path / "gaussian.bsdf").stat().st_size > 0


def test_the_documented_surface_example_runs(capsys):
    """The second python block of docs/python.md (a surface record and its tile) prints
    what the doc shows after it."""
    exec(compile(python_blocks()[1], str(DOC), "exec"), {"__name__": "__docs__"})
    printed = capsys.readouterr().out.strip().splitlines()
    shown = re.search(r"It prints \(the realised .*?```\n(.*?)```",
                      DOC.read_text(encoding="utf-8"), flags=re.S).group(1).strip().splitlines()
    assert printed == shown


def test_a_dict_recipe_is_the_file_recipe(tmp_path):
    """A dict recipe resolves as the same TOML file does, overrides included, and the
    caller's dict is left as it was."""
    raw = {"surface": {"kind": "vgroove", "slope": 30}, "material": {"kind": "mirror"},
           "simulation": {"theta_i": [0, 30], "rays": 1000}}
    before = repr(raw)
    path = tmp_path / "r.toml"
    path.write_text('[surface]\nkind = "vgroove"\nslope = 30\n[material]\nkind = "mirror"\n'
                    '[simulation]\ntheta_i = [0, 30]\nrays = 1000\n', encoding="utf-8")
    a = microsim.load_recipe(raw, ["simulation.rays=2000"])
    b = microsim.load_recipe(path, ["simulation.rays=2000"])
    assert a.simulation == b.simulation and a.surface == b.surface
    assert a.simulation.rays == 2000 and repr(raw) == before
    with pytest.raises(InputError, match="slope"):
        microsim.load_recipe(raw, ["surface.slope=95"])


def test_model_is_the_registry_model_and_export_checks_the_format(tmp_path):
    """``model`` builds what the spec names (Torrance-Sparrow with Beckmann's α and
    height-correlated Smith masking, the registry's default); ``export`` writes the
    formats ``microsim export`` writes and refuses others."""
    from microsim.analytic.brdf import TorranceSparrow
    from microsim.analytic.ndf import Beckmann
    from microsim.comparison.metrics import model_table
    from microsim.tables.binning import HemisphereBins

    beckmann = microsim.model("beckmann:alpha=0.2")
    assert isinstance(beckmann, TorranceSparrow) and isinstance(beckmann.ndf, Beckmann)
    assert beckmann.ndf.alpha_x == beckmann.ndf.alpha_y == 0.2
    table = model_table(beckmann, np.radians([0.0, 40.0]), HemisphereBins(8, 16))
    with pytest.raises(ValueError, match="format"):
        microsim.export(table, tmp_path / "x.bsdf", format="bsdf")
    microsim.export(table, tmp_path / "x.npz", format="npz")
    assert (tmp_path / "x.npz").stat().st_size > 0


def test_no_api_function_is_shadowed_by_a_module():
    """Importing a submodule binds its name on the package: no API function may share a
    name with a module of the package (``compare`` and ``fit`` are modules)."""
    import importlib
    import pkgutil

    api = ["load_recipe", "simulate", "read_table", "write_table", "model", "compare_model",
           "fit_model", "export"]
    modules = {m.name for m in pkgutil.iter_modules(microsim.__path__)}
    assert not set(api) & modules
    for name in modules - {"__main__"}:
        importlib.import_module(f"microsim.{name}")
    assert all(callable(getattr(microsim, name)) and not isinstance(
        getattr(microsim, name), type(microsim)) for name in api)
