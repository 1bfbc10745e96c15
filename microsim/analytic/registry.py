"""Named analytic models with validated parameters: ``parse_model_spec("beckmann:alpha=0.3")``.

A spec is ``NAME`` or ``NAME:key=value,key=value``. Values are read as TOML (numbers,
``true``, strings); angles are degrees, as everywhere on the command line. Parameters are
validated with the recipe schema's rules (type, range, NaN refused), and a bad name or key
gets the list of valid ones and a did-you-mean.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from microsim.analytic.fresnel import ConductorFresnel, DielectricFresnel, Fresnel
from microsim.analytic.velvet_geometry import VELVET_GEOMETRY
from microsim.errors import InputError
from microsim.schema import Key, Toml, Value, check_section, parse_value, suggest


@dataclass(frozen=True)
class ModelSpec:
    """A model's name-level description: its parameters and how to build it."""

    doc: str
    params: dict[str, Key]
    build: Callable[[dict[str, Value]], Any]


def _facets(p: dict[str, Value], ndf_name: str) -> tuple[Any, Fresnel | None]:
    """The NDF and the Fresnel record of a microfacet spec."""
    from microsim.analytic import ndf as ndfs

    name = p.get("ndf", ndf_name)
    if name == "blinn":
        dist = ndfs.Blinn(p["n"])
    elif name == "gaussian":
        dist = ndfs.TorranceSparrowGaussian(p["c"])
    else:
        cls = ndfs.Beckmann if name == "beckmann" else ndfs.GGX
        dist = (cls(alpha_x=p["alpha_x"], alpha_y=p["alpha_y"])
                if "alpha_x" in p else cls(p["alpha"]))
    fresnel: Fresnel | None = None
    if "k" in p:
        fresnel = ConductorFresnel(np.asarray(p.get("eta", [1.5] * len(p["k"]))),
                                   np.asarray(p["k"]))
    elif "eta" in p:
        fresnel = DielectricFresnel(np.asarray(p["eta"]))
    return dist, fresnel


def _microfacet(ndf_name: str) -> Callable[[dict[str, Value]], Any]:
    def build(p: dict[str, Value]) -> Any:
        from microsim.analytic.brdf import TorranceSparrow

        dist, fresnel = _facets(p, ndf_name)
        return TorranceSparrow(dist, fresnel=fresnel, shadowing=p["shadowing"])

    return build


def _multiple(ndf_name: str) -> Callable[[dict[str, Value]], Any]:
    def build(p: dict[str, Value]) -> Any:
        from microsim.analytic.multiple_scattering import SmithMultipleScattering

        dist, fresnel = _facets(p, ndf_name)
        return SmithMultipleScattering(dist, fresnel, samples=p["samples"], seed=p["seed"])

    return build


def _check_alphas(p: dict[str, Value]) -> None:
    if ("alpha_x" in p) != ("alpha_y" in p):
        raise InputError("model: give both alpha_x and alpha_y, or alpha")


MODEL_ALPHA_MIN = 1e-4
"""Smallest roughness a model spec takes: the range the analytic models are tested in
(tests/test_analytic_*.py); far below, D overflows float64 near the peak."""
MICROFACET = {
    "alpha": Key("float", 0.3, "Roughness (Walter et al. 2007's alpha).", low=MODEL_ALPHA_MIN,
                 high=10.0),
    "alpha_x": Key("float", None, "Anisotropic roughness along x (with alpha_y).",
                   low=MODEL_ALPHA_MIN, high=10.0),
    "alpha_y": Key("float", None, "Anisotropic roughness along y (with alpha_x).",
                   low=MODEL_ALPHA_MIN, high=10.0),
    "shadowing": Key("str", "smith-correlated", "Masking-shadowing.",
                     choices=("smith-correlated", "smith-separable", "v-groove", "none")),
    "eta": Key("channels", None, "Fresnel: index of refraction, one value or one per colour "
               "channel (dielectric, or conductor with k). Without eta and k, F = 1.", low=0.0,
               low_open=True, high=100.0),
    "k": Key("channels", None, "Fresnel: conductor extinction coefficient, one value or "
             "one per channel.", low=0.0, high=100.0),
}

