"""The ``[surface]`` keys of every generator: names, defaults, ranges, units, part names.

Lengths are in tile units (any consistent unit: the BRDF is scale-free, only ratios
matter). Angles are degrees. Pure Python: imported by the recipe validator, which must
start fast.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from microsim.schema import REQUIRED, Key
from microsim.surfaces.rules import (
    MICRO_RESOLUTION,
    SURFACE_ALPHA_MIN,
    VELVET_REALISATIONS,
    check_cylinders,
    check_gaussian,
    check_paint,
    check_velvet,
    check_vgroove,
    check_weave,
    gaussian_realisations,
    paint_realisations,
    paint_triangles,
    vgroove_realisations,
)


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
def _len(doc: str, default: Any = REQUIRED, zero: bool = False) -> Key:
    """A length key: in [LENGTH_MIN, LENGTH_MAX] tile units (or 0 with ``zero``)."""
    return Key("float", default, doc, unit="length", low=0.0 if zero else LENGTH_MIN,
               high=LENGTH_MAX)


def _alpha(doc: str, high: float = 10.0) -> Key:
    """An optional roughness key, alpha in [SURFACE_ALPHA_MIN, high]."""
    return Key("float", None, doc, low=SURFACE_ALPHA_MIN, high=high)


SEED = Key("int", 0, "Seed of the generator's random numbers.", low=0, high=2**63 - 1)
SIZE = _len("Tile side length (period along x and y).", 1.0)
SMOOTH = Key("bool", True, "Scatter at the curved surface the faces approximate (its "
             "normal where the ray enters it: docs/surfaces.md); false keeps the flat "
             "facets.")
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
        check_gaussian,
        lambda s: 2 * s["resolution"] ** 2,
        gaussian_realisations,
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
        check_vgroove,
        lambda s: (2 * s.get("micro_resolution", MICRO_RESOLUTION) ** 2
                   if "micro_alpha" in s else 4 * s["grooves"]),
        vgroove_realisations,
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
        check_cylinders,
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
        check_velvet,
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
        check_weave,
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
        check_paint,
        paint_triangles,
        paint_realisations,
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
