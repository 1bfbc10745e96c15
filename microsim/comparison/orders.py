"""A table's scattering orders against Smith and Heitz et al. 2016's multiple scattering:
albedo residuals and median lobe errors, each with its error bar.

Heitz, Hanika, d'Eon & Dachsbacher 2016 ("Multiple-scattering microfacet BSDFs with the
Smith model", ACM TOG 35(4)) give every order of a Smith microsurface
(``microsim.analytic.multiple_scattering``); this module measures how far a simulated
table's orders lie from it and from single-scattering Smith. ``scripts/multiscatter_study.py``
runs it over the published recipes (docs/compare.md). The references are taken at
the surface's realised roughness pooled over its realisations and with its facets'
Fresnel (as ``microsim compare`` takes them):

- **Smith**: Torrance-Sparrow + Beckmann + height-correlated Smith (``beckmann``), the
  single-scattering model: compared with order 1, and with the total (what single
  scattering leaves out);
- **walk**: Heitz et al. 2016's multiple-scattering Smith microsurface (``beckmann-ms``),
  compared with every order and the total. Its order 1 is Smith's exactly; its higher
  orders' bin averages are ``samples`` random walks per bin (the total's random part is
  the sum of the orders', whose errors add in quadrature), its albedos the escape
  statistics of ``walks`` walks per incidence.

For every table, incidence and component (``total`` and each order):

- **albedo** (∫ f_r cos θo dωo, mean over the channels: R, G, B or a spectral table's
  wavelengths) simulated and of each reference, and the
  **residual** simulated − reference ± its standard error. For a table simulated here
  the error is the batch-means error over realisations of A_r − γ α_r (A_r: realisation
  r's albedo, α_r its realised roughness, γ = dA/dα of the reference, a central
  difference at α ± ``SLOPE_STEP`` α): the residual is taken at the pooled α, so the part
  of the tiles' spread that their own α explains is not an error of it; with the
  reference's own error in quadrature. A table read from a file holds no realisation
  sums: its error is the table's own albedo error (which also counts that part).
  The channel mean's errors are the mean of the channels' (they share rays and walks:
  the bound for fully correlated channels).
- **median lobe error**: the median of |sim − model| / model over the model's lobe bins
  (≥ 10% of its peak per channel, as ``compare``), with an error bar (the standard
  deviation of the median over ``replicates`` parametric replicates: every bin of table
  and model redrawn from a normal with its standard error), the **noise floor** (the
  median noise alone gives: the same medians with the model as the truth) and the **z
  spread** (``compare``'s, 1 for noise alone). Where the model has no lobe bins (an order
  no walk reached), they are NaN in arrays and None in the rows: "no lobe".
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from microsim.analytic.registry import parse_model_spec
from microsim.comparison.metrics import bin_averages, bin_estimate, lobe_residuals
from microsim.comparison.table_models import model_defaults
from microsim.geometry import direction
from microsim.schema import Value
from microsim.tables.components import order_range
from microsim.tables.table import lobe_of

SLOPE_STEP = 0.05
"""Relative step in α of the central difference dA/dα of a reference's albedo: small
against the curvature of A(α), large against the tiles' spread of α (2–3% here)."""


class References(NamedTuple):
    """The two references at the pooled realised α, and at α (1 ∓ ``SLOPE_STEP``)."""

    smith: Any
    walk: Any
    shifted: list[tuple[Any, Any]]
    step: float


def references(table: Any, samples: int, seed: int) -> References:
    """Smith and the walk with the table's realised α and Fresnel (``model_defaults``)."""
    defaults = model_defaults(table.meta)

    def pair(values: dict[str, Value]) -> tuple[Any, Any]:
        return (parse_model_spec("beckmann", values)[2],
                parse_model_spec(f"beckmann-ms:samples={samples},seed={seed}", values)[2])

    smith, walk = pair(defaults)
    alpha = defaults.get("alpha")
    if alpha is None:                       # anisotropic: no slope, no α adjustment
        return References(smith, walk, [], 0.0)
    shifted = [pair({**defaults, "alpha": alpha * s}) for s in (1 - SLOPE_STEP,
                                                                1 + SLOPE_STEP)]
    return References(smith, walk, shifted, 2 * SLOPE_STEP * alpha)


def incidences(table: Any) -> list[tuple[int, int, tuple]]:
    """(a, b, arguments of ``bin_average`` after the model) for every incidence, with
    the azimuth convention of ``compare_table``."""
    return [(a, b, (direction(t, p), table.bins.theta_edges, table.bins.phi_edges,
                    p if table.isotropic else 0.0))
            for a, t in enumerate(table.theta_i) for b, p in enumerate(table.phi_i)]


