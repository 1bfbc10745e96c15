"""The command line: exit statuses, error lines, help, fast start."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from microsim import __version__
from microsim.cli import NAMES, build_parser, main

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
    for name in NAMES:
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


def test_importing_the_command_line_loads_nothing_heavy():
    """Before ``main`` runs, a Ctrl-C is a traceback: importing ``microsim.cli`` loads no
    command module and not numpy (about 0.2 s together), which ``main`` imports inside its
    guard, so a Ctrl-C while they load is ``error: interrupted`` and status 130."""
    code = ("import sys\nimport microsim.cli\n"
            "print(sorted(m for m in sys.modules if m == 'numpy' or "
            "m.startswith('microsim.commands')))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"


def test_console_script_runs():
    out = subprocess.run([sys.executable, "-m", "microsim.cli", "--version"],
                         capture_output=True, text=True, check=True).stdout
    assert __version__ in out


def test_parser_builds():
    assert build_parser().prog == "microsim"


def test_simulate_explains_its_ray_share_column(cli, tmp_path):
    """simulate's text report prints each direction's ray share as the whole percentage
    of its JSON ``ray_share`` and says why it may pass 100% (a ratio of two noisy
    variances: the tiles spread less than their rays' noise predicts); values of
    101-109% were printed unexplained."""
    recipe = Path(__file__).resolve().parent.parent / "surfaces" / "gaussian-0.3.toml"
    argv = ["simulate", str(recipe), "-o", str(tmp_path / "t.exr"), "--rays", "4000",
            "--realisations", "4", "--set", "surface.resolution=32", "--set",
            "simulation.theta_i=[0, 40]", "--set", "table.sh_order=0", "--set",
            "table.theta_bins=8", "--set", "table.phi_bins=16"]
    code, text, err = cli(*argv)
    assert code == 0, err
    assert ("above 100% where the tiles spread less than their rays' noise predicts, a "
            "ratio of two noisy variances") in " ".join(text.split())
    code, out, err = cli(*argv, "--json")
    assert code == 0, err
    shares = json.loads(out)["ray_share"]
    rows = [line.split() for line in text.splitlines() if line.split()[:1] in (["0.0"],
                                                                             ["40.0"])]
    assert [r[-2] for r in rows] == [f"{100 * s:.0f}%" for s in shares], (rows, shares)
