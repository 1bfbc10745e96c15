"""The rules of the ``[surface]`` keys beyond their ranges: which keys go together, the
lengths a tile can resolve, the default realisations of a random surface, and the
triangles a tile will have (the memory guard's estimate). Pure Python, like the keys
themselves (``microsim.surfaces.params``).
"""

from __future__ import annotations

import math
from typing import Any

from microsim.errors import InputError
from microsim.schema import Key

SPAN = 1e4
"""Largest ratio between two lengths of one tile (the period, heights, radii,
thicknesses, correlation lengths): the tracer offsets secondary rays by 1e-6 of the
tile's extent (microsim.trace.EPS_REL), so the smallest feature stays 100 offsets wide."""
SURFACE_ALPHA_MIN = 1e-3
"""Smallest roughness a recipe asks for: below it a surface is a mirror at every bin
resolution a table has (its lobe is narrower than 0.06 degrees)."""


DEFAULT_CELLS = 8
"""Default correlation length in grid cells (docs/conventions.md: τ = 8 cells gives G1
within 0.005 of Smith)."""
MICRO_RESOLUTION = 512
"""Default grid of a ``vgroove`` tile with micro-roughness (columns and rows)."""
def check_span(s: dict[str, Any], keys: dict[str, Key], where: str = "surface.") -> None:
    """The lengths of a resolved section (zeros aside) lie within a factor ``SPAN`` of
    each other; ``InputError`` names the smallest and the largest otherwise."""
    lengths = {f"{name}[{i}]" if isinstance(s[name], list) else name: v
               for name, key in keys.items() if key.unit == "length" and name in s
               for i, v in enumerate(s[name] if isinstance(s[name], list) else [s[name]])
               if v > 0}
    if len(lengths) < 2:
        return
    low, high = min(lengths, key=lengths.get), max(lengths, key=lengths.get)
    if lengths[high] > SPAN * lengths[low]:
        raise InputError(f"{where}{low} = {lengths[low]!r}: at most {SPAN:g} times smaller "
                         f"than {where}{high} = {lengths[high]!r} (the tracer resolves "
                         "features down to 1e-4 of the tile); rescale one of them")


def check_correlation(s: dict[str, Any], name: str, tau: float, cell: float,
                       length: float) -> None:
    """A correlation length ``tau`` (set by key ``name``) spans at least one grid cell and
    at most the tile's ``length``: outside, the heights are white noise or one bump."""
    if not cell <= tau <= length:
        raise InputError(f"surface.{name} = {s[name]!r}: gives a correlation length of "
                         f"{tau:.3g}, which must lie between one grid cell ({cell:.3g}) and "
                         f"the tile ({length:.3g})")


def correlation_lengths(surface: dict[str, Any]) -> tuple[float, float, float]:
    """(σ, τx, τy) of a resolved gaussian ``[surface]`` from whichever of alpha /
    alpha_x, alpha_y / sigma it gives: RMS height and the correlation lengths along the
    rotated axes (tile units); α = 2σ/τ."""
    cell = surface["size"] / surface["resolution"]
    tau = surface.get("correlation_length", DEFAULT_CELLS * cell)
    if "sigma" in surface:
        return surface["sigma"], tau, tau
    if "alpha" in surface:
        return surface["alpha"] * tau / 2, tau, tau
    ax, ay = surface["alpha_x"], surface["alpha_y"]
    sigma = max(ax, ay) * tau / 2  # the rougher axis gets tau, the smoother a longer one
    return sigma, 2 * sigma / ax, 2 * sigma / ay


ENSEMBLE_AREAS = 32 * 32**2
"""Correlation areas a Gaussian table's realisations hold together by default: 32 tiles of
32 × 32 correlation lengths (the shipped 256² tile), with which the shipped recipe's lobe
lies within 3% (median) of Torrance-Sparrow + Smith at 0-60° (docs/performance.md)."""
MAX_DEFAULT_REALISATIONS = 64
"""The default never asks for more realisations than this (tiny tiles)."""


