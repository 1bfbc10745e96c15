"""Simulated against analytic: a model averaged over the table's bins, and the metrics.

A table bin holds the projected-solid-angle average of f_r over the bin (that is what the
goniophotometer estimates: weight in the bin / rays / ∫_bin cos θo dω). Comparing it with
the model at the bin centre would charge the model with the curvature of the lobe inside
the bin, so the model is averaged over each bin the same way: in the coordinates
u = sin²θo, φo the projected solid angle is uniform (cos θ dω = ½ du dφ), so the average is
the mean over an ``n × n`` midpoint grid in (u, φ) inside the bin.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol

import numpy as np

LOBE_FRACTION = 0.1
"""Lobe bins: those where the model's bin average is at least this fraction of its peak."""


class Model(Protocol):
    """Anything with ``eval(wi, wo) -> (...,) or (..., 3)`` f_r in 1/sr."""

    def eval(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray: ...


def direction(theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Unit vectors from polar angles.

    Parameters
    ----------
    theta, phi : (...) float
        Polar angle from +z and azimuth from +x towards +y, radians.

    Returns
    -------
    (..., 3) float
    """
    theta, phi = np.broadcast_arrays(np.asarray(theta, float), np.asarray(phi, float))
    s = np.sin(theta)
    return np.stack([s * np.cos(phi), s * np.sin(phi), np.cos(theta)], axis=-1)


def half_difference(theta_h: np.ndarray, theta_d: np.ndarray, phi_d: float
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(ωi, ωo) from Rusinkiewicz's half/difference angles with φh = 0 (Rusinkiewicz
    1998, "A new change of variables for efficient BRDF representation", sec. 3): the
    difference vector d(θd, φd) in the half vector's frame, rotated by θh about y; ωo is
    d mirrored about h.

    Returns
    -------
    wi, wo : (..., 3) float
    """
    d = direction(theta_d, phi_d)
    e = d * np.array([-1.0, -1.0, 1.0])
    c, s = np.cos(theta_h)[..., None], np.sin(theta_h)[..., None]

    def rot(v: np.ndarray) -> np.ndarray:
        return np.stack([c[..., 0] * v[..., 0] + s[..., 0] * v[..., 2], v[..., 1],
                         -s[..., 0] * v[..., 0] + c[..., 0] * v[..., 2]], axis=-1)

    return rot(d), rot(e)


def _rgb(values: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """Broadcast a model's scalar or RGB output to ``shape + (3,)``."""
    values = np.asarray(values, float)
    if values.shape == shape:
        values = values[..., None]
    return np.broadcast_to(values, shape + (3,))


def bin_average(model: Model, wi: np.ndarray, theta_edges: np.ndarray,
                phi_edges: np.ndarray, phi_i: float = 0.0, n: int = 8) -> np.ndarray:
    """Projected-solid-angle average of a model's f_r over every outgoing bin.

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
    p = phi_edges[:-1, None] + np.diff(phi_edges)[:, None] * t  # (np, n)
    theta = np.arcsin(np.sqrt(np.clip(u, 0.0, 1.0)))
    wo = direction(theta[:, None, :, None], phi_i + p[None, :, None, :])  # (nt, np, n, n, 3)
    f = _rgb(model.eval(np.broadcast_to(wi, wo.shape), wo), wo.shape[:-1])
    return f.mean(axis=(2, 3))


def lobe_residuals(sim: np.ndarray, err: np.ndarray, model: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Relative errors and z-scores over the model's lobe bins.

    Parameters
    ----------
    sim, err, model : (nt, np, 3) float
        Simulated f_r, its standard error (NaN where undefined), the model's bin average.

    Returns
    -------
    rel : (k,) float
        |sim − model| / model over lobe bins (model ≥ 10% of its peak, per channel).
    z : (j,) float
        (sim − model) / stderr over lobe bins with a defined, non-zero error.
    lobe : (nt, np, 3) bool
    """
    peak = model.max(axis=(0, 1), keepdims=True)
    lobe = model >= LOBE_FRACTION * np.where(peak > 0, peak, np.inf)
    rel = np.abs(sim - model)[lobe] / model[lobe]
    ok = lobe & np.isfinite(err) & (err > 0)
    return rel, (sim - model)[ok] / err[ok], lobe


def metrics(sim: np.ndarray, err: np.ndarray, model: np.ndarray,
            proj: np.ndarray) -> dict[str, Any]:
    """Error metrics of one incidence's simulated bins against the model's bin averages.

    Parameters
    ----------
    sim, err, model : (nt, np, 3) float
        Simulated f_r, its standard error (NaN where undefined), the model's bin average.
    proj : (nt, np) float
        Projected solid angle of each bin, sr.

    Returns
    -------
    dict
        ``median_rel_error`` and ``p90_rel_error`` over lobe bins (model ≥ 10% of its
        peak), ``rms_error`` (1/sr, all bins), ``z_mean`` and ``z_std`` of
        (sim − model)/stderr over lobe bins with a defined, non-zero error, ``lobe_bins``,
        ``albedo_sim`` and ``albedo_model`` per channel (Σ f_r Ω_proj), and their difference.
    """
    rel, z, lobe = lobe_residuals(sim, err, model)
    albedo_sim = (sim * proj[..., None]).sum(axis=(0, 1))
    albedo_model = (model * proj[..., None]).sum(axis=(0, 1))
    nan = float("nan")
    return {
        "median_rel_error": float(np.median(rel)) if rel.size else nan,
        "p90_rel_error": float(np.percentile(rel, 90)) if rel.size else nan,
        "rms_error": float(np.sqrt(np.mean((sim - model) ** 2))),
        "z_mean": float(z.mean()) if z.size else nan,
        "z_std": float(z.std(ddof=1)) if z.size > 1 else nan,
        "lobe_bins": int(lobe[..., 0].sum()),
        "albedo_sim": albedo_sim.tolist(),
        "albedo_model": albedo_model.tolist(),
        "albedo_difference": (albedo_sim - albedo_model).tolist(),
    }


def fresnel_of(material: Mapping[str, Any]) -> tuple | None:
    """The ``TorranceSparrow`` Fresnel argument for a resolved facet material: None for a
    mirror (F = 1), ``("conductor", eta, k)`` or ``("dielectric", eta)``."""
    kind = material["kind"]
    if kind == "mirror":
        return None
    if kind == "conductor":
        return ("conductor", np.asarray(material["eta"]), np.asarray(material["k"]))
    if kind == "dielectric":
        return ("dielectric", float(material["eta"]))
    raise ValueError(f"a {kind} facet has no microfacet model")


def microfacet_model(meta: Mapping[str, Any]) -> Model:
    """Torrance-Sparrow with a Beckmann NDF at the surface's realised roughness and
    height-correlated Smith masking: the model a Gaussian surface's single scattering is
    meant to follow (Walter et al. 2007, eq. 20; Heitz 2014, eq. 99).

    Parameters
    ----------
    meta : mapping
        A table's metadata: ``surface.alpha_realised`` (a number, or [αx, αy]) and the
        recipe's material of the part ``base``.
    """
    from microsim.analytic.brdf import TorranceSparrow
    from microsim.analytic.ndf import Beckmann

    alpha = meta["surface"]["alpha_realised"]
    ndf = (Beckmann(alpha_x=alpha[0], alpha_y=alpha[1]) if isinstance(alpha, list)
           else Beckmann(alpha))
    material = meta["recipe"]["material"]["base"]
    return TorranceSparrow(ndf, fresnel=fresnel_of(material), shadowing="smith-correlated")


def ndf_bin_average(ndf: Any, edges: np.ndarray, n: int = 16) -> np.ndarray:
    """Bin averages ∫_B D cos θ dω / ∫_B cos θ dω of an isotropic NDF over θ bins.

    Parameters
    ----------
    ndf : NDF
        With ``D(m)``.
    edges : (k + 1,) float
        Bin edges in θ, radians.
    n : int
        Gauss-Legendre nodes per bin.

    Returns
    -------
    (k,) float
    """
    x, w = np.polynomial.legendre.leggauss(n)
    lo, hi = edges[:-1, None], edges[1:, None]
    t = lo + (hi - lo) * (x + 1) / 2
    weights = w * (hi - lo) / 2 * np.cos(t) * np.sin(t)
    return (ndf.D(direction(t, 0.0)) * weights).sum(axis=1) / weights.sum(axis=1)


def model_defaults(meta: Mapping[str, Any]) -> dict[str, Any]:
    """Model parameters a table's metadata implies: the realised roughness (``alpha``, or
    ``alpha_x``/``alpha_y``) and, when every part has the same material, its Fresnel
    (``eta``, ``k``) or Lambertian ``albedo``. A spec's own values override these."""
    out: dict[str, Any] = {}
    alpha = meta.get("surface", {}).get("alpha_realised")
    if isinstance(alpha, list):
        out.update(alpha_x=alpha[0], alpha_y=alpha[1])
    elif alpha is not None:
        out["alpha"] = alpha
    materials = list(meta.get("recipe", {}).get("material", {}).values())
    if materials and all(m == materials[0] for m in materials):
        m = materials[0]
        out.update({k: m[k] for k in ("eta", "k", "albedo") if k in m})
    return out


def model_table(model: Model, theta_i: np.ndarray, bins: Any, sigma_rel: float = 0.0,
                rng: np.random.Generator | None = None,
                meta: Mapping[str, Any] | None = None,
                phi_i: np.ndarray | None = None) -> Any:
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
        floor of 1e-12 so no error is zero).
    rng : numpy.random.Generator or None
        Source of the noise (required when ``sigma_rel`` > 0).
    meta : mapping or None
        The table's metadata (default: a surface of kind ``"analytic"``).
    phi_i : (b,) float or None
        None: an isotropic table (incidences at φi = 0, outgoing azimuths relative to it).
        Otherwise the incident azimuths (radians, increasing, within [0, 2π)) of an
        anisotropic table with absolute outgoing azimuths.

    Returns
    -------
    BRDFTable
        Components ``total`` and ``single`` alike; albedo = Σ f_r Ω_proj over the bins of
        the (noisy) values, with zero error; no lost energy.
    """
    from microsim.tables.table import COMPONENTS, BRDFTable

    theta_i = np.asarray(theta_i, float)
    azimuths = np.zeros(1) if phi_i is None else np.asarray(phi_i, float)
    avg = np.stack([np.stack([bin_average(model, direction(t, p), bins.theta_edges,
                                          bins.phi_edges) for p in azimuths])
                    for t in theta_i])
    err = sigma_rel * avg + 1e-12
    values = avg + rng.standard_normal(avg.shape) * err if sigma_rel else avg
    albedo = (values * bins.projected_solid_angle[None, None, :, :, None]).sum(axis=(2, 3))
    zeros = np.zeros_like(albedo)
    return BRDFTable(bins, theta_i, azimuths, phi_i is None, {c: values for c in COMPONENTS},
                     {c: err for c in COMPONENTS}, np.full(avg.shape[:2], 10**6),
                     {c: albedo for c in COMPONENTS}, {c: zeros for c in COMPONENTS},
                     zeros, dict(meta or {"surface": {"kind": "analytic"}}))


def compare_table(table: Any, model: Model, component: str = "total") -> dict[str, Any]:
    """Every incidence of a table against a model: per-incidence and pooled metrics.

    Parameters
    ----------
    table : BRDFTable
    model : Model
    component : str
        ``"total"`` or ``"single"``.

    Returns
    -------
    dict
        ``median_rel_error``, ``p90_rel_error``, ``z_mean``, ``z_std`` pooled over every
        incidence's lobe bins; ``per_theta_i``: one row per incident direction with
        ``theta_i``, ``phi_i`` (degrees), the ``metrics`` keys and
        ``multiple_scattering_share`` (the share of the escaping energy scattered more
        than once: what a single-scattering model leaves out); ``model`` (per-bin bin
        averages, (a, b, nt, np, 3)) for plots.
    """
    rows, rels, zs = [], [], []
    averages = np.zeros_like(table.values[component])
    for a, theta in enumerate(table.theta_i):
        for b, phi in enumerate(table.phi_i):
            # isotropic tables hold azimuths relative to phi_i, anisotropic ones absolute;
            # a folded table's bins hold phi and -phi alike, which a model symmetric about
            # the plane of incidence fills equally
            avg = bin_average(model, direction(theta, phi), table.bins.theta_edges,
                              table.bins.phi_edges, phi if table.isotropic else 0.0)
            averages[a, b] = avg
            sim, err = table.values[component][a, b], table.errors[component][a, b]
            rel, z, _ = lobe_residuals(sim, err, avg)
            rels.append(rel)
            zs.append(z)
            m = metrics(sim, err, avg, table.bins.projected_solid_angle)
            total = table.albedo_of["total"][a, b].mean()
            single = table.albedo_of["single"][a, b].mean()
            m.update(theta_i=float(np.degrees(theta)), phi_i=float(np.degrees(phi)),
                     multiple_scattering_share=float((total - single) / total)
                     if total > 0 else float("nan"))
            rows.append(m)
    rel, z = np.concatenate(rels), np.concatenate(zs)
    nan = float("nan")
    return {
        "median_rel_error": float(np.median(rel)) if rel.size else nan,
        "p90_rel_error": float(np.percentile(rel, 90)) if rel.size else nan,
        "z_mean": float(z.mean()) if z.size else nan,
        "z_std": float(z.std(ddof=1)) if z.size > 1 else nan,
        "per_theta_i": rows,
        "model": averages,
    }


AGREEMENT_SIGNIFICANCE = 1e-3
"""Significance of the test whether a table agrees with a model within its error bars."""


def agreement(result: Mapping[str, Any]) -> dict[str, Any]:
    """Whether a comparison's z = (sim − model) / stderr looks like noise alone.

    If the model were exact and the error bars calibrated, the z of the N lobe bins would
    be standard normal: their mean within z_{1−α/2} / √N of 0 and (N − 1) s² below the
    1 − α quantile of χ²(N − 1), at significance α = ``AGREEMENT_SIGNIFICANCE``. N counts
    lobe bins, not colour channels (the channels of a grey material repeat each other, so
    counting them would claim three times the evidence).

    Parameters
    ----------
    result : mapping
        ``compare_table``'s result (``z_mean``, ``z_std``, ``per_theta_i`` with
        ``lobe_bins``).

    Returns
    -------
    dict
        ``agrees`` (bool), ``lobe_bins`` (N), ``z_mean_max`` and ``z_std_max`` (the
        bounds), ``significance``.
    """
    from scipy.stats import chi2, norm

    n = sum(row["lobe_bins"] for row in result["per_theta_i"])
    alpha = AGREEMENT_SIGNIFICANCE
    mean_max = float(norm.ppf(1 - alpha / 2) / np.sqrt(max(n, 1)))
    std_max = float(np.sqrt(chi2.ppf(1 - alpha, n - 1) / (n - 1))) if n > 1 else np.nan
    agrees = bool(n > 1 and abs(result["z_mean"]) <= mean_max
                  and result["z_std"] <= std_max)
    return {"agrees": agrees, "lobe_bins": n, "z_mean_max": mean_max,
            "z_std_max": std_max, "significance": alpha}


def verdict_text(result: Mapping[str, Any], check: Mapping[str, Any]) -> str:
    """One line: does the table agree with the model within its error bars, and what the
    numbers say (``result`` from ``compare_table``, ``check`` from ``agreement``)."""
    numbers = (f"z = (sim − model) / stderr has mean {result['z_mean']:.2f} and spread "
               f"{result['z_std']:.2f} over {check['lobe_bins']} lobe bins; noise alone "
               f"gives a mean within ±{check['z_mean_max']:.2f} and a spread up to "
               f"{check['z_std_max']:.2f} at significance {check['significance']:g}")
    if check["agrees"]:
        return f"verdict: agrees with the model within the error bars ({numbers})"
    return (f"verdict: differs from the model by more than the error bars ({numbers}); the "
            f"median relative error against the model is "
            f"{100 * result['median_rel_error']:.1f}%")


def table_difference(a: Any, b: Any, component: str = "total") -> list[dict[str, Any]]:
    """Two tables of the same axes against each other, incidence by incidence.

    Neither is the truth: both are estimates with standard errors (e.g. a two-level
    hierarchy of scale and the same surface simulated in one level, docs/materials.md).

    Parameters
    ----------
    a, b : BRDFTable
        Same incident directions and bins.
    component : str
        ``"total"`` or ``"single"``.

    Returns
    -------
    list of dict
        Per incident direction: ``theta_i``, ``phi_i`` (degrees); ``albedo_a``,
        ``albedo_b``, ``albedo_difference`` (a − b) and ``albedo_difference_err`` (3,);
        ``l1`` = Σ |f_a − f_b| Ω / Σ f_b Ω, the share of b's reflected energy that a
        places differently (mean over RGB); ``l1_noise``, the L1 noise alone gives in
        expectation (Σ √(2/π) √(σ_a² + σ_b²) Ω over the same sum: E|N(0, σ²)| =
        σ √(2/π)); ``z_rms``, the RMS of (f_a − f_b) / √(σ_a² + σ_b²) over bins with a
        defined error (1 for noise alone).

    Raises
    ------
    ValueError
        If the axes or bins differ.
    """
    same = (a.bins.shape == b.bins.shape and a.isotropic == b.isotropic
            and np.allclose(a.theta_i, b.theta_i) and np.allclose(a.phi_i, b.phi_i))
    if not same:
        raise ValueError("tables with different incidences or bins do not compare")
    omega = a.bins.projected_solid_angle[..., None]
    rows = []
    for i, theta in enumerate(a.theta_i):
        for j, phi in enumerate(a.phi_i):
            fa, fb = a.values[component][i, j], b.values[component][i, j]
            ea, eb = a.errors[component][i, j], b.errors[component][i, j]
            sigma = np.hypot(np.nan_to_num(ea), np.nan_to_num(eb))
            reflected = (fb * omega).sum(axis=(0, 1))
            with np.errstate(divide="ignore", invalid="ignore"):
                l1 = (np.abs(fa - fb) * omega).sum(axis=(0, 1)) / reflected
                noise = (np.sqrt(2 / np.pi) * sigma * omega).sum(axis=(0, 1)) / reflected
            defined = sigma > 0
            z = (fa - fb)[defined] / sigma[defined]
            da, db = a.albedo_of[component][i, j], b.albedo_of[component][i, j]
            rows.append({
                "theta_i": float(np.degrees(theta)), "phi_i": float(np.degrees(phi)),
                "albedo_a": da.tolist(), "albedo_b": db.tolist(),
                "albedo_difference": (da - db).tolist(),
                "albedo_difference_err": np.hypot(a.albedo_err_of[component][i, j],
                                                  b.albedo_err_of[component][i, j]).tolist(),
                "l1": float(l1.mean()), "l1_noise": float(noise.mean()),
                "z_rms": float(np.sqrt(np.mean(z**2))) if z.size else float("nan"),
            })
    return rows