def model_bins(table: Any, refs: References) -> dict[tuple[str, str], tuple[np.ndarray,
                                                                             np.ndarray]]:
    """Bin averages and their standard errors, (a, b, nt, np, C), per (component,
    reference): Smith for order 1 and the total, the walk for the orders above 1 (random
    parts) and the total (Smith + the orders' random parts)."""
    shape = table["total"].values.shape
    smith = bin_averages(refs.smith, table.axes)
    random = {c: (np.zeros(shape), np.zeros(shape)) for c in table.components
              if order_range(c)[0] >= 2}
    for a, b, args in incidences(table):
        for c, (mean, err) in random.items():
            mean[a, b], err[a, b] = bin_estimate(refs.walk.with_orders(*order_range(c)),
                                                 *args)
    zero = np.zeros(shape)
    out = {("order1", "smith"): (smith, zero), ("total", "smith"): (smith, zero),
           ("total", "walk"): (smith + sum(m for m, _ in random.values()),
                               np.sqrt(sum(e**2 for _, e in random.values())))}
    out.update({(c, "walk"): v for c, v in random.items()})
    return out


def lobe_medians(sim: np.ndarray, model: np.ndarray, lobe: np.ndarray) -> np.ndarray:
    """(a, b) median of |sim − model| / |model| over each incidence's lobe bins; NaN
    where it has none."""
    rel = np.abs(sim - model) / np.where(lobe, np.abs(model), 1.0)
    flat = np.where(lobe, rel, np.nan).reshape(rel.shape[:2] + (-1,))
    some = lobe.reshape(flat.shape).any(axis=-1)
    out = np.full(some.shape, np.nan)
    out[some] = np.nanmedian(flat[some], axis=-1)
    return out


def lobe_errors(table: Any, component: str, model: np.ndarray, model_err: np.ndarray,
                rng: np.random.Generator, replicates: int) -> dict[str, np.ndarray]:
    """Per incidence (a, b): ``median`` lobe error, its replicate standard deviation
    ``median_err``, the ``noise_floor`` and the ``z_std`` (module docstring); NaN where
    the model has no lobe."""
    sim = table[component].values
    sim_err = np.nan_to_num(table[component].errors)
    lobe = lobe_of(model, (2, 3))              # per incidence and channel, as compare

    def redraw(x: np.ndarray, e: np.ndarray) -> np.ndarray:
        return x + rng.standard_normal(x.shape) * e

    median = lobe_medians(sim, model, lobe)
    spread = np.std([lobe_medians(redraw(sim, sim_err), redraw(model, model_err), lobe)
                     for _ in range(replicates)], axis=0, ddof=1)
    noise = np.hypot(sim_err, model_err)
    floor = np.mean([lobe_medians(redraw(model, noise), model, lobe)
                     for _ in range(replicates)], axis=0)
    z_std = np.full(median.shape, np.nan)
    for a, b, _ in incidences(table):
        _, z, _ = lobe_residuals(sim[a, b], table[component].errors[a, b], model[a, b],
                                 model_err[a, b], table[component].dof[a, b])
        if z.size > 1:
            z_std[a, b] = z.std(ddof=1)
    return {"median": median, "median_err": spread, "noise_floor": floor, "z_std": z_std}


def realisation_albedos(table: Any) -> tuple[np.ndarray, np.ndarray] | None:
    """Per component, each realisation's albedo (channel mean, (K, a, b), NaN where it traced
    nothing) and realised α (K,); None for a table without realisation albedos (one read
    from a file) or without a scalar α per realisation."""
    per = () if table.meta.surface is None else table.meta.surface.per_realisation
    if table["total"].realisation_albedo is None or not per or not all(
            isinstance(r.get("alpha_realised"), int | float) for r in per):
        return None
    albedo = {c: table[c].realisation_albedo.mean(axis=-1) for c in table.components}
    return albedo, np.array([r["alpha_realised"] for r in per])


