"""Fitting analytic models to a table ("models for measured data").

Weighted least squares on every bin with a defined error, in log space: the residual of a
bin is

    r = (ln(m + ε) − ln(s + ε)) / √((σ / (s + ε))² + ρ²),

with s the simulated value, σ its standard error, m the model's bin average
(``compare.bin_average``), ε = 10⁻³ × the table's peak and ρ = 1%. In log space a bin's
weight is its relative precision, so the specular peak (a few bins with huge values) does
not outweigh the lobe's flanks and the diffuse floor, which carry the shape; ε keeps empty
and near-zero bins finite, and the floor ρ stops bins with tiny errors from dominating
(models are approximations: no bin is trusted beyond 1%). Bins whose error is undefined
(no ray landed) are left out. ``scipy.optimize.least_squares`` (trust region, bounds)
minimises Σ r²; parameter uncertainties are √diag((JᵀJ)⁻¹) scaled by χ²/dof when that
exceeds 1 (the model does not explain the noise: the uncertainty widens accordingly).

Colour parameters (a Fresnel F0, an albedo, a specular scale) are one per channel of the
table: ``F0_R``, ``F0_G``, ``F0_B`` of an RGB table, ``F0_400nm``, … (``Channels.names``)
of a spectral one, fitted together with the shape parameters; a model without colour
parameters (Lafortune) is grey, the same in every channel.

The result is a ``FitResult`` (one ``IncidenceFit`` per incidence), and the progress
callback receives a ``FitProgress``; their JSON form (``to_json``) is made here only: it is
what ``microsim fit --json`` prints, before the command's own keys.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from microsim.analytic.brdf import KayKajiya, Lafortune, OrenNayar, Phong, TorranceSparrow
from microsim.analytic.cloth import MicrocylinderCloth
from microsim.analytic.fresnel import SchlickFresnel
from microsim.analytic.ndf import GGX, Beckmann
from microsim.comparison.metrics import Model, bin_averages, channels_of, compare_table
from microsim.comparison.table_models import model_defaults
from microsim.errors import InputError
from microsim.memory import check_memory
from microsim.schema import Value
from microsim.spectra.channels import RGB_NAMES

EPS_FRACTION = 1e-3
REL_FLOOR = 0.01
FIT_BYTES_PER_RESIDUAL = 800
"""Memory per residual of a fit (a bin with light, per channel) while it runs: measured
660-730 B beyond a fixed 15 MB (tracemalloc peak of Beckmann and of three Lafortune
lobes fitted to 32 x 64 and 64 x 128 tables of three incidences), rounded up."""
SUBSAMPLES = 5
"""Midpoints per bin and axis while fitting (8 for the final metrics). With 3, the model's
own discretisation shifted α by 4 standard errors on a 16 × 32 table with 5% noise; with 5
by 0.7 (tests/test_fit.py)."""


@dataclass(frozen=True)
class FitProgress:
    """Where a fit stands after one evaluation of the model over the table.

    Attributes
    ----------
    evaluations : int
        Evaluations of the model over the table so far (counting from 1).
    chi2_dof : float
        χ²/dof of that evaluation's residuals.
    """

    evaluations: int
    chi2_dof: float

    def to_json(self) -> dict[str, Any]:
        """The progress as JSON: ``evaluations`` and ``chi2_dof``."""
        return {"evaluations": self.evaluations, "chi2_dof": self.chi2_dof}


@dataclass(frozen=True)
class IncidenceFit:
    """The fitted model against the table at one incident direction.

    Attributes
    ----------
    theta_i, phi_i : float
        The incident direction, degrees.
    albedo_fit, albedo_table : (C,) float
        Σ f_r Ω_proj over every bin, per channel: of the fitted model and of the table's
        fitted component.
    """

    theta_i: float
    phi_i: float
    albedo_fit: np.ndarray
    albedo_table: np.ndarray

    def to_json(self) -> dict[str, Any]:
        """The row as JSON, the albedos as lists."""
        return {"theta_i": self.theta_i, "phi_i": self.phi_i,
                "albedo_fit": self.albedo_fit.tolist(),
                "albedo_table": self.albedo_table.tolist()}


@dataclass(frozen=True)
class FitResult:
    """A model family fitted to a table: the parameters, their errors, the fit's quality.

    Attributes
    ----------
    model : str
        The family's spec (``lafortune:K`` with its number of lobes).
    params, uncertainty : dict of str to float
        The fitted parameters and their 1σ uncertainties, by the family's parameter names
        in its order.
    chi2_dof : float
        χ² of the weighted log-space residuals over the degrees of freedom (the bins with
        a defined error less the parameters, at least 1).
    median_rel_error : float
        Median |sim − fit| / fit over lobe bins, as ``compare_table``'s.
    per_theta_i : tuple of IncidenceFit
        One per incident direction (θi outer, φi inner).
    nfev : int
        Evaluations of the residuals by ``scipy.optimize.least_squares``.
    fitted : Model
        The model at the fitted parameters.
    held, held_sources : dict of str to Value, dict of str to str
        The model's parameters the fit holds (``Family.held``) and where each came from.
    model_bins : (a, b, nt, np, C) float
        The fitted model's bin averages per incidence (a θi, b φi), bin and channel, 1/sr:
        for plots.
    """

    model: str
    params: dict[str, float]
    uncertainty: dict[str, float]
    chi2_dof: float
    median_rel_error: float
    per_theta_i: tuple[IncidenceFit, ...]
    nfev: int
    fitted: Model
    model_bins: np.ndarray
    held: dict[str, Value] = field(default_factory=dict)
    held_sources: dict[str, str] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        """The fit as JSON: the parameters, their uncertainties, the held parameters and
        their sources, the fit's quality and the per-incidence rows; the ``fitted`` model
        and its ``model_bins`` are left out."""
        return {"model": self.model, "params": dict(self.params),
                "uncertainty": dict(self.uncertainty), "held": dict(self.held),
                "held_sources": dict(self.held_sources), "chi2_dof": self.chi2_dof,
                "median_rel_error": self.median_rel_error,
                "per_theta_i": [row.to_json() for row in self.per_theta_i],
                "nfev": self.nfev}


@dataclass(frozen=True)
class Family:
    """A fittable model: parameter names, start values, bounds, a builder (of the
    parameter vector, in the order of the names), and the parameters of the model
    (``microsim.analytic.registry``'s keys) it holds, the table's or its own default,
    with where each came from."""

    names: tuple[str, ...]
    start: tuple[float, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    build: Callable[[np.ndarray], Any]
    held: dict[str, Value] = field(default_factory=dict)
    held_sources: dict[str, str] = field(default_factory=dict)


def _held(defaults: Mapping[str, Value], own: Mapping[str, Value]
          ) -> tuple[dict[str, Value], dict[str, str]]:
    """The parameters ``own`` (key: the family's default) as held: the table's value
    where ``defaults`` (``model_defaults``) has one, with its source, else the default."""
    sources = getattr(defaults, "sources", {})
    values = {k: defaults.get(k, v) for k, v in own.items()}
    return values, {k: sources.get(k, "the table's") if k in defaults else "default"
                    for k in own}


def _per_channel(name: str, channels: Sequence[str]) -> tuple[str, ...]:
    """A colour parameter's names, one per channel: ``F0_R``, …, or ``F0_550nm``, …"""
    return tuple(f"{name}_{c}" for c in channels)


def _microfacet(ndf_name: str, channels: Sequence[str]) -> Family:
    count = len(channels)
    held, sources = _held({}, {"shadowing": "smith-correlated"})

    def build(p: np.ndarray) -> Any:
        cls = Beckmann if ndf_name == "beckmann" else GGX
        return TorranceSparrow(cls(p[0]), fresnel=SchlickFresnel(p[1:1 + count]),
                               shadowing=held["shadowing"])

    return Family(("alpha", *_per_channel("F0", channels)), (0.3, *(0.9,) * count),
                  (1e-3, *(0.0,) * count), (5.0, *(1.0,) * count), build, held, sources)


def _oren_nayar(channels: Sequence[str]) -> Family:
    """Oren-Nayar's slope deviation sigma in degrees, as the model spec takes it."""
    count = len(channels)
    held, sources = _held({}, {"model": "full"})

    def build(p: np.ndarray) -> Any:
        return OrenNayar(np.radians(p[0]), p[1:1 + count], held["model"])

    return Family(("sigma", *_per_channel("albedo", channels)),
                  (math.degrees(0.3), *(0.5,) * count), (0.0, *(0.0,) * count),
                  (math.degrees(1.5), *(1.0,) * count), build, held, sources)


def _phong(channels: Sequence[str]) -> Family:
    count = len(channels)
    held, sources = _held({}, {"normalized": True})

    def build(p: np.ndarray) -> Any:
        class Scaled:
            def eval(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
                return (Phong(p[0], normalized=held["normalized"]).eval(wi, wo)[..., None]
                        * p[1:1 + count])

        return Scaled()

    return Family(("n", *_per_channel("ks", channels)), (20.0, *(0.8,) * count),
                  (0.0, *(0.0,) * count), (1e5, *(5.0,) * count), build, held, sources)


def _lafortune(lobes: int) -> Family:
    """Isotropic lobes (Cx = Cy) of Lafortune et al. 1997, eq. 6: per lobe Cxy, Cz, n."""

    def build(p: np.ndarray) -> Any:
        q = p.reshape(lobes, 3)
        return Lafortune([(c, c, z, n) for c, z, n in q])

    names = tuple(f"{k}_{i}" for i in range(1, lobes + 1) for k in ("Cxy", "Cz", "n"))
    start = tuple(v for i in range(lobes) for v in (-1.0 / (i + 1), 1.0 / (i + 1),
                                                     10.0 / (i + 1)))
    return Family(names, start, tuple(v for _ in range(lobes) for v in (-50.0, -50.0, 0.0)),
                  tuple(v for _ in range(lobes) for v in (50.0, 50.0, 1e4)), build)


def _kay_kajiya(defaults: Mapping[str, Value], channels: Sequence[str]) -> Family:
    """Kay-Kajiya as a fibre-layer BRDF (``KayKajiya`` with ``coverage``): kd and ks per
    channel and the exponent n; the tangent and coverage are the table's (its surface's
    axis, 2 radius / spacing), 1 and +y without them."""
    count = len(channels)
    held, sources = _held(defaults, {"tangent_theta": 90.0, "tangent_phi": 90.0,
                                     "coverage": 1.0})

    def build(p: np.ndarray) -> Any:
        theta, phi = np.radians(held["tangent_theta"]), np.radians(held["tangent_phi"])
        t = [np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)]
        models = [KayKajiya(t, p[c], p[count + c], p[2 * count], held["coverage"])
                  for c in range(count)]

        class PerChannel:
            def eval(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
                return np.stack([m.eval(wi, wo) for m in models], axis=-1)

        return PerChannel()

    kd = defaults.get("kd", 0.05)
    return Family((*_per_channel("kd", channels), *_per_channel("ks", channels), "n"),
                  (*(kd,) * count, *(0.5,) * count, 20.0), (0.0,) * (2 * count + 1),
                  (*(10.0,) * count, *(1e3,) * count, 1e4), build, held, sources)


class _ClothPerChannel:
    """The microcylinder cloth model in any number of channels, from RGB
    ``MicrocylinderCloth`` evaluations: f_r is affine in the volume scales, f = S +
    Σ_families a V A (Sadeghi et al. 2013, eq. 12 of the volume term; ``cloth.eval``), so
    with grey scales 0 (S), and 1 for one family and 0 for the other (S + a V of that
    family), the channels' f_r are S + Σ (S + a V − S) A_c."""

    def __init__(self, parts: np.ndarray, albedo: np.ndarray, slope: float,
                 flat: float) -> None:
        coverage, eta, gamma_s, gamma_v, kd = parts[0:2], parts[2], parts[3], parts[4], parts[5]
        self.albedo = np.asarray(albedo, float)                          # (2, C)
        self.models = [MicrocylinderCloth(coverage, eta, gamma_s, gamma_v, kd, grey,
                                          slope, flat)
                       for grey in (np.zeros((2, 1)), [[1.0], [0.0]], [[0.0], [1.0]])]

    def eval(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """f_r, 1/sr: (..., C)."""
        base, warp, weft = (m.eval(wi, wo)[..., :1] for m in self.models)
        return base + (warp - base) * self.albedo[0] + (weft - base) * self.albedo[1]


def _microcylinder(defaults: Mapping[str, Value], channels: Sequence[str]) -> Family:
    """The microcylinder cloth model (``MicrocylinderCloth``): coverage a_1 (warp), a_2
    (weft), η, γ_s, γ_v (degrees, as the model spec takes them), k_d, and the volume
    scale A per family and channel (up to 5: not an albedo); the tangent curves are the
    table's weave (``slope``, ``flat``). An RGB table's model is ``MicrocylinderCloth``
    itself; any other channels' is ``_ClothPerChannel`` (the same f_r, from three RGB
    evaluations)."""
    count = len(channels)
    held, sources = _held(defaults, {"slope": 0.0, "flat": 0.0})

    def build(p: np.ndarray) -> Any:
        parts = np.array([p[0], p[1], p[2], np.radians(p[3]), np.radians(p[4]), p[5]])
        albedo = p[6:6 + 2 * count].reshape(2, count)
        slope, flat = held["slope"], held["flat"]
        if tuple(channels) == RGB_NAMES:
            return MicrocylinderCloth(parts[0:2], *parts[2:6], albedo, slope, flat)
        return _ClothPerChannel(parts, albedo, slope, flat)

    a = min(0.95, defaults.get("yarn_width", 0.8) / defaults.get("spacing", 1.0))
    albedo = [float(np.mean(defaults.get(f"albedo_{part}", 0.5))) for part in
              ("warp", "weft")]
    return Family(("a_warp", "a_weft", "eta", "gamma_s", "gamma_v", "kd",
                   *_per_channel("A_warp", channels), *_per_channel("A_weft", channels)),
                  (a, a, 1.5, math.degrees(0.2), math.degrees(0.4), 0.5,
                   *[albedo[0]] * count, *[albedo[1]] * count),
                  (0.0, 0.0, 1.01, math.degrees(0.005), math.degrees(0.005), 0.0,
                   *(0.0,) * (2 * count)),
                  (1.0, 1.0, 3.0, math.degrees(1.0), math.degrees(1.5), 1.0,
                   *(5.0,) * (2 * count)),
                  build, held, sources)


FAMILIES = "beckmann, ggx, oren-nayar, phong, lafortune[:K], kay-kajiya, microcylinder"


def family(spec: str, defaults: Mapping[str, Value] | None = None,
           channels: Sequence[str] = RGB_NAMES) -> tuple[str, Family]:
    """``beckmann``, ``ggx``, ``oren-nayar``, ``phong``, ``lafortune[:K]`` (K lobes,
    default 1), ``kay-kajiya`` or ``microcylinder``; ``defaults`` are the table's
    (``compare.model_defaults``: the fibre tangent and coverage, the weave's tangent
    curves), ``channels`` its channel names (``Channels.names``: one colour parameter
    per channel)."""

    defaults = defaults or {}
    name, _, k = spec.partition(":")
    if name in ("beckmann", "ggx"):
        return name, _microfacet(name, channels)
    if name == "oren-nayar":
        return name, _oren_nayar(channels)
    if name == "phong":
        return name, _phong(channels)
    if name == "kay-kajiya":
        return name, _kay_kajiya(defaults, channels)
    if name == "microcylinder":
        return name, _microcylinder(defaults, channels)
    if name == "lafortune":
        if k and not (k.isdigit() and 1 <= int(k) <= 4):
            raise InputError(f"--model {spec}: lafortune takes 1 to 4 lobes, e.g. "
                             "lafortune:2")
        return name, _lafortune(int(k or 1))
    raise InputError(f"--model {spec}: must be one of {FAMILIES}")


def fit_table(table: Any, spec: str, component: str = "total",
              start: Sequence[float] | None = None,
              progress: Callable[[FitProgress], None] | None = None) -> FitResult:
    """Fit a model family to a table.

    Parameters
    ----------
    table : BRDFTable
        Isotropic, or anisotropic (every incident azimuth is fitted).
    spec : str
        Model family (see ``family``).
    component : str
        A component of the table (``"total"``, ``"single"``, ``"order2"``, …).
    start : sequence of float, optional
        Start values, one per parameter within its range (``Family.lower``, ``upper``;
        an ``InputError`` otherwise) (default: the family's; for microfacet models α
        starts at the table's realised roughness when it has one).
    progress : callable or None
        Called after every evaluation of the model over the table with a
        ``FitProgress`` (the evaluations so far and that evaluation's χ²/dof).

    Returns
    -------
    FitResult
        The parameters and their 1σ uncertainties, χ²/dof, the median relative error
        over lobe bins, per incidence the albedo of fit and table, the fitted model and
        its bin averages (a, b, nt, np, C).
    """
    name, fam = family(spec, model_defaults(table.meta), table.channels.names)
    component = table.component(component)
    sim, err = table[component].values, table[component].errors
    eps = EPS_FRACTION * float(np.nanmax(sim))
    keep = np.isfinite(err)
    sigma = np.sqrt((err[keep] / (sim[keep] + eps)) ** 2 + REL_FLOOR**2)
    target = np.log(sim[keep] + eps)
    x0 = np.array(start if start is not None else fam.start, float)
    surface = table.meta.surface
    alpha = None if surface is None else surface.alpha_realised
    if start is None and fam.names[0] == "alpha" and alpha is not None and alpha.isotropic:
        x0[0] = alpha.alpha
    if len(x0) != len(fam.names):
        raise InputError(f"fit {name}: {len(x0)} start values for the {len(fam.names)} "
                         f"parameters ({', '.join(fam.names)})")
    for n, v, lo, hi in zip(fam.names, x0, fam.lower, fam.upper, strict=True):
        if not lo <= v <= hi:  # NaN too
            raise InputError(f"fit {name}: start {n} = {v:g} outside its range "
                             f"[{lo:g}, {hi:g}]")

    if keep.sum() <= len(x0):
        raise InputError(f"fit {name}: the {component} of this table has {int(keep.sum())} "
                         f"bins with light (a defined error), not more than the {len(x0)} "
                         "parameters to fit: nothing escaped into it to fit a model to")
    check_memory(FIT_BYTES_PER_RESIDUAL * float(keep.sum()),
                 f"fit {name}: {int(keep.sum()):,} residuals (bins with light, per channel)",
                 "fit a table of fewer bins or incidences")
    dof = max(int(keep.sum()) - len(x0), 1)
    evaluations = 0

    def residuals(p: np.ndarray) -> np.ndarray:
        nonlocal evaluations
        m = channels_of(bin_averages(fam.build(p), table.axes, SUBSAMPLES),
                        table.channels.count)[keep]
        r = (np.log(np.maximum(m, 0.0) + eps) - target) / sigma
        evaluations += 1
        if progress is not None:
            progress(FitProgress(evaluations, float(r @ r) / dof))
        return r

    try:
        result = least_squares(residuals, x0, bounds=(fam.lower, fam.upper), x_scale="jac")
    except ValueError as exc:  # scipy: residuals not finite (the model is NaN or inf there)
        raise InputError(f"fit {name}: {exc} (the model's values over this table's bins "
                         "are not finite at the start values or during the fit)") from None
    chi2 = float(np.sum(result.fun**2))
    try:
        cov = np.linalg.inv(result.jac.T @ result.jac) * max(chi2 / dof, 1.0)
        unc = np.sqrt(np.maximum(np.diag(cov), 0.0))
    except np.linalg.LinAlgError:
        unc = np.full(len(x0), np.nan)
    fitted = fam.build(result.x)
    compared = compare_table(table, fitted, component)
    proj = table.bins.projected_solid_angle[None, None, :, :, None]
    albedo_fit = (compared.model * proj).sum(axis=(2, 3))
    rows = tuple(IncidenceFit(float(np.degrees(t)), float(np.degrees(p)), albedo_fit[k, j],
                              table[component].albedo[k, j].copy())
                 for k, t in enumerate(table.theta_i) for j, p in enumerate(table.phi_i))
    return FitResult(
        model=spec if name != "lafortune" else f"lafortune:{len(x0) // 3}",  # 3 per lobe
        params=dict(zip(fam.names, result.x.tolist(), strict=True)),
        uncertainty=dict(zip(fam.names, unc.tolist(), strict=True)),
        chi2_dof=chi2 / dof, median_rel_error=compared.median_rel_error, per_theta_i=rows,
        nfev=int(result.nfev), fitted=fitted, model_bins=compared.model,
        held=dict(fam.held), held_sources=dict(fam.held_sources))
