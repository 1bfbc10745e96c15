"""The command line: exit statuses, error lines, help, fast start."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from microsim import __version__
from microsim.cli import COMMANDS, build_parser, main

ROOT = Path(__file__).resolve().parent.parent
RECIPE = str(ROOT / "surfaces" / "gaussian-0.3.toml")
HEAVY = ("embreex", "pyvista", "vtk", "matplotlib", "OpenEXR", "trimesh", "scipy", "dask",
         "numba", "llvmlite")



def test_version(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out.strip() == f"microsim {__version__}"


def test_every_command_has_complete_help(capsys):
    for name in COMMANDS:
        with pytest.raises(SystemExit) as info:
            main([name, "--help"])
        assert info.value.code == 0
        text = capsys.readouterr().out
        assert text.startswith("usage: microsim " + name), name
        assert len(text.splitlines()) > 3, name


def test_check_prints_resolved_recipe(cli):
    code, out, err = cli("check", RECIPE, "--set", "surface.alpha=0.5", "--json")
    assert code == 0 and err == ""
    resolved = json.loads(out)
    assert resolved["surface"]["alpha"] == 0.5
    assert resolved["table"]["theta_bins"] >= 1


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["check", "no/such/file.toml"], "no such file"),
        (["check", RECIPE, "--set", "surface.alpah=0.3"], "did you mean 'alpha'"),
        (["check", RECIPE, "--set", "simulation.rays=-3"], "simulation.rays = -3"),
        (["check", RECIPE, "--set", "surface.alpha=nan"], "surface.alpha = nan"),
        (["check", RECIPE, "--set", "oops"], "must be section.key=value"),
        (["check"], "the following arguments are required: RECIPE"),
        (["nosuchcommand"], "invalid choice"),
        (["check", RECIPE, "--bogus"], "unrecognized arguments: --bogus"),
    ],
)
def test_bad_input_is_one_error_line_and_exit_2(cli, argv, needle):
    code, out, err = cli(*argv)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("error: ") and needle in lines[0]
    assert "Traceback" not in err


def test_parser_and_check_import_nothing_heavy():
    """`microsim --help` and `microsim check` must start fast: no Embree, PyVista, ..."""
    code = (
        "import sys\n"
        "from microsim.cli import main\n"
        f"main(['check', {RECIPE!r}])\n"
        "print(sorted({m.split('.')[0] for m in sys.modules} & set(" + repr(HEAVY) + ")))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip().splitlines()[-1] == "[]"


def test_console_script_runs():
    out = subprocess.run([sys.executable, "-m", "microsim.cli", "--version"],
                         capture_output=True, text=True, check=True).stdout
    assert __version__ in out


def test_parser_builds():
    assert build_parser().prog == "microsim"