def model_albedos(table: Any, refs: References, bins: dict, walks: int
                  ) -> dict[tuple[str, str], tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per (component, reference) the reference's albedo (channel mean, (a, b)), its error
    and its slope dA/dα (NaN without a scalar α): Smith's from its bin averages
    (Σ f_r Ω_proj: exact), the walk's from escapes."""
    omega = table.bins.projected_solid_angle[..., None]
    shape = table["total"].albedo.shape[:2]
    ranges = [order_range(c) for c in table.components]
    out: dict[tuple[str, str], tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    smith = (bins[("order1", "smith")][0] * omega).sum(axis=(2, 3)).mean(axis=-1)
    walk = {c: (np.zeros(shape), np.zeros(shape), np.full(shape, np.nan))
            for c in table.components}
    smith_slope = np.full(shape, np.nan)
    if refs.shifted:
        lo, hi = ((bin_averages(s, table.axes) * omega).sum(axis=(2, 3)).mean(axis=-1)
                  for s, _ in refs.shifted)
        smith_slope = (hi - lo) / refs.step
    for a, b, args in incidences(table):
        mean, err = refs.walk.albedo(args[0], walks, ranges)
        ends = [model.albedo(args[0], walks, ranges)[0] for _, model in refs.shifted]
        for j, c in enumerate(table.components):
            walk[c][0][a, b], walk[c][1][a, b] = mean[j].mean(), err[j].mean()
            if ends:
                walk[c][2][a, b] = (ends[1][j] - ends[0][j]).mean() / refs.step
    for c in ("order1", "total"):
        out[(c, "smith")] = (smith, np.zeros(shape), smith_slope)
    out.update({(c, "walk"): v for c, v in walk.items()})
    return out


def compare_orders(table: Any, label: str, samples: int, walks: int, seed: int,
                   replicates: int) -> tuple[list[dict[str, Any]], dict]:
    """Every incidence and component of a table against Smith and the walk.

    Parameters
    ----------
    table : BRDFTable
        With an order split (``[table] orders`` ≥ 2).
    label : str
        The table's name in the rows.
    samples : int
        Walks per bin of the walk's bin averages.
    walks : int
        Walks per incidence of its albedos (and of each end of their slopes).
    seed : int
        Of the walks and the replicates.
    replicates : int
        Parametric replicates of the median lobe errors.

    Returns
    -------
    rows : list of dict
        One per incidence and component (module docstring; keys ``albedo_sim``,
        ``residual_<ref>``, ``median_rel_<ref>``, … with ``_err``; ref ``smith``, ``walk``).
    bins : dict
        ``model_bins``: the references' bin averages, for figures.

    Raises
    ------
    ValueError
        If the table holds no order split.
    """
    if table.orders is None or table.orders < 2:
        raise ValueError(f"{label}: the table holds no order split (simulate it with "
                         "[table] orders >= 2)")
    refs = references(table, samples, seed)
    bins = model_bins(table, refs)
    albedos = model_albedos(table, refs, bins, walks)
    per_realisation = realisation_albedos(table)
    rng = np.random.default_rng(seed)
    surface, recipe = table.meta.surface, table.meta.recipe
    alpha = None if surface is None else surface.alpha_realised
    alpha_err = None if surface is None else surface.alpha_realised_stderr
    kinds = sorted({m.kind for m in recipe.material.values()}) if recipe is not None else []
    rows: dict[tuple[int, int, str], dict[str, Any]] = {}
    for a, b, _ in incidences(table):
        for c in table.components:
            rows[(a, b, c)] = {
                "table": label,
                "alpha_realised": None if alpha is None else alpha.to_json(),
                "alpha_realised_stderr": None if alpha_err is None else alpha_err.to_json(),
                "material": kinds,
                "realisations": int(table.realisations[a, b]),
                "rays": int(table.rays[a, b]), "error_model": table.error_model,
                "theta_i": float(np.degrees(table.theta_i[a])),
                "phi_i": float(np.degrees(table.phi_i[b])), "component": c,
                "albedo_sim": float(table[c].albedo[a, b].mean()),
                "albedo_sim_err": float(table[c].albedo_err[a, b].mean())}
    for (c, ref), (model, model_err) in bins.items():
        lobe = lobe_errors(table, c, model, model_err, rng, replicates)
        albedo, albedo_err, slope = albedos[(c, ref)]
        for (a, b), median in np.ndenumerate(lobe["median"]):
            row = rows[(a, b, c)]
            residual = row["albedo_sim"] - albedo[a, b]
            sim_err, kind = row["albedo_sim_err"], "table"
            if per_realisation is not None and np.isfinite(slope[a, b]):
                r = per_realisation[0][c][:, a, b] - slope[a, b] * per_realisation[1]
                r = r[np.isfinite(r)]
                if r.size > 1:
                    sim_err, kind = float(r.std(ddof=1) / np.sqrt(r.size)), "alpha-adjusted"
            finite = np.isfinite(median)
            row.update({
                f"albedo_{ref}": float(albedo[a, b]),
                f"albedo_{ref}_err": float(albedo_err[a, b]),
                f"albedo_{ref}_slope": float(slope[a, b]),
                f"residual_{ref}": residual,
                f"residual_{ref}_err": float(np.hypot(sim_err, albedo_err[a, b])),
                f"residual_{ref}_error_model": kind,
                f"median_rel_{ref}": float(median) if finite else None,
                f"median_rel_{ref}_err": float(lobe["median_err"][a, b]) if finite else None,
                f"noise_floor_{ref}": float(lobe["noise_floor"][a, b]) if finite else None,
                f"z_std_{ref}": float(lobe["z_std"][a, b]) if finite else None})
    for (c, ref), (albedo, albedo_err, _) in albedos.items():   # the walk's order 1 too
        for (a, b), value in np.ndenumerate(albedo):
            rows[(a, b, c)].setdefault(f"albedo_{ref}", float(value))
            rows[(a, b, c)].setdefault(f"albedo_{ref}_err", float(albedo_err[a, b]))
    return list(rows.values()), bins
