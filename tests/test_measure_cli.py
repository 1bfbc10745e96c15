"""`microsim measure g1` and `microsim measure ndf` from the command line."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
RECIPE = str(ROOT / "surfaces" / "gaussian-0.3.toml")



def test_g1_json_against_smith(cli):
    """G1 of 4 realisations of the default 256² α = 0.3 tile (32 correlation lengths) at
    80° with 40k rays: the ensemble's stderr ≈ 0.002 (3 degrees of freedom); such tiles
    follow Smith to ~0.005 (docs/conventions.md), so |G1 − Smith| < 0.005 + 4 stderr. (A
    128² tile, 16 correlation lengths, misses by 0.012: too few independent slopes; the generator
    warns about it.)"""
    code, out, _ = cli("measure", "g1", RECIPE, "--theta", "0,80", "--rays", "40000",
                       "--realisations", "4", "--json")
    assert code == 0
    r = json.loads(out)
    assert set(r) >= {"theta", "g1", "g1_stderr", "smith", "alpha_realised"}
    assert r["theta"] == [0.0, 80.0] and r["g1"][0] == 1.0
    assert abs(r["g1"][1] - r["smith"][1]) < 0.005 + 4 * r["g1_stderr"][1]


def test_ndf_json_and_plot(cli, tmp_path):
    plot = tmp_path / "ndf.png"
    code, out, _ = cli("measure", "ndf", RECIPE, "--set", "surface.resolution=128",
                       "--bins", "12", "--plot", str(plot), "--json")
    assert code == 0
    r = json.loads(out)
    assert len(r["D"]) == len(r["beckmann"]) == 12
    assert plot.stat().st_size > 10_000


@pytest.mark.parametrize(("argv", "needle"), [
    (["measure", "g1", RECIPE, "--theta", "95"], "[0, 90]"),
    (["measure", "g1", RECIPE, "--theta", "a,b"], "--theta"),
    (["measure", "g1", RECIPE, "--rays", "0"], "--rays"),
    (["measure", "g1", RECIPE, "--phi", "nan"], "--phi"),
    (["measure", "ndf", RECIPE, "--bins", "-2"], "--bins"),
    (["measure"], "required"),
])
def test_bad_flags(cli, argv, needle):
    code, _, err = cli(*argv)
    assert code == 2 and err.startswith("error: ") and needle in err


def test_g1_of_a_refracting_layer_warns(cli):
    """G1 samples every face, so for a paint layer it also counts faces inside the binder:
    the command says so (and still measures)."""
    paint = str(ROOT / "surfaces" / "paint.toml")
    code, out, err = cli("measure", "g1", paint, "--theta", "30", "--rays", "500",
                         "--set", "surface.top_alpha=0", "--json")
    assert code == 0 and json.loads(out)["theta"] == [30.0]
    assert err.startswith("warning: part 'binder' refracts")