def gaussian_realisations(s: dict[str, Any]) -> int:
    """Enough realisations for ``ENSEMBLE_AREAS`` correlation areas (size² / (τx τy) each)."""
    _, tau_x, tau_y = correlation_lengths(s)
    areas = s["size"] ** 2 / (tau_x * tau_y)
    return max(1, min(MAX_DEFAULT_REALISATIONS, math.ceil(ENSEMBLE_AREAS / areas - 1e-9)))


VELVET_REALISATIONS = 4
"""Default realisations of a velvet tile: its fibres' spread is small against the ray noise
of velvet.toml, and 4 is the fewest with which the moderated error estimates its own
degrees of freedom (docs/ensembles.md; measured by scripts/ensemble_defaults.py)."""
PAINT_REALISATIONS = 8
"""Default realisations of a paint tile with particles or a rough top: balances the
realisations' and the rays' variance of paint.toml at grazing incidence."""
VGROOVE_REALISATIONS = 8
"""Default realisations of V-grooves with random slopes or micro-roughness: balances them
for vgroove-rough-direct.toml."""


def vgroove_realisations(s: dict[str, Any]) -> int | None:
    """Random slopes (``alpha``) or micro-roughness make the grooves random."""
    return VGROOVE_REALISATIONS if "alpha" in s or "micro_alpha" in s else None


def paint_realisations(s: dict[str, Any]) -> int | None:
    """Particles or a rough top make a paint random."""
    random = s["pigment_fraction"] > 0 or s["top_alpha"] > 0
    return PAINT_REALISATIONS if random else None


def check_gaussian(s: dict[str, Any]) -> None:
    """Exactly one of: ``alpha``; ``alpha_x`` and ``alpha_y``; ``sigma`` (with
    ``correlation_length``)."""
    given = [k for k in ("alpha", "alpha_x", "alpha_y", "sigma") if k in s]
    ok = given in (["alpha"], ["alpha_x", "alpha_y"], ["sigma"])
    if not ok:
        raise InputError("surface: a gaussian surface takes exactly one of: alpha; "
                         "alpha_x and alpha_y; sigma (with correlation_length); got "
                         + (", ".join(given) or "none of them"))
    if "sigma" in s and "correlation_length" not in s:
        raise InputError("surface.correlation_length: missing; sigma needs it "
                         "(alpha = 2 sigma / correlation_length)")
    sigma, tau_x, tau_y = correlation_lengths(s)
    cell = s["size"] / s["resolution"]
    if "sigma" in s and not SURFACE_ALPHA_MIN <= 2 * sigma / tau_x <= 10:
        raise InputError(f"surface.sigma = {sigma!r}: gives alpha = 2 sigma / "
                         f"correlation_length = {2 * sigma / tau_x:.3g}; must be in "
                         f"[{SURFACE_ALPHA_MIN:g}, 10]")
    base = "correlation_length" if "correlation_length" in s else "resolution"
    for axis, tau in (("x", tau_x), ("y", tau_y)):
        # the smoother axis of an anisotropic surface gets the longer correlation length
        name = f"alpha_{axis}" if "alpha_x" in s and tau > s["size"] else base
        check_correlation(s, name, tau, cell, s["size"])


def check_vgroove(s: dict[str, Any]) -> None:
    if ("slope" in s) == ("alpha" in s):
        raise InputError("surface: a vgroove surface takes exactly one of slope, alpha")
    if "micro_alpha" not in s:
        return
    if "slope" not in s:
        raise InputError("surface.micro_alpha: needs slope (one slope for every groove), "
                         "not alpha")
    n = s.get("micro_resolution", MICRO_RESOLUTION)
    if n % (2 * s["grooves"]):
        raise InputError(f"surface.micro_resolution = {n!r}: must be a "
                         f"multiple of 2 * grooves = {2 * s['grooves']} (whole grid columns "
                         "per groove face)")
    if "micro_correlation" in s:
        check_correlation(s, "micro_correlation", s["micro_correlation"], s["size"] / n,
                           s["size"])


