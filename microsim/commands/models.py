"""``microsim models``: list the analytic models, or evaluate one."""

from __future__ import annotations

import argparse

from microsim.commands.common import (
    Parser,
    add_direction_args,
    add_json_arg,
    print_json,
    readable,
)
from microsim.errors import InputError


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``models`` command and its ``eval`` sub-command."""
    p = sub.add_parser(
        "models",
        help="list the analytic BRDF models and their parameters, or evaluate one",
        description="List the analytic models (name, parameters with defaults and ranges; "
                    "angles in degrees). `microsim models eval SPEC --wi THETA,PHI --wo "
                    "THETA,PHI` prints f_r in 1/sr. SPEC is NAME or NAME:key=value,... "
                    "(see docs/models.md).",
    )
    add_json_arg(p)
    p.set_defaults(func=run_list)
    inner = p.add_subparsers(dest="models_command", metavar="eval", parser_class=Parser)
    e = inner.add_parser(
        "eval", help="evaluate a model's f_r (1/sr) at one direction pair",
        description="Evaluate f_r (1/sr, not times cos) of an analytic model. Directions "
                    "are THETA,PHI in degrees, pointing away from the surface: --wi "
                    "towards the light, --wo towards the viewer.")
    e.add_argument("spec", metavar="SPEC", help="model name or NAME:key=value,...")
    add_direction_args(e)
    e.add_argument("--param", action="append", default=[], metavar="KEY=VALUE",
                   help="model parameter (repeatable), e.g. --param alpha=0.3")
    add_json_arg(e)
    e.set_defaults(func=run_eval)


def run_list(args: argparse.Namespace) -> int:
    """Print every model with its parameters."""
    from microsim.analytic.registry import MODELS

    if args.json:
        print_json({name: {"doc": m.doc, "params": {
            k: {"kind": key.kind, "default": key.default, "allowed": key.allowed(),
                "doc": key.doc} for k, key in m.params.items()}}
            for name, m in MODELS.items()})
        return 0
    for name, m in MODELS.items():
        print(f"{name}: {m.doc}")
        for k, key in m.params.items():
            default = "optional" if key.default is None else f"default {key.default}"
            print(f"    {k:<14} {default}; {key.allowed()}")
    return 0


def run_eval(args: argparse.Namespace) -> int:
    """Evaluate one model at one direction pair."""
    import numpy as np

    from microsim.analytic.registry import (
        parameter_sources,
        parameter_units,
        parameters_text,
        parse_model_spec,
    )
    from microsim.comparison.metrics import check_model_channels, singular_albedo
    from microsim.geometry import direction

    spec = args.spec
    for item in args.param:
        if "=" not in item:
            raise InputError(f"--param {item!r}: must be KEY=VALUE")
        spec += ("," if ":" in spec else ":") + item
    check_model_channels(spec, None, None, "model")
    name, params, model = parse_model_spec(spec)
    wi = direction(*np.radians(args.wi))
    wo = direction(*np.radians(args.wo))
    estimate = getattr(model, "estimate", None)        # Monte Carlo models: with an error
    f, err = estimate(wi, wo) if estimate is not None else (model.eval(wi, wo), None)
    value = np.asarray(f, float).tolist()
    error = None if err is None else np.asarray(err, float).tolist()
    # a model with a singular part (mirror cylinders' cone) has a delta eval cannot give
    delta = singular_albedo(model, wi)
    sources = parameter_sources(spec, params)
    if args.json:
        print_json({"model": name, "params": params, "param_sources": sources,
                    "units": parameter_units(name), "wi": list(args.wi),
                    "wo": list(args.wo), "f_r": value, "singular_albedo": delta,
                    **({} if error is None else {"f_r_err": error})})
    else:
        spread = "" if error is None else f" ± {readable(error, 2)} (standard error)"
        print(f"{name}: {parameters_text(name, params, sources)}")
        print(f"f_r = {readable(value, 6)}{spread} 1/sr")
        if delta > 0:
            print(f"plus a singular part (a delta on the specular cone) reflecting "
                  f"{delta:.4g} of the incident power, which has no value at one "
                  "direction: compare and fit average it over table bins")
    return 0