MULTIPLE = {
    **{k: v for k, v in MICROFACET.items() if k != "shadowing"},
    "samples": Key("int", 256, "Random walks per estimate: per direction pair, or per "
                   "bin when compared with a table (the error falls as 1/sqrt; about 2 µs a "
                   "walk, so the most, 10^7, is some 20 s a pair).", low=2, high=10**7),
    "seed": Key("int", 0, "Seed of the random walks.", low=0, high=2**63 - 1),
}


def _lambertian_facet(p: Mapping[str, Value]) -> Any:
    from microsim.analytic.brdf import Lambertian

    return Lambertian(p["albedo"])


CYLINDER_FACETS: dict[str, Callable[[Mapping[str, Value]], Any]] = {
    "mirror": lambda p: None,
    "conductor": lambda p: ConductorFresnel(np.asarray(p["eta"], float),
                                            np.asarray(p["k"], float)),
    "dielectric": lambda p: DielectricFresnel(np.asarray(p["eta"], float)),
    "lambertian": _lambertian_facet,
}
"""The ``cylinders`` model's facet kinds and the record each makes of a spec's
parameters (``CylinderArray``'s ``facet``)."""


MODELS: dict[str, ModelSpec] = {
    "beckmann": ModelSpec("Torrance-Sparrow with a Beckmann NDF.", MICROFACET,
                          _microfacet("beckmann")),
    "ggx": ModelSpec("Torrance-Sparrow with a GGX (Trowbridge-Reitz) NDF.", MICROFACET,
                     _microfacet("ggx")),
    "beckmann-ms": ModelSpec(
        "Every scattering order of a Smith microsurface with a Beckmann NDF (Heitz et al. "
        "2016's random walk; order 1 is Torrance-Sparrow with height-correlated Smith): "
        "Monte Carlo, each value with its standard error.", MULTIPLE, _multiple("beckmann")),
    "ggx-ms": ModelSpec(
        "Every scattering order of a Smith microsurface with a GGX NDF (Heitz et al. "
        "2016's random walk): Monte Carlo, each value with its standard error.", MULTIPLE,
        _multiple("ggx")),
    "torrance-sparrow": ModelSpec(
        "Torrance-Sparrow microfacet BRDF with a chosen NDF.",
        {**MICROFACET,
         "ndf": Key("str", "beckmann", "Distribution.",
                    choices=("beckmann", "ggx", "blinn", "gaussian")),
         "n": Key("float", 20.0, "Blinn exponent (ndf = blinn).", low=0.0, high=1e6),
         "c": Key("float", 3.0, "Gaussian width 1/c (ndf = gaussian).", low=0.0,
                  low_open=True, high=1e4)},
        _microfacet("beckmann")),
    "blinn": ModelSpec("Torrance-Sparrow with the normalised Blinn NDF (n+2)/(2 pi) cos^n.",
                       {**MICROFACET, "n": Key("float", 20.0, "Blinn exponent.", low=0.0,
                                               high=1e6)},
                       lambda p: _microfacet("blinn")({**p, "ndf": "blinn"})),
    "phong": ModelSpec(
        "Phong's lobe about the mirror direction, cos^n (normalised: (n+2)/(2 pi) cos^n).",
        {"n": Key("float", 10.0, "Exponent.", low=0.0, high=1e6),
         "normalized": Key("bool", True, "Energy-conserving normalisation.")},
        lambda p: _brdf("Phong")(p["n"], normalized=p["normalized"])),
    "blinn-phong": ModelSpec("Blinn-Phong half-vector lobe (n+2)/(8 pi) cos^n theta_h.",
                             {"n": Key("float", 10.0, "Exponent.", low=0.0, high=1e6)},
                             lambda p: _brdf("BlinnPhong")(p["n"])),
    "lambertian": ModelSpec("Lambert: albedo / pi.",
                            {"albedo": Key("channels", 0.8, "Albedo, one value or one per "
                                           "colour channel.", low=0.0, high=1.0)},
                            lambda p: _brdf("Lambertian")(p["albedo"])),
    "coated-lambertian": ModelSpec(
        "Lambertian substrate under a smooth dielectric layer, internal reflections "
        "summed (diffuse part; the specular F(theta_i) is a Dirac peak not evaluated).",
        {"albedo": Key("channels", 0.8, "Substrate albedo, one value or one per channel.", low=0.0,
                       high=1.0),
         "eta": Key("float", 1.5, "Index of the layer relative to air.", low=1.0,
                    low_open=True, high=10.0)},
        lambda p: _layered()(p["albedo"], p["eta"])),
    "oren-nayar": ModelSpec(
        "Oren-Nayar rough diffuse reflection (full model with interreflection, or the "
        "qualitative A/B model).",
        {"sigma": Key("float", 20.0, "Slope standard deviation.", unit="deg", low=0.0,
                      high=90.0),
         "albedo": Key("channels", 0.8, "Facet albedo, one value or one per channel.", low=0.0,
                       high=1.0),
         "model": Key("str", "full", "Variant.", choices=("full", "qualitative"))},
        lambda p: _brdf("OrenNayar")(math.radians(p["sigma"]), p["albedo"], p["model"])),
    "lafortune": ModelSpec(
        "One Lafortune lobe (Cx wx wx' + Cy wy wy' + Cz wz wz')^n.",
        {"cx": Key("float", -1.0, "Cx.", low=-1e6, high=1e6),
         "cy": Key("float", -1.0, "Cy.", low=-1e6, high=1e6),
         "cz": Key("float", 1.0, "Cz.", low=-1e6, high=1e6),
         "n": Key("float", 10.0, "Exponent.", low=0.0, high=1e6)},
        lambda p: _brdf("Lafortune")([(p["cx"], p["cy"], p["cz"], p["n"])])),
    "kay-kajiya": ModelSpec(
        "Kay-Kajiya fibre reflection L = kd sin(t, wi) + ks cos^n(theta_i - theta_o) "
        "(the fibre's radiance per unit irradiance); with coverage, the BRDF of a layer of "
        "parallel fibres, coverage L sin(t, wo) / (cos theta_i cos theta_o). Compared with "
        "a table, the tangent and coverage come from its surface (cylinders: along y, "
        "diameter / spacing) and kd = albedo / pi^2 from Lambertian fibres.",
        {"tangent_theta": Key("float", 90.0, "Fibre tangent polar angle.", unit="deg",
                              low=0.0, high=180.0),
         "tangent_phi": Key("float", 0.0, "Fibre tangent azimuth.", unit="deg", low=-360.0,
                            high=360.0),
         "kd": Key("float", 0.1, "Diffuse coefficient, 1/sr.", low=0.0, high=1e3),
         "ks": Key("float", 0.5, "Specular coefficient, 1/sr.", low=0.0, high=1e3),
         "n": Key("float", 20.0, "Specular exponent.", low=0.0, high=1e6),
         "coverage": Key("float", None, "Projected fibre area per unit area (diameter / "
                         "spacing): the layer BRDF; unset: L itself.", low=0.0,
                         low_open=True, high=1.0)},
        lambda p: _brdf("KayKajiya")(_tangent(p), p["kd"], p["ks"], p["n"],
                                     p.get("coverage"))),
    "cylinders": ModelSpec(
        "Exact single scattering of parallel cylinders along y on a base (the cylinders "
        "surface made smooth): specular cylinders reflect into the cone with Marschner et "
        "al. 2003's R-lobe distribution 1/4 cos(phi/2) and the exact Fresnel factor, "
        "Lambertian ones over their lit and seen arc; neighbours and base shadow exactly; "
        "a Lambertian base of albedo base_albedo (0: black).",
        {"radius": Key("float", 0.5, "Cylinder radius.", unit="length", low=0.0,
                       low_open=True),
         "spacing": Key("float", 1.0, "Distance between axes (>= 2 radius).",
                        unit="length", low=0.0, low_open=True),
         "sink": Key("float", 0.0, "Depth sunk into the base (< 2 radius).", unit="length",
                     low=0.0),
         "kind": Key("str", "mirror", "The cylinders' facet material.",
                     choices=tuple(CYLINDER_FACETS)),
         "eta": Key("channels", None, "Index of refraction (conductor, dielectric).", low=0.0,
                    low_open=True, high=100.0),
         "k": Key("channels", None, "Extinction coefficient (conductor).", low=0.0, high=100.0),
         "albedo": Key("channels", 0.8, "Albedo (lambertian).", low=0.0, high=1.0),
         "base_albedo": Key("channels", 0.0, "Albedo of a Lambertian base.", low=0.0, high=1.0)},
        lambda p: _cylinders(p)),
    "velvet-sparse": ModelSpec(
        "Single scattering of sparse velvet: Lambertian fibres (smooth cylinders with the "
        "velvet surface's pyramid tips) on a black base, no fibre shadowing another, "
        "averaged over the fibre axes by quadrature (Westin et al. 1992's velvet in the "
        "low-density limit).",
        {**VELVET_GEOMETRY,
         "kind": Key("str", "lambertian", "The fibres' facet material.",
                     choices=("lambertian",)),
         "albedo": Key("channels", 0.8, "The fibres' albedo.", low=0.0, high=1.0),
         "base_albedo": Key("channels", 0.0, "The base's albedo: must be 0 (the model's base "
                            "is black).", low=0.0, high=1.0)},
        lambda p: _velvet(p)),
    "microcylinder": ModelSpec(
        "Woven cloth: Sadeghi et al. 2013's microcylinder model (thread scattering with a "
        "Fresnel surface lobe and a volume lobe, shadowing-masking, two thread families "
        "with the weave's tangent curves), combined as layers of cylinders.",
        {"a_warp": Key("float", 0.8, "Coverage of the warp.", low=0.0, high=1.0),
         "a_weft": Key("float", 0.8, "Coverage of the weft.", low=0.0, high=1.0),
         "eta": Key("float", 1.5, "The threads' index of refraction.", low=1.0, low_open=True,
                    high=10.0),
         "gamma_s": Key("float", 10.0, "Width of the surface lobe.", unit="deg", low=0.01,
                        high=90.0),
         "gamma_v": Key("float", 20.0, "Width of the volume lobe.", unit="deg", low=0.01,
                        high=90.0),
         "kd": Key("float", 0.5, "Isotropic share of the volume scattering.", low=0.0,
                   high=1.0),
         "albedo_warp": Key("channels", 0.5, "Volume scale A of the warp.", low=0.0, high=5.0),
         "albedo_weft": Key("channels", 0.5, "Volume scale A of the weft.", low=0.0, high=5.0),
         "slope": Key("float", 0.0, "Largest slope of the yarns (pi crimp / spacing).",
                      low=0.0, high=100.0),
         "flat": Key("float", 0.0, "Share of the yarns' length that is flat.", low=0.0,
                     high=1.0)},
        lambda p: _cloth(p)),
}