def check_velvet(s: dict[str, Any]) -> None:
    """Fibres must be small against the tile: the periodic wrap moves a cut piece by one
    period at most, and a fibre's root reaches radius · (tan 80° + 1) below the base."""
    if s["fibre_length"] > 0.5 * s["size"]:
        raise InputError(f"surface.fibre_length = {s['fibre_length']!r}: must be <= half the "
                         f"tile size ({0.5 * s['size']:g}); raise size for longer fibres")
    if s["fibre_radius"] > 0.02 * s["size"]:
        raise InputError(f"surface.fibre_radius = {s['fibre_radius']!r}: must be <= 2% of "
                         f"the tile size ({0.02 * s['size']:g})")


def check_weave(s: dict[str, Any]) -> None:
    if s["yarn_width"] > 0.95 * s["spacing"]:
        raise InputError(f"surface.yarn_width = {s['yarn_width']!r}: must be <= 0.95 * "
                         f"spacing = {0.95 * s['spacing']:g} (neighbouring yarns would touch)")
    if any(v != int(v) for v in s["float"]):
        raise InputError(f"surface.float = {s['float']!r}: must be whole numbers of yarns")


def check_cylinders(s: dict[str, Any]) -> None:
    if s["spacing"] < 2 * s["radius"]:
        raise InputError(f"surface.spacing = {s['spacing']!r}: must be >= 2 * radius "
                         f"= {2 * s['radius']:g} (cylinders must not overlap)")
    if s["sink"] >= 2 * s["radius"]:
        raise InputError(f"surface.sink = {s['sink']!r}: must be < 2 * radius "
                         f"= {2 * s['radius']:g} (the cylinder would vanish)")


def check_paint(s: dict[str, Any]) -> None:
    """Particles must fit in the binder and be small against the tile (the periodic wrap
    moves a cut piece by one period at most)."""
    r_max = s["pigment_radius"] * math.exp(2 * s["radius_spread"])  # radii are clipped there
    flake = s["pigment_shape"] == "flake"
    height = s["flake_thickness"] if flake else 2 * r_max
    if s["pigment_fraction"] > 0 and height * (1 + PAINT_GAP) >= s["binder_thickness"]:
        raise InputError(f"surface.binder_thickness = {s['binder_thickness']!r}: must exceed "
                         f"the largest particle's height {height:g} (pigment_radius "
                         "e^(2 radius_spread), doubled for spheres); raise it or lower "
                         "pigment_radius")
    if r_max > 0.25 * s["size"]:
        raise InputError(f"surface.pigment_radius = {s['pigment_radius']!r}: the largest "
                         f"radius {r_max:g} must be <= a quarter of the tile size "
                         f"({0.25 * s['size']:g}); raise size")
    if 0 < s["top_alpha"] < SURFACE_ALPHA_MIN:
        raise InputError(f"surface.top_alpha = {s['top_alpha']!r}: must be 0 (flat) or at "
                         f"least {SURFACE_ALPHA_MIN:g}")
    if s["top_alpha"] > 0 and "top_correlation_length" in s:
        check_correlation(s, "top_correlation_length", s["top_correlation_length"],
                           s["size"] / s["resolution"], s["size"])
    if flake and s["flake_thickness"] >= s["pigment_radius"]:
        raise InputError(f"surface.flake_thickness = {s['flake_thickness']!r}: must be below "
                         f"pigment_radius = {s['pigment_radius']!r} (a flake is thin)")


PAINT_GAP = 0.02
"""Particles keep 1% of their radius off every other surface (microsim.surfaces.paint.GAP),
on both sides: the binder must exceed a particle's height by this fraction."""


def paint_triangles(s: dict[str, Any]) -> float:
    """Top grid, substrate, and the particles the fraction asks for at the smallest radius
    (each cut by the wrap into at most a few pieces: times 2)."""
    top = 2 * s["resolution"] ** 2 if s["top_alpha"] > 0 else 2
    r = s["pigment_radius"] * math.exp(-2 * s["radius_spread"])
    flake = s["pigment_shape"] == "flake"
    volume = math.pi * r * r * s["flake_thickness"] if flake else 4 / 3 * math.pi * r**3
    count = s["pigment_fraction"] * s["size"] ** 2 * s["binder_thickness"] / volume
    per = 4 * s["sides"] if flake else 2 * s["sides"] * (s["sides"] // 2 - 1)
    return top + 2 + 2 * count * per


