"""`microsim models` and the model registry."""

from __future__ import annotations

import json
import math

import pytest

from microsim.analytic.registry import MODELS, parse_model_spec
from microsim.errors import InputError
from microsim.geometry import direction


def test_list_names_every_model(cli):
    code, out, _ = cli("models", "--json")
    assert code == 0
    listed = json.loads(out)
    assert set(listed) == set(MODELS)
    assert listed["beckmann"]["params"]["alpha"]["default"] == 0.3


def test_eval_prints_f_r(cli):
    """Mirror configuration of Beckmann α = 0.3 at 30°: h = n, so f = D(n) G2 / (4 cos²30°)
    with D(n) = 1/(π α²) and G2 = 1/(1 + 2Λ), Λ(a = 1/(0.3 tan 30°) = 5.77) < 1e-15."""
    code, out, _ = cli("models", "eval", "beckmann:alpha=0.3", "--wi", "30,0",
                       "--wo", "30,180", "--json")
    assert code == 0
    expected = 1 / (math.pi * 0.09) / (4 * math.cos(math.radians(30)) ** 2)
    assert json.loads(out)["f_r"] == pytest.approx(expected, rel=1e-12)


def test_param_flag_equals_spec(cli):
    _, a, _ = cli("models", "eval", "oren-nayar", "--param", "sigma=30", "--wi",
                  "40,0", "--wo", "20,90", "--json")
    _, b, _ = cli("models", "eval", "oren-nayar:sigma=30", "--wi", "40,0", "--wo",
                  "20,90", "--json")
    assert json.loads(a)["f_r"] == json.loads(b)["f_r"]


@pytest.mark.parametrize(("argv", "needle"), [
    (["models", "eval", "beckman", "--wi", "0,0", "--wo", "0,0"], "did you mean 'beckmann'"),
    (["models", "eval", "beckmann:alpah=0.3", "--wi", "0,0", "--wo", "0,0"], "did you mean 'alpha'"),
    (["models", "eval", "beckmann:alpha=-1", "--wi", "0,0", "--wo", "0,0"], "alpha = -1"),
    (["models", "eval", "beckmann:alpha=nan", "--wi", "0,0", "--wo", "0,0"], "alpha = nan"),
    (["models", "eval", "ggx:alpha_x=0.2", "--wi", "0,0", "--wo", "0,0"], "alpha_x and alpha_y"),
    (["models", "eval", "ggx", "--wi", "30", "--wo", "0,0"], "THETA,PHI"),
    (["models", "eval", "ggx", "--wi", "nan,0", "--wo", "0,0"], "THETA,PHI"),
    (["models", "eval", "ggx", "--wi", "0,0"], "--wo"),
    (["models", "eval", "ggx", "--param", "alpha", "--wi", "0,0", "--wo", "0,0"], "KEY=VALUE"),
])
def test_bad_input_exits_2_with_one_line(cli, argv, needle):
    code, _, err = cli(*argv)
    assert code == 2
    assert err.startswith("error: ") and err.count("\n") == 1 and needle in err


def test_every_model_builds_with_defaults_and_evaluates_finite():
    wi, wo = direction(0.4, 0.0), direction(0.7, 2.0)
    for name in MODELS:
        _, params, model = parse_model_spec(name)
        f = model.eval(wi, wo)
        assert math.isfinite(float(f if f.ndim == 0 else f.max())), name


def test_defaults_fill_only_keys_the_model_has():
    _, params, _ = parse_model_spec("beckmann", {"alpha": 0.25, "sigma": 3.0})
    assert params["alpha"] == 0.25 and "sigma" not in params
    _, params, _ = parse_model_spec("beckmann:alpha_x=0.1,alpha_y=0.2", {"alpha": 0.25})
    assert "alpha" not in params


def test_bad_spec_raises_input_error():
    with pytest.raises(InputError, match="must be key=value"):
        parse_model_spec("ggx:alpha")