def _cloth(p: Mapping[str, Value]) -> Any:
    from microsim.analytic.brdf import rgb
    from microsim.analytic.cloth import MicrocylinderCloth

    albedo = np.stack([rgb(p[f"albedo_{part}"], f"albedo_{part}") for part in ("warp", "weft")])
    return MicrocylinderCloth([p["a_warp"], p["a_weft"]], p["eta"],
                              math.radians(p["gamma_s"]), math.radians(p["gamma_v"]),
                              p["kd"], albedo, p["slope"], p["flat"])


def _velvet(p: Mapping[str, Value]) -> Any:
    from microsim.analytic.velvet import SparseVelvet

    if np.any(np.asarray(p["base_albedo"]) > 0):  # one value or three
        raise InputError(f"model velvet-sparse: base_albedo = {p['base_albedo']}: the model "
                         "needs a black base (base_albedo = 0); simulate the velvet on one "
                         "with --set material.base.kind=black")

    return SparseVelvet(p["fibre_radius"], p["fibre_length"], p["density"], p["tilt"],
                        p["tilt_spread"], p["azimuth"], p["azimuth_spread"], p["albedo"],
                        sides=p["sides"])


def _cylinders(p: Mapping[str, Value]) -> Any:
    from microsim.analytic.cylinders import CylinderArray

    need = {"conductor": ("eta", "k"), "dielectric": ("eta",)}.get(p["kind"], ())
    missing = [k for k in need if p.get(k) is None]
    if missing:
        raise InputError(f"model cylinders: kind = {p['kind']} needs " + " and ".join(missing))
    if not (p["spacing"] >= 2 * p["radius"] and p["sink"] < 2 * p["radius"]):
        raise InputError("model cylinders: need spacing >= 2 radius and sink < 2 radius")
    return CylinderArray(p["radius"], p["spacing"], p["sink"], CYLINDER_FACETS[p["kind"]](p),
                         p["base_albedo"])


