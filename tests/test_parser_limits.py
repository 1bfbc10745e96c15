"""Inputs past the parser's, Python's or the OS's limits are one ``error:`` line (exit 2),
never a traceback: TOML nested 5000 deep, integers of 5000 digits (in a recipe, a
``--set`` and a model spec), a model spec with a repeated key, ``microsim`` without a
command, an output name longer than the file system takes, stdout to a full device."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from test_robustness import GAUSSIAN, one_error_line

DIGITS = "9" * 5000


@pytest.mark.parametrize(("text", "needle"), [
    ("a = " + "[" * 5000 + "]" * 5000, "nested too deeply"),
    ('[surface]\nkind = "gaussian"\nalpha = ' + DIGITS, "4300 digits"),
])
def test_a_recipe_past_the_toml_limits_is_one_error_line(cli, tmp_path, text, needle):
    path = tmp_path / "r.toml"
    path.write_text(text, encoding="utf-8")
    code, _, err = cli("check", str(path))
    one_error_line(code, err, str(path), needle)


@pytest.mark.parametrize(("value", "needle"), [
    (DIGITS, "--set surface.alpha = 9999"),
    ("9" * 400, "surface.alpha = 9999"),  # an integer beyond float64, for a float key
    ("[" * 3000 + "]" * 3000, "--set surface.alpha"),
])
def test_a_set_value_past_the_limits_is_one_error_line(cli, value, needle):
    code, _, err = cli("check", GAUSSIAN, "--set", f"surface.alpha={value}")
    one_error_line(code, err, needle)


@pytest.mark.parametrize(("spec", "needle"), [
    ("beckmann:alpha=0.3,alpha=0.5", "alpha given twice"),
    (f"beckmann:alpha={DIGITS}", "model beckmann: alpha = 9999"),
    ("beckmann:alpha=" + "9" * 400, "alpha = 9999"),
])
def test_a_model_spec_past_the_limits_is_one_error_line(cli, spec, needle):
    code, _, err = cli("models", "eval", spec, "--wi", "0,0", "--wo", "30,180")
    one_error_line(code, err, needle)


def test_microsim_without_a_command_is_one_error_line(cli):
    code, _, err = cli()
    one_error_line(code, err, "a command is required", "simulate", "microsim --help")


def test_an_output_name_too_long_for_the_file_system_is_refused_before_the_work(cli, tmp_path):
    """255 bytes is the usual limit; the file is written under a temporary name about 25
    bytes longer first, so 240 bytes is already too long (found after the work, at the
    rename, before)."""
    name = "a" * 240 + ".npz"
    code, _, err = cli("export", str(tmp_path / "missing.exr"), "--format", "npz", "-o",
                       str(tmp_path / name))
    one_error_line(code, err, "--output", "a file name of 244 bytes")


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full")
@pytest.mark.parametrize("argv", [["check", GAUSSIAN], ["check", GAUSSIAN, "--json"]])
def test_stdout_to_a_full_device_is_one_error_line(argv):
    with open("/dev/full", "w") as full:
        done = subprocess.run([sys.executable, "-m", "microsim.cli", *argv], stdout=full,
                              stderr=subprocess.PIPE, text=True, timeout=120)
    one_error_line(done.returncode, done.stderr, "No space left on device")


def test_a_library_warning_is_one_line(cli, monkeypatch):
    """A warning of numpy, scipy or a library (here a UserWarning with a line break) is one
    ``warning:`` line naming its category and where it was raised, not Python's two lines
    with the source."""
    import warnings

    from microsim.commands import check

    def warn_then_check(args):
        warnings.warn("overflow in exp\nsecond line", UserWarning, stacklevel=1)
        return 0

    monkeypatch.setattr(check, "run", warn_then_check)
    code, _, err = cli("check", GAUSSIAN)
    assert code == 0
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("warning: UserWarning: overflow in exp"), err
    assert "test_parser_limits.py:" in lines[0]

