"""The ``[surface]`` keys of every generator: names, defaults, ranges, units, part names.

Lengths are in tile units (any consistent unit: the BRDF is scale-free, only ratios
matter). Angles are degrees. Pure Python: imported by the recipe validator, which must
start fast.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from microsim.errors import InputError
from microsim.schema import REQUIRED, Key


@dataclass(frozen=True)
class SurfaceKind:
    """One generator's recipe vocabulary.

    Parameters
    ----------
    doc : str
        What the generator builds (for docs/recipes.md).
    parts : tuple of str
        Material part names; face material id ``i`` is ``parts[i]``.
    keys : dict of str to Key
        The ``[surface]`` keys besides ``kind``.
    check : callable or None
        Cross-key rules on the resolved section; raises ``InputError``.
    triangles : callable or None
        Upper estimate of the tile's triangle count from the resolved section, for the
        memory guard (None: unknown before building, e.g. an imported mesh).
    realisations : callable or None
        For a section whose geometry is random, the default number of independent
        realisations a table averages (``simulation.realisations``; chosen by measurement,
        docs/ensembles.md); None for a deterministic section. None: never random.
    """

    doc: str
    parts: tuple[str, ...]
    keys: dict[str, Key] = field(default_factory=dict)
    check: Callable[[dict[str, Any]], None] | None = None
    triangles: Callable[[dict[str, Any]], float] | None = None
    realisations: Callable[[dict[str, Any]], int | None] | None = None


def _f(doc: str, default: Any = REQUIRED, **kw: Any) -> Key:
    return Key("float", default, doc, **kw)


LENGTH_MIN, LENGTH_MAX = 1e-9, 1e9
"""Bounds of every length, in tile units: lengths are scale-free (only ratios matter), and
this range holds any unit from nanometres to kilometres while squares and products of
lengths stay far inside float64 (and the tile's coordinates inside float32)."""
SPAN = 1e4
"""Largest ratio between two lengths of one tile (the period, heights, radii,
thicknesses, correlation lengths): the tracer offsets secondary rays by 1e-6 of the
tile's extent (microsim.trace.EPS_REL), so the smallest feature stays 100 offsets wide."""
ALPHA_MIN = 1e-3
"""Smallest roughness a recipe asks for: below it a surface is a mirror at every bin
resolution a table has (its lobe is narrower than 0.06 degrees)."""


def _len(doc: str, default: Any = REQUIRED, zero: bool = False) -> Key:
    """A length key: in [LENGTH_MIN, LENGTH_MAX] tile units (or 0 with ``zero``)."""
    return Key("float", default, doc, unit="length", low=0.0 if zero else LENGTH_MIN,
               high=LENGTH_MAX)


def _alpha(doc: str, high: float = 10.0) -> Key:
    """An optional roughness key, alpha in [ALPHA_MIN, high]."""
    return Key("float", None, doc, low=ALPHA_MIN, high=high)


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


def _check_correlation(s: dict[str, Any], name: str, tau: float, cell: float,
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


DEFAULT_CELLS = 8
"""Default correlation length in grid cells (DESIGN.md: τ = 8 cells gives G1 within 0.005
of Smith)."""
MICRO_RESOLUTION = 512
"""Default grid of a ``vgroove`` tile with micro-roughness (columns and rows)."""
SEED = Key("int", 0, "Seed of the generator's random numbers.", low=0, high=2**63 - 1)
SIZE = _len("Tile side length (period along x and y).", 1.0)
SMOOTH = Key("bool", True, "Scatter at the curved surface the faces approximate (its "
             "normal where the ray enters it: docs/surfaces.md); false keeps the flat "
             "facets.")
ENSEMBLE_AREAS = 32 * 32**2
"""Correlation areas a Gaussian table's realisations hold together by default: 32 tiles of
32 × 32 correlation lengths (the shipped 256² tile), with which the shipped recipe's lobe
lies within 3% (median) of Torrance-Sparrow + Smith at 0-60° (docs/performance.md)."""
MAX_DEFAULT_REALISATIONS = 64
"""The default never asks for more realisations than this (tiny tiles)."""


def _gaussian_realisations(s: dict[str, Any]) -> int:
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


def _vgroove_realisations(s: dict[str, Any]) -> int | None:
    """Random slopes (``alpha``) or micro-roughness make the grooves random."""
    return VGROOVE_REALISATIONS if "alpha" in s or "micro_alpha" in s else None


def _paint_realisations(s: dict[str, Any]) -> int | None:
    """Particles or a rough top make a paint random."""
    random = s["pigment_fraction"] > 0 or s["top_alpha"] > 0
    return PAINT_REALISATIONS if random else None


def _check_gaussian(s: dict[str, Any]) -> None:
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
    if "sigma" in s and not ALPHA_MIN <= 2 * sigma / tau_x <= 10:
        raise InputError(f"surface.sigma = {sigma!r}: gives alpha = 2 sigma / "
                         f"correlation_length = {2 * sigma / tau_x:.3g}; must be in "
                         f"[{ALPHA_MIN:g}, 10]")
    base = "correlation_length" if "correlation_length" in s else "resolution"
    for axis, tau in (("x", tau_x), ("y", tau_y)):
        # the smoother axis of an anisotropic surface gets the longer correlation length
        name = f"alpha_{axis}" if "alpha_x" in s and tau > s["size"] else base
        _check_correlation(s, name, tau, cell, s["size"])


def _check_vgroove(s: dict[str, Any]) -> None:
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
        _check_correlation(s, "micro_correlation", s["micro_correlation"], s["size"] / n,
                           s["size"])


def _check_velvet(s: dict[str, Any]) -> None:
    """Fibres must be small against the tile: the periodic wrap moves a cut piece by one
    period at most, and a fibre's root reaches radius · (tan 80° + 1) below the base."""
    if s["fibre_length"] > 0.5 * s["size"]:
        raise InputError(f"surface.fibre_length = {s['fibre_length']!r}: must be <= half the "
                         f"tile size ({0.5 * s['size']:g}); raise size for longer fibres")
    if s["fibre_radius"] > 0.02 * s["size"]:
        raise InputError(f"surface.fibre_radius = {s['fibre_radius']!r}: must be <= 2% of "
                         f"the tile size ({0.02 * s['size']:g})")


def _check_weave(s: dict[str, Any]) -> None:
    if s["yarn_width"] > 0.95 * s["spacing"]:
        raise InputError(f"surface.yarn_width = {s['yarn_width']!r}: must be <= 0.95 * "
                         f"spacing = {0.95 * s['spacing']:g} (neighbouring yarns would touch)")
    if any(v != int(v) for v in s["float"]):
        raise InputError(f"surface.float = {s['float']!r}: must be whole numbers of yarns")


def _check_cylinders(s: dict[str, Any]) -> None:
    if s["spacing"] < 2 * s["radius"]:
        raise InputError(f"surface.spacing = {s['spacing']!r}: must be >= 2 * radius "
                         f"= {2 * s['radius']:g} (cylinders must not overlap)")
    if s["sink"] >= 2 * s["radius"]:
        raise InputError(f"surface.sink = {s['sink']!r}: must be < 2 * radius "
                         f"= {2 * s['radius']:g} (the cylinder would vanish)")


def _check_paint(s: dict[str, Any]) -> None:
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
    if 0 < s["top_alpha"] < ALPHA_MIN:
        raise InputError(f"surface.top_alpha = {s['top_alpha']!r}: must be 0 (flat) or at "
                         f"least {ALPHA_MIN:g}")
    if s["top_alpha"] > 0 and "top_correlation_length" in s:
        _check_correlation(s, "top_correlation_length", s["top_correlation_length"],
                           s["size"] / s["resolution"], s["size"])
    if flake and s["flake_thickness"] >= s["pigment_radius"]:
        raise InputError(f"surface.flake_thickness = {s['flake_thickness']!r}: must be below "
                         f"pigment_radius = {s['pigment_radius']!r} (a flake is thin)")


PAINT_GAP = 0.02
"""Particles keep 1% of their radius off every other surface (microsim.surfaces.paint.GAP),
on both sides: the binder must exceed a particle's height by this fraction."""


def _paint_triangles(s: dict[str, Any]) -> float:
    """Top grid, substrate, and the particles the fraction asks for at the smallest radius
    (each cut by the wrap into at most a few pieces: times 2)."""
    top = 2 * s["resolution"] ** 2 if s["top_alpha"] > 0 else 2
    r = s["pigment_radius"] * math.exp(-2 * s["radius_spread"])
    flake = s["pigment_shape"] == "flake"
    volume = math.pi * r * r * s["flake_thickness"] if flake else 4 / 3 * math.pi * r**3
    count = s["pigment_fraction"] * s["size"] ** 2 * s["binder_thickness"] / volume
    per = 4 * s["sides"] if flake else 2 * s["sides"] * (s["sides"] // 2 - 1)
    return top + 2 + 2 * count * per


SURFACE_KINDS: dict[str, SurfaceKind] = {
    "flat": SurfaceKind(
        "A flat square tile at z = 0: the trivial reference.",
        ("base",),
        {"size": SIZE, "seed": SEED},
        triangles=lambda s: 2,
    ),
    "gaussian": SurfaceKind(
        "A Gaussian random height field with autocorrelation sigma^2 exp(-r^2/tau^2), made "
        "by spectral (FFT) synthesis on a periodic grid. Roughness alpha = 2 sigma / tau "
        "(Walter et al. 2007's alpha, the lecture's m). Anisotropic: alpha_x, alpha_y set "
        "different correlation lengths along the rotated x and y axes.",
        ("base",),
        {
            "alpha": _alpha("Target roughness (isotropic)."),
            "alpha_x": _alpha("Target roughness along the (rotated) x axis."),
            "alpha_y": _alpha("Target roughness along the (rotated) y axis."),
            "sigma": _len("RMS height (with correlation_length instead of alpha).", None),
            "correlation_length": _len(
                "Correlation length tau (of the larger roughness axis when anisotropic). "
                "Default: 8 grid cells.", None),
            "rotation": _f("Rotation of the anisotropy axes about +z.", 0.0, unit="deg",
                           low=-360.0, high=360.0),
            "resolution": Key("int", 256, "Vertices per tile side.", low=4, high=8192),
            "size": SIZE,
            "seed": SEED,
        },
        _check_gaussian,
        lambda s: 2 * s["resolution"] ** 2,
        _gaussian_realisations,
    ),
    "vgroove": SurfaceKind(
        "Symmetric V-grooves along y (Torrance-Sparrow cavities): one slope angle for "
        "every groove, or slopes drawn from a Beckmann distribution of roughness alpha; "
        "with slope, optionally Gaussian micro-roughness on every face (micro_alpha).",
        ("base",),
        {
            "slope": _f("Slope angle of every groove face (give slope or alpha).", None,
                        unit="deg", low=0.0, low_open=True, high=89.0),
            "alpha": _alpha("Draw each groove's slope from a Beckmann slope distribution "
                            "of this roughness (give slope or alpha)."),
            "grooves": Key("int", 64, "Grooves per tile.", low=1, high=1_000_000),
            "micro_alpha": _alpha("Gaussian micro-roughness alpha of every groove face, "
                                  "displaced along the face's normal (with slope); "
                                  "optional.", high=2.0),
            "micro_resolution": Key("int", None, "Grid columns (and rows) of a tile with "
                                    f"micro_alpha; a multiple of 2 * grooves. Default: "
                                    f"{MICRO_RESOLUTION}.", low=8, high=8192),
            "micro_correlation": _len("Correlation length of the micro-roughness along a "
                                    "face. Default: 8 grid cells measured along the face.",
                                    None),
            "size": SIZE,
            "seed": SEED,
        },
        _check_vgroove,
        lambda s: (2 * s.get("micro_resolution", MICRO_RESOLUTION) ** 2
                   if "micro_alpha" in s else 4 * s["grooves"]),
        _vgroove_realisations,
    ),
    "cylinders": SurfaceKind(
        "Parallel circular cylinders along y lying on (or sunk into) a flat base plane: "
        "brushed metal, hair-like anisotropic surfaces.",
        ("base", "cylinder"),
        {
            "radius": _len("Cylinder radius.", 0.5),
            "spacing": _len("Distance between cylinder axes (the tile period along x).", 1.0),
            "sink": _len("Depth the cylinders are sunk into the base plane.", 0.0,
                         zero=True),
            "segments": Key("int", 128, "Facets around a full circumference. A mirror "
                            "reflection turns by twice the facet step, so 128 gives 5.6 "
                            "degree steps: the default phi bin width.", low=6, high=65536),
            "length": _len("Tile period along the cylinder axis (y).", 1.0),
            "smooth_normals": SMOOTH,
            "seed": SEED,
        },
        _check_cylinders,
        lambda s: 2 * (s["segments"] + 2),
    ),
    "velvet": SurfaceKind(
        "Dense short fibres standing on a flat base (Westin et al. 1992's velvet), placed "
        "by a seeded jittered-grid process, periodic; fibres are closed tubes with tips.",
        ("base", "fibre"),
        {
            "fibre_radius": _len("Fibre radius.", 0.01),
            "fibre_length": _len("Fibre length.", 0.15),
            "density": _f("Fibres per unit area.", 400.0, low=0.0, low_open=True),
            "tilt": _f("Mean tilt of the fibres from +z.", 10.0, unit="deg", low=0.0,
                       high=89.0),
            "tilt_spread": _f("Standard deviation of the tilt.", 5.0, unit="deg", low=0.0,
                              high=90.0),
            "azimuth": _f("Mean azimuth of the tilt, from +x towards +y.", 0.0, unit="deg",
                          low=-360.0, high=360.0),
            "azimuth_spread": _f("Standard deviation of the tilt azimuth (360 = uniform).",
                                 360.0, unit="deg", low=0.0, high=360.0),
            "sides": Key("int", 6, "Facets around each fibre.", low=3, high=64),
            "smooth_normals": SMOOTH,
            "size": SIZE,
            "seed": SEED,
        },
        _check_velvet,
        lambda s: 2 + 8 * s["sides"] * s["density"] * s["size"] ** 2,
        lambda s: VELVET_REALISATIONS,
    ),
    "weave": SurfaceKind(
        "Woven cloth, one pattern repeat: warp yarns along y and weft yarns along x as "
        "swept tubes of elliptical cross-section on crimped (sinusoidal) paths.",
        ("warp", "weft"),
        {
            "pattern": Key("str", "plain", "Weave pattern.", choices=("plain", "twill")),
            "float": Key("floats", [2.0, 1.0], "Twill float: yarns passed over, then under "
                         "(e.g. [2, 1] for 2/1 twill, [2, 2] for 2/2).", low=1, high=16,
                         length=2),
            "yarn_width": _len("Yarn cross-section width.", 0.8),
            "yarn_thickness": _len("Yarn cross-section thickness.", 0.3),
            "spacing": _len("Distance between neighbouring yarns (warp and weft).", 1.0),
            "segments": Key("int", 16, "Path samples per yarn crossing.", low=4,
                            high=1024),
            "sides": Key("int", 24, "Facets around each yarn's cross-section (with "
                         "smooth normals, 12 trap mirror light between crossing yarns: "
                         "docs/surfaces.md).", low=4, high=256),
            "smooth_normals": SMOOTH,
            "seed": SEED,
        },
        _check_weave,
        lambda s: 4 * s["segments"] * s["sides"] * (s["float"][0] + s["float"][1]) ** 2,
    ),
    "paint": SurfaceKind(
        "A pigmented coating (Gondek, Meyer & Newman 1994): a dielectric binder layer with "
        "a flat or Gaussian rough top, pigment spheres or thin flakes inside it (seeded "
        "random sequential addition, no overlaps, periodic), over a flat substrate at "
        "z = 0. Give the binder a dielectric material with refract = true.",
        ("binder", "pigment", "substrate"),
        {
            "binder_thickness": _len("Mean thickness of the binder layer.", 0.2),
            "top_alpha": _f("Roughness alpha of the binder's top (a Gaussian height "
                            "field); 0 = flat.", 0.0, low=0.0, high=2.0),
            "top_correlation_length": _len("Correlation length of the top's heights. "
                                         "Default: 8 grid cells.", None),
            "resolution": Key("int", 256, "Vertices per tile side of a rough top.", low=4,
                              high=8192),
            "pigment_fraction": _f("Pigment volume over binder volume (pigment included); "
                                   "0 = none.", 0.1, low=0.0, high=0.4),
            "pigment_shape": Key("str", "sphere", "Particle shape: spheres, or thin discs "
                                 "(flakes) with tilted normals.",
                                 choices=("sphere", "flake")),
            "pigment_radius": _len("Median particle radius (a flake's disc radius).", 0.03),
            "radius_spread": _f("Log-standard deviation of the lognormal radius (clipped "
                                "at 2 standard deviations); 0 = all equal.", 0.2, low=0.0,
                                high=1.0),
            "flake_thickness": _len("Thickness of a flake.", 0.002),
            "flake_tilt_spread": _f("RMS tilt of the flake normals from +z (tilt vector "
                                    "Gaussian, azimuth uniform).", 10.0, unit="deg",
                                    low=0.0, high=60.0),
            "sides": Key("int", 12, "Facets around a particle (sphere meridians, disc "
                         "edges).", low=4, high=256),
            "size": SIZE,
            "seed": SEED,
        },
        _check_paint,
        _paint_triangles,
        _paint_realisations,
    ),
    "mesh": SurfaceKind(
        "A user tile (PLY, OBJ or STL, read by trimesh) with its period given here. The "
        "mesh must lie within [0, period_x] x [0, period_y] and tile seamlessly.",
        ("base",),
        {
            "path": Key("path", REQUIRED, "Mesh file (relative to the recipe's folder)."),
            "period": Key("pair", REQUIRED, "Tile period [Lx, Ly].", unit="length",
                          low=LENGTH_MIN, high=LENGTH_MAX),
            "seed": SEED,
        },
    ),
}