def _brdf(name: str) -> Any:
    from microsim.analytic import brdf

    return getattr(brdf, name)


def _layered() -> Any:
    from microsim.analytic.layered import CoatedLambertian

    return CoatedLambertian


def _tangent(p: Mapping[str, Value]) -> list[float]:
    t, f = math.radians(p["tangent_theta"]), math.radians(p["tangent_phi"])
    return [math.sin(t) * math.cos(f), math.sin(t) * math.sin(f), math.cos(t)]


def split_spec(spec: str, what: str) -> tuple[str, dict[str, Toml]]:
    """``NAME[:key=value,...]`` to the name and its values read as TOML (unchecked); a
    list value keeps its commas, as in ``eta=[0.2,0.9,1.1]``.

    Parameters
    ----------
    spec : str
    what : str
        How errors name the spec, e.g. ``"model"`` or ``"--light"``.
    """
    name, _, rest = spec.strip().partition(":")
    given: dict[str, Toml] = {}
    for item in filter(None, (s.strip() for s in re.split(r",(?![^\[]*\])", rest))):
        key, eq, value = item.partition("=")
        if not eq:
            raise InputError(f"{what} {name}: {item!r} must be key=value")
        if key.strip() in given:
            raise InputError(f"{what} {name}: {key.strip()} given twice; give each key once")
        given[key.strip()] = parse_value(value, f"{what} {name}: {key.strip()}")
    return name, given


