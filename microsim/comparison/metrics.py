"""Simulated against analytic: a model averaged over the table's bins, and the metrics.

A table bin holds the projected-solid-angle average of f_r over the bin (that is what the
goniophotometer estimates: weight in the bin / rays / ∫_bin cos θo dω). Comparing it with
the model at the bin centre would charge the model with the curvature of the lobe inside
the bin, so the model is averaged over each bin the same way: in the coordinates
u = sin²θo, φo the projected solid angle is uniform (cos θ dω = ½ du dφ), so the average is
the mean over an ``n × n`` midpoint grid in (u, φ) inside the bin; in the bin at the
horizon, n Gauss-Legendre nodes in s = cos θo weighted by s (cos θ dω = s ds dφ), exact
where f_r grows as 1/cos θo towards the horizon, as fibre layers seen edge-on do.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import replace
from typing import Protocol

import numpy as np

from microsim.analytic.brdf import as_rgb
from microsim.comparison.records import Comparison, IncidenceMetrics
from microsim.comparison.table_models import microfacet_model, model_defaults
from microsim.errors import InputError
from microsim.geometry import direction
from microsim.schema import Value
from microsim.spectra.channels import Channels
from microsim.surfaces.facts import SurfaceFacts, TileFacts
from microsim.tables.binning import HemisphereBins
from microsim.tables.components import order_range
from microsim.tables.evaluate import Axes
from microsim.tables.meta import TableMeta
from microsim.tables.table import LOBE_FRACTION, BRDFTable, ComponentEstimate, lobe_of

__all__ = ["LOBE_FRACTION", "Comparison", "IncidenceMetrics", "Model", "StochasticModel",
           "bin_average", "bin_averages", "bin_estimate", "compare_table", "direction",
           "lobe_residuals", "metrics", "microfacet_model", "model_defaults", "model_for",
           "model_table", "normal_z", "residual_statistics", "singular_albedo"]
"""``direction``, ``LOBE_FRACTION``, ``microfacet_model`` and ``model_defaults`` are
``microsim.geometry``'s, ``microsim.tables.table``'s and ``microsim.comparison.table_models``'s, and
``Comparison`` and ``IncidenceMetrics`` ``microsim.comparison.records``'s, named here too for the
scripts that compare tables with models."""


class Model(Protocol):
    """Anything with ``eval(wi, wo) -> (...,) or (..., 3)`` f_r in 1/sr.

    A model with a singular part (a delta: mirror cylinders' specular cone) also has
    ``singular(wi, theta_edges, phi_edges, phi_i) -> (nt, np, 3)``, that part's bin
    averages, which ``bin_average`` adds to the regular part's.
    """

    def eval(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray: ...


class StochasticModel(Model, Protocol):
    """A Monte Carlo model: an exact part (a ``Model``, or None) plus a random part whose
    bin averages come with standard errors (``SmithMultipleScattering``)."""

    exact: Model | None

    def random_bin_average(self, wi: np.ndarray, theta_edges: np.ndarray,
                           phi_edges: np.ndarray, phi_i: float = 0.0
                           ) -> tuple[np.ndarray, np.ndarray]: ...


CHUNK_POINTS = 1 << 18
"""Outgoing directions ``bin_average`` evaluates a model at, at most, at once: 200-320 B
each while a model evaluates (tracemalloc peak of Beckmann, RGB Beckmann, Oren-Nayar,
the cloth model), so at most about 84 MB whatever the table's bins."""


def bin_average(model: Model, wi: np.ndarray, theta_edges: np.ndarray,
                phi_edges: np.ndarray, phi_i: float = 0.0, n: int = 8) -> np.ndarray:
    """Projected-solid-angle average of a model's f_r over every outgoing bin, rows of θo
    bins at a time (at most ``CHUNK_POINTS`` directions, or one row).

    Parameters
    ----------
    model : Model
        The analytic BRDF.
    wi : (3,) float
        Incident direction (towards the light).
    theta_edges : (nt + 1,) float
        Bin edges in θo, radians.
    phi_edges : (np + 1,) float
        Bin edges in φo − φi, radians.
    phi_i : float
        Incident azimuth: the outgoing azimuth is ``phi_i`` + the table's relative φ.
    n : int
        Midpoints per bin and axis.

    Returns
    -------
    (nt, np, 3) float
        The average f_r per bin and colour, 1/sr.
    """
    t = (np.arange(n) + 0.5) / n
    u_lo, u_hi = np.sin(theta_edges[:-1]) ** 2, np.sin(theta_edges[1:]) ** 2
    u = u_lo[:, None] + (u_hi - u_lo)[:, None] * t  # (nt, n)
    theta = np.arcsin(np.sqrt(np.clip(u, 0.0, 1.0)))
    weight = np.full(theta.shape, 1.0 / n)
    if theta_edges[-1] >= np.pi / 2 - 1e-9:
        # the bin at the horizon: Gauss-Legendre in s = cos θo with weight s (cos θ dω =
        # s ds dφ), exact where f_r grows as 1/cos θo (fibre layers seen edge-on), whose
        # average midpoints in sin²θo underestimate by ~5% at n = 8
        x, w = np.polynomial.legendre.leggauss(n)
        top = np.cos(theta_edges[-2])
        s = top * (x + 1) / 2
        theta[-1] = np.arccos(s)
        weight[-1] = w * s / np.sum(w * s)
    p = phi_edges[:-1, None] + np.diff(phi_edges)[:, None] * t  # (np, n)
    rows = max(1, CHUNK_POINTS // (len(p) * n * n))
    parts = []
    for start in range(0, len(theta), rows):
        part = slice(start, start + rows)
        wo = direction(theta[part, None, :, None], phi_i + p[None, :, None, :])  # (r, np, n, n, 3)
        f = as_rgb(model.eval(np.broadcast_to(wi, wo.shape), wo), wo.shape[:-1])
        parts.append(np.einsum("tpijc,ti->tpc", f, weight[part]) / n)
    f = np.concatenate(parts)
    if hasattr(model, "singular"):
        f = f + model.singular(wi, theta_edges, phi_edges, phi_i)
    return f


def bin_averages(model: Model, axes: Axes, n: int = 8) -> np.ndarray:
    """``bin_average`` at every incidence of a table's axes.

    Parameters
    ----------
    model : Model
    axes : Axes
        The table's (``BRDFTable.axes``): outgoing azimuths relative to φi when
        isotropic, absolute otherwise.
    n : int
        Midpoints per bin and axis.

    Returns
    -------
    (a, b, nt, np, 3) float
        1/sr, θi outer, φi inner.
    """
    return np.stack([np.stack([bin_average(model, direction(t, p), axes.bins.theta_edges,
                                           axes.bins.phi_edges,
                                           p if axes.isotropic else 0.0, n)
                               for p in axes.phi_i]) for t in axes.theta_i])


def singular_albedo(model: Model, wi: np.ndarray) -> float:
    """The share of the incident power in a model's singular part (0 without one): its
    average over the hemisphere as one bin, times π."""
    if not hasattr(model, "singular"):
        return 0.0
    whole = model.singular(wi, np.array([0.0, np.pi / 2]), np.array([0.0, 2 * np.pi]))
    return float(np.pi * whole.mean())


NORMAL_DOF = 1e5
"""Above this many degrees of freedom a Student-t z-score is taken as normal."""


def normal_z(t: np.ndarray, dof: np.ndarray | float) -> np.ndarray:
    """The standard normal quantile with the probability of a Student-t score:
    Φ⁻¹(F_ν(t)), so z-scores of errors with few degrees of freedom (an ensemble of few
    realisations, ``microsim.tables.estimator``) have unit spread under the null.
    NaN where ν ≤ 0: an error of no degrees of freedom (an ensemble whose jackknife is
    undefined) says nothing of the spread, so no score can be given."""
    dof = np.broadcast_to(np.asarray(dof, float), np.shape(t))
    if np.all(dof >= NORMAL_DOF):
        return np.asarray(t, float)
    from scipy import stats

    # through the smaller tail, so large |t| keep their precision; where that tail
    # underflows (|t| in the tens or more) t itself stands, a finite bound
    p = stats.t.sf(np.abs(t), dof)
    z = np.sign(t) * stats.norm.isf(p)  # isf(0) = inf, without a warning
    return np.where(dof <= 0, np.nan, np.where((dof >= NORMAL_DOF) | ~np.isfinite(z), t, z))


def bin_estimate(model: Model, wi: np.ndarray, theta_edges: np.ndarray,
                 phi_edges: np.ndarray, phi_i: float = 0.0, n: int = 8
                 ) -> tuple[np.ndarray, np.ndarray]:
    """A model's bin averages with their standard errors.

    An analytic model's averages are ``bin_average``'s, with zero error; a
    ``StochasticModel``'s are its exact part's ``bin_average`` plus its random part's
    unbiased Monte Carlo averages (``random_bin_average``), whose errors they carry.

    Parameters
    ----------
    model, wi, theta_edges, phi_edges, phi_i, n
        As ``bin_average``.

    Returns
    -------
    mean, stderr : (nt, np, C) float
        1/sr, in the model's channels (3 for a grey one).
    """
    shape = (len(theta_edges) - 1, len(phi_edges) - 1)
    random_part = getattr(model, "random_bin_average", None)
    if random_part is None:
        mean = bin_average(model, wi, theta_edges, phi_edges, phi_i, n)
        return mean, np.zeros_like(mean)
    mean, err = (as_rgb(x, shape) for x in random_part(wi, theta_edges, phi_edges, phi_i))
    if model.exact is not None:
        mean = mean + bin_average(model.exact, wi, theta_edges, phi_edges, phi_i, n)
    return mean, err


def channels_of(values: np.ndarray, count: int) -> np.ndarray:
    """A model's (..., C') bin averages as the table's C channels: as they are when
    C' = C; a grey model's (its channels equal) repeated.

    Raises
    ------
    InputError
        For a model whose channels differ and are not the table's (RGB parameters against
        a spectral table).
    """
    if values.shape[-1] == count:
        return values
    if np.array_equal(values, np.broadcast_to(values[..., :1], values.shape)):
        return np.broadcast_to(values[..., :1], values.shape[:-1] + (count,))
    raise InputError(f"the model has {values.shape[-1]} colour channels, the table "
                     f"{count}: give the model's colour parameters (eta, k, albedo) as one "
                     "number, or leave them out to take the table's own per channel")


RGB_ONLY_MODELS = ("cylinders", "velvet-sparse", "microcylinder")
"""Models that compute R, G and B only (``microsim.analytic.cylinders``,
``microsim.analytic.cloth``): their colour parameters take one or three values."""


def check_model_channels(spec: str, defaults: Mapping[str, Value] | None,
                         channels: Channels | None, flag: str = "--model") -> None:
    """Refuse, before it is built, an RGB-only model (``RGB_ONLY_MODELS``) with colour
    parameters (the spec's, else the table's ``defaults``) it cannot compute: of other
    than one or three (R, G, B) values, or, for a spectral table, differing between its
    wavelengths (the same model with grey parameters, one value, compares with every
    wavelength).

    Parameters
    ----------
    spec : str
        The model spec, ``NAME[:key=value,...]``.
    defaults : mapping or None
        The table's (``microsim.comparison.table_models.model_defaults``), or None.
    channels : Channels or None
        The table's channels; None without a table (``microsim models eval``).
    flag : str
        How the error names the spec.

    Raises
    ------
    InputError
        Naming the flag, the parameters and what they may be.
    """
    from microsim.analytic.registry import MODELS, split_spec

    name, given = split_spec(spec, "model")
    if name not in RGB_ONLY_MODELS:
        return
    keys = MODELS[name].params
    merged = {k: v for k, v in (defaults or {}).items() if k in keys}
    merged.update(getattr(defaults, "for_model", {}).get(name, {}))
    merged.update(given)
    spectral = channels is not None and channels.spectral
    values = {}
    for k, key in keys.items():
        if key.kind == "channels" and merged.get(k) is not None:
            try:
                values[k] = np.ravel(np.asarray(merged[k], float))
            except (TypeError, ValueError):
                pass                 # not numbers: parse_model_spec says what is allowed
    if spectral:
        coloured = [k for k, v in values.items() if np.unique(v).size > 1]
        if coloured:
            raise InputError(f"{flag} {spec}: the {name} model computes R, G and B only, "
                             f"and {', '.join(coloured)} differ between this table's "
                             f"{channels.count} wavelengths; give each one number (e.g. "
                             f"{name}:{coloured[0]}=0.5), the same in every wavelength")
    else:
        coloured = [k for k, v in values.items() if v.size not in (1, 3)]
        if coloured:
            raise InputError(f"{flag} {spec}: the {name} model computes R, G and B only; "
                             f"{', '.join(coloured)} must be one number or three (R, G, B)")


def lobe_residuals(sim: np.ndarray, err: np.ndarray, model: np.ndarray,
                   model_err: np.ndarray | None = None, dof: np.ndarray | float = np.inf
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Relative errors and z-scores over the model's lobe bins.

    Parameters
    ----------
    sim, err, model : (nt, np, 3) float
        Simulated f_r, its standard error (NaN where undefined), the model's bin average.
    model_err : (nt, np, 3) float or None
        The model's own standard error (a Monte Carlo model); None: exact.
    dof : (3,) float or float
        Degrees of freedom of the errors per channel (``BRDFTable.dof``); the z-scores
        are Student-t scores mapped to normal ones (``normal_z``), with the model's
        error (of many degrees of freedom) by Welch-Satterthwaite.

    Returns
    -------
    rel : (k,) float
        |sim − model| / model over lobe bins (model ≥ 10% of its peak, per channel).
    z : (j,) float
        normal_z((sim − model) / √(stderr² + model_err²)) over lobe bins with a defined,
        non-zero error of some degrees of freedom (ν > 0; a NaN ν is taken as normal):
        the two estimates are independent, so their variances add.
    lobe : (nt, np, 3) bool
    """
    lobe = lobe_of(model, (0, 1))
    rel = np.abs(sim - model)[lobe] / model[lobe]
    nu = np.broadcast_to(np.asarray(dof, float), sim.shape)
    if model_err is not None:
        # Welch-Satterthwaite with the model's error known to many degrees of freedom:
        # ν = (e² + m²)² / (e⁴ / ν_sim)
        with np.errstate(invalid="ignore", divide="ignore"):
            nu = nu * (1 + (model_err / err) ** 2) ** 2
        err = np.hypot(err, model_err)
    ok = lobe & np.isfinite(err) & (err > 0) & ~(nu <= 0)
    return rel, normal_z((sim - model)[ok] / err[ok], np.nan_to_num(nu[ok], nan=np.inf)), lobe


def residual_statistics(rel: np.ndarray, z: np.ndarray) -> tuple[float, float, float, float]:
    """Median and 90th percentile of relative errors, mean and sample standard deviation
    of z-scores, as ``lobe_residuals`` gives them; NaN where there are too few (none; one
    for the standard deviation).

    Parameters
    ----------
    rel : (k,) float
    z : (j,) float

    Returns
    -------
    median_rel_error, p90_rel_error, z_mean, z_std : float
    """
    nan = float("nan")
    return (float(np.median(rel)) if rel.size else nan,
            float(np.percentile(rel, 90)) if rel.size else nan,
            float(z.mean()) if z.size else nan,
            float(z.std(ddof=1)) if z.size > 1 else nan)


def metrics(sim: np.ndarray, err: np.ndarray, model: np.ndarray,
            proj: np.ndarray, model_err: np.ndarray | None = None,
            dof: np.ndarray | float = np.inf) -> IncidenceMetrics:
    """Error metrics of one incidence's simulated bins against the model's bin averages.

    Parameters
    ----------
    sim, err, model : (nt, np, 3) float
        Simulated f_r, its standard error (NaN where undefined), the model's bin average.
    proj : (nt, np) float
        Projected solid angle of each bin, sr.
    model_err : (nt, np, 3) float or None
        The model's own standard error (None: exact).
    dof : (3,) float or float
        Degrees of freedom of the errors (``lobe_residuals``).

    Returns
    -------
    IncidenceMetrics
        Relative errors over lobe bins (model ≥ 10% of its peak), the RMS error over all
        bins, the z-scores' mean and spread, the albedos per channel (Σ f_r Ω_proj) and the
        model's standard error of its albedo (√Σ (σ Ω_proj)², bins being independent
        estimates); no incidence (``theta_i`` and the rest None).
    """
    return _metrics(sim, err, model, proj, model_err, dof)[0]


def _metrics(sim: np.ndarray, err: np.ndarray, model: np.ndarray, proj: np.ndarray,
             model_err: np.ndarray | None, dof: np.ndarray | float
             ) -> tuple[IncidenceMetrics, np.ndarray, np.ndarray]:
    """``metrics`` with the lobe bins' relative errors and z-scores it was made from
    (``lobe_residuals``), which ``compare_table`` pools over incidences."""
    rel, z, lobe = lobe_residuals(sim, err, model, model_err, dof)
    median, p90, z_mean, z_std = residual_statistics(rel, z)
    albedo_sim = (sim * proj[..., None]).sum(axis=(0, 1))
    albedo_model = (model * proj[..., None]).sum(axis=(0, 1))
    albedo_model_err = np.zeros(sim.shape[-1]) if model_err is None else np.sqrt(
        ((model_err * proj[..., None]) ** 2).sum(axis=(0, 1)))
    return IncidenceMetrics(
        median_rel_error=median, p90_rel_error=p90,
        rms_error=float(np.sqrt(np.mean((sim - model) ** 2))), z_mean=z_mean, z_std=z_std,
        lobe_bins=int(lobe[..., 0].sum()), albedo_sim=albedo_sim, albedo_model=albedo_model,
        albedo_difference=albedo_sim - albedo_model, albedo_model_err=albedo_model_err
    ), rel, z


def model_table(model: Model, theta_i: np.ndarray, bins: HemisphereBins,
                sigma_rel: float = 0.0, rng: np.random.Generator | None = None,
                meta: TableMeta | None = None, phi_i: np.ndarray | None = None,
                channels: Channels | None = None) -> BRDFTable:
    """A table whose bins hold an analytic model's bin averages: a noiseless reference,
    or one with Gaussian noise of known relative standard deviation.

    Parameters
    ----------
    model : Model
        The analytic BRDF.
    theta_i : (a,) float
        Incident polar angles, radians.
    bins : HemisphereBins
        Outgoing bins.
    sigma_rel : float
        Relative standard deviation of the noise added to each bin and channel (0: none);
        the bins' standard error is reported as ``sigma_rel`` × the bin average (with a
        floor of 1e-12 so no error is zero). A noisy value is clipped at 0: f_r is never
        negative (``microsim.tables.validation``), and only bins whose average is within
        the noise of 0 are clipped.
    rng : numpy.random.Generator or None
        Source of the noise (required when ``sigma_rel`` > 0).
    meta : TableMeta or None
        The table's metadata (default: a surface of kind ``"analytic"``).
    phi_i : (b,) float or None
        None: an isotropic table (incidences at φi = 0, outgoing azimuths relative to it).
        Otherwise the incident azimuths (radians, increasing, within [0, 2π)) of an
        anisotropic table with absolute outgoing azimuths.
    channels : Channels or None
        The table's channels (default: RGB); a grey model fills each of them, a model of
        per-channel values must give one per channel (``channels_of``).

    Returns
    -------
    BRDFTable
        Components ``total`` and ``single`` alike; albedo = Σ f_r Ω_proj over the bins of
        the (noisy) values, with zero error; no lost energy; a nominal 10⁶ rays per
        direction (many: its errors are known, ``NORMAL_DOF``).
    """
    theta_i = np.asarray(theta_i, float)
    azimuths = np.zeros(1) if phi_i is None else np.asarray(phi_i, float)
    avg = bin_averages(model, Axes(bins, theta_i, azimuths, phi_i is None))
    if channels is not None:
        avg = np.array(channels_of(avg, channels.count))
    err = sigma_rel * avg + 1e-12
    values = np.maximum(avg + rng.standard_normal(avg.shape) * err, 0.0) if sigma_rel else avg
    albedo = (values * bins.projected_solid_angle[None, None, :, :, None]).sum(axis=(2, 3))
    zeros = np.zeros_like(albedo)
    estimate = ComponentEstimate(values, err, albedo, zeros)
    return BRDFTable(bins, theta_i, azimuths, phi_i is None,
                     dict.fromkeys(("total", "single"), estimate),
                     np.full(avg.shape[:2], 10**6), zeros,
                     meta or TableMeta(surface=SurfaceFacts(TileFacts(kind="analytic"))),
                     **({} if channels is None else {"channels": channels}))


def model_for(model: Model, component: str) -> Model:
    """The model to compare with a table's ``component``: a model that holds chosen
    scattering orders (``with_orders``) restricted to the component's; any other as is."""
    return model.with_orders(*order_range(component)) if hasattr(model, "with_orders") \
        else model


def compare_table(table: BRDFTable, model: Model, component: str = "total",
                  progress: Callable[[int, int], None] | None = None) -> Comparison:
    """Every incidence of a table against a model: per-incidence and pooled metrics.

    Parameters
    ----------
    table : BRDFTable
    model : Model
    component : str
        A component of the table (``"total"``, ``"single"``, ``"order2"``, …). A model
        that holds chosen scattering orders (``with_orders``: ``beckmann-ms``) is
        compared with the same orders.
    progress : callable or None
        ``progress(done, incidences)`` after each incidence's bin averages.

    Returns
    -------
    Comparison
        The metrics pooled over every incidence's lobe bins (z against both errors,
        ``lobe_residuals``); the table's error model, realisations (the most of any
        incidence) and degrees of freedom (the fewest of a bin's error); per incidence
        ``metrics`` with θi, φi (degrees) and the multiple-scattering share of the
        simulation; the model's bin averages and their standard errors, (a, b, nt, np, 3).
    """
    component = table.component(component)
    model = model_for(model, component)
    rows, rels, zs = [], [], []
    averages = np.zeros_like(table[component].values)
    errors = np.zeros_like(averages)
    for a, theta in enumerate(table.theta_i):
        for b, phi in enumerate(table.phi_i):
            # isotropic tables hold azimuths relative to phi_i, anisotropic ones absolute;
            # a folded table's bins hold phi and -phi alike, which a model symmetric about
            # the plane of incidence fills equally
            avg, avg_err = (channels_of(x, table.channels.count) for x in bin_estimate(
                model, direction(theta, phi), table.bins.theta_edges, table.bins.phi_edges,
                phi if table.isotropic else 0.0))
            averages[a, b], errors[a, b] = avg, avg_err
            sim, err = table[component].values[a, b], table[component].errors[a, b]
            m, rel, z = _metrics(sim, err, avg, table.bins.projected_solid_angle, avg_err,
                                 table[component].dof[a, b])
            rels.append(rel)
            zs.append(z)
            total = table["total"].albedo[a, b].mean()
            single = table["single"].albedo[a, b].mean()
            rows.append(replace(m, theta_i=float(np.degrees(theta)),
                                phi_i=float(np.degrees(phi)),
                                multiple_scattering_share=float((total - single) / total)
                                if total > 0 else float("nan")))
            if progress is not None:
                progress(len(rows), len(table.theta_i) * len(table.phi_i))
    median, p90, z_mean, z_std = residual_statistics(np.concatenate(rels), np.concatenate(zs))
    return Comparison(
        median_rel_error=median, p90_rel_error=p90, z_mean=z_mean, z_std=z_std,
        error_model=table.error_model, realisations=int(table.realisations.max()),
        dof=float(table[component].dof.min()), per_theta_i=tuple(rows), model=averages,
        model_err=errors)
