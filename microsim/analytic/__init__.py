"""Analytic BRDF models: the references every simulation is compared with.

The documented models (docs/models.md) are importable from here, e.g.
``from microsim.analytic import Beckmann, GGX, TorranceSparrow, fresnel_conductor``. They
load on first use (PEP 562), so that importing ``microsim.analytic.registry`` for a
command's ``--help`` stays light.
"""

from __future__ import annotations

import importlib
from typing import Any

_PUBLIC = {
    "ndf": ("Beckmann", "GGX", "Blinn", "TorranceSparrowGaussian", "lambda_beckmann",
            "lambda_ggx"),
    "shadowing": ("smith_g2", "vgroove_G", "vcavity_G1"),
    "fresnel": ("fresnel_dielectric", "fresnel_conductor", "fresnel_thin_film",
                "ConductorFresnel", "DielectricFresnel", "SchlickFresnel", "CoatedFresnel",
                "Fresnel"),
    "brdf": ("TorranceSparrow", "Phong", "BlinnPhong", "Lambertian", "OrenNayar",
             "Lafortune", "KayKajiya", "mirror"),
    "layered": ("CoatedLambertian", "internal_reflectance"),
    "registry": ("MODELS", "parse_model_spec"),
}
_MODULE_OF = {name: module for module, names in _PUBLIC.items() for name in names}
__all__ = sorted(_MODULE_OF)


def __getattr__(name: str) -> Any:
    """The public name ``name``, imported from its module on first use."""
    if name not in _MODULE_OF:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{_MODULE_OF[name]}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