def _same_channels(name: str, raw: Mapping[str, Toml], params: dict[str, Value],
                   keys: Mapping[str, Key]) -> None:
    """Give a spec's colour parameters (kind ``channels``) one count of channels, in
    place: a number given alone (which ``check_section`` read as R, G, B) takes the length
    of the lists beside it; lists of different lengths are refused."""
    colour = [k for k in params if keys[k].kind == "channels"]
    lists = {k: len(raw[k]) for k in colour if isinstance(raw.get(k), list)}
    if len(set(lists.values())) > 1:
        raise InputError(f"model {name}: " + ", ".join(f"{k} has {n} values"
                                                       for k, n in lists.items())
                         + "; give each colour parameter one number or one per channel, "
                         "as many for each")
    if lists:
        count = next(iter(lists.values()))
        for k in colour:
            if k not in lists:  # one number: as given, or as check_section's R, G, B
                value = params[k]
                params[k] = [value[0] if isinstance(value, list) else value] * count


def parse_model_spec(spec: str, defaults: Mapping[str, Value] | None = None
                     ) -> tuple[str, dict[str, Value], Any]:
    """Build a model from ``NAME[:key=value,...]``.

    Parameters
    ----------
    spec : str
        E.g. ``"beckmann:alpha=0.31"``, ``"oren-nayar:sigma=20,model=qualitative"``.
    defaults : mapping, optional
        Values used for keys the spec does not give (e.g. a table's realised alpha); a
        ``microsim.comparison.table_models.ModelDefaults`` also holds keys for one model only
        (``for_model``).

    Returns
    -------
    name : str
    params : dict of str to Value
        Every parameter, resolved (``check_value``'s).
    model : object
        With ``eval(wi, wo)``.
    """
    name, given = split_spec(spec, "model")
    if name not in MODELS:
        raise InputError(f"model {name!r}: unknown{suggest(name, MODELS)}; models: "
                         + ", ".join(MODELS))
    keys = MODELS[name].params
    merged = {k: v for k, v in (defaults or {}).items() if k in keys}
    merged.update(getattr(defaults, "for_model", {}).get(name, {}))
    merged.update(given)
    if "alpha_x" in given or "alpha_y" in given:
        merged.pop("alpha", None)
    params = check_section(merged, keys, f"model {name}: ")
    _same_channels(name, merged, params, keys)
    if "alpha_x" in keys:
        _check_alphas(params)
        if "alpha_x" in params:
            del params["alpha"]  # its default does not apply to an anisotropic model
    return name, params, MODELS[name].build(params)


UNITS = {"deg": "°", "length": " (tile units)"}
"""How a key's unit is printed after its value (dimensionless: nothing)."""


def parameter_units(name: str) -> dict[str, str]:
    """The unit of each parameter of a model that has one, as printed after its value:
    the unit its model spec reads it in, so a printed value can be given back as it is
    (``--model oren-nayar:sigma=34.1``); an unknown name has none.

    Parameters
    ----------
    name : str
        A model's name.
    """
    keys = MODELS[name].params if name in MODELS else {}
    return {key: UNITS[k.unit] for key, k in keys.items() if k.unit in UNITS}


def parameter_sources(spec: str, params: Mapping[str, Value],
                      defaults: Mapping[str, Value] | None = None) -> dict[str, str]:
    """Where each resolved parameter of a spec came from: ``"given"`` (the spec),
    the source a ``ModelDefaults`` names (e.g. ``"the table's realised alpha"``), or
    ``"default"`` (the model's own).

    Parameters
    ----------
    spec : str
        The spec ``parse_model_spec`` read.
    params : mapping
        Its resolved parameters.
    defaults : mapping or None
        The defaults it was given.
    """
    name, given = split_spec(spec, "model")
    sources = getattr(defaults, "sources", {})
    special = getattr(defaults, "for_model", {}).get(name, {})
    out = {}
    for key in params:
        if key in given:
            out[key] = "given"
        elif key in special:
            out[key] = sources.get(f"{name}.{key}", "from the table")
        elif defaults is not None and key in defaults:
            out[key] = sources.get(key, "from the table")
        else:
            out[key] = "default"
    return out


def parameters_text(name: str, params: Mapping[str, Value], sources: Mapping[str, str]
                    ) -> str:
    """The parameters of a model as a command prints them, each with its unit and
    source: ``alpha 0.2983 (the table's realised alpha), sigma 20° (default)``.

    Parameters
    ----------
    name : str
        A model of ``MODELS``.
    params : mapping
        Its resolved parameters.
    sources : mapping of str to str
        ``parameter_sources``'s.
    """
    keys = MODELS[name].params

    def value(key: str) -> str:
        v = params[key]
        unit = UNITS.get(keys[key].unit, "") if key in keys else ""
        if isinstance(v, list | tuple):
            text = "[" + ", ".join(f"{x:.4g}" for x in v) + "]"
        elif isinstance(v, float):
            text = f"{v:.4g}"
        else:
            text = str(v)
        return text + unit

    return ", ".join(f"{k} {value(k)} ({sources.get(k, 'default')})" for k in params)
