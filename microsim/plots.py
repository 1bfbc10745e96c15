"""Matplotlib figures of simulated BRDF tables against analytic models."""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Any

import numpy as np

from microsim.compare import Model
from microsim.files import atomic_path
from microsim.geometry import half_difference
from microsim.tables import sh
from microsim.tables.table import BRDFTable


def incidence_plane_bins(table: BRDFTable, phi: float = 0.0
                         ) -> tuple[list[int], list[int]]:
    """The φo bins of the plane of incidence: (back-scattering side φ = ``phi``, forward
    side φ = ``phi`` + π), each the bin containing that azimuth, or the two bins on
    either side when it lies on a bin edge (as φ = 0 does: the plane is then their
    mean). ``phi`` is 0 for an isotropic table, whose azimuths are relative to φi, and φi
    (radians) for an anisotropic one."""
    edges = table.bins.phi_edges
    period = edges[-1]

    def around(target: float) -> list[int]:
        x = np.mod(target, period)
        k = int(np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2))
        near = np.isclose(x, edges[k], atol=1e-9) or np.isclose(x, edges[k + 1], atol=1e-9)
        if not near:
            return [k]
        lower = k if np.isclose(x, edges[k + 1], atol=1e-9) else k - 1
        return sorted({lower % (len(edges) - 1), (lower + 1) % (len(edges) - 1)})

    return around(phi), around(phi + np.pi)


def _wrapped(title: str, fig: Any, fontsize: float) -> str:
    """``title`` in lines that fit the figure's width at ``fontsize`` points (a character
    of DejaVu Sans is at most about 0.6 em wide on average)."""
    width_pt = fig.get_figwidth() * 72
    return textwrap.fill(title, max(20, int(width_pt / (0.6 * fontsize))))


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def incidence_plane(table: BRDFTable, model_bins: np.ndarray, path: str | Path,
                    component: str = "single", title: str = "",
                    model_label: str = "model", incidences: list[int] | None = None
                    ) -> None:
    """Plot f_r cos θo in the plane of incidence, simulation against model: one panel per
    incidence (columns θi; rows φi for an anisotropic table).

    The simulated bins (with ±1 standard error bars) and the model averaged over the
    same bins (``compare.compare_table``'s ``model``) are drawn against the signed θo of
    the bin centre: negative on the back-scattering side (towards the light), positive on
    the forward side (towards the mirror direction); where the plane runs along a bin
    edge, the mean of the bins on either side (``incidence_plane_bins``).

    Parameters
    ----------
    table : BRDFTable
    model_bins : (a, b, nt, np, 3) float
        The model's bin averages.
    path : str or Path
        PNG file to write.
    component : str
        A component of the table (``"single"``, ``"total"``, ``"order2"``, …).
    title : str
        Figure title.
    model_label : str
        Legend entry of the model's curve (e.g. the fitted model's name).
    incidences : list of int or None
        Indices of the polar angles to draw (default: all).
    """
    plt = _pyplot()
    theta = np.degrees(table.bins.theta_centers)
    cos_o = np.cos(table.bins.theta_centers)
    chosen = list(range(len(table.theta_i))) if incidences is None else list(incidences)
    n = len(chosen)
    rows = 1 if table.isotropic else len(table.phi_i)
    fig, axes = plt.subplots(rows, n, figsize=(3.6 * n, 3.4 * rows), squeeze=False)
    for j in range(rows):
        back, forward = incidence_plane_bins(table, 0.0 if table.isotropic
                                             else float(table.phi_i[j]))
        for k, ax in zip(chosen, axes[j], strict=True):
            avg = model_bins[k, j]
            values = table.values[component][k, j]
            errors = np.nan_to_num(table.errors[component][k, j])
            for side, sign in ((back, -1), (forward, 1)):
                x = sign * theta
                sim = values[:, side, 1].mean(axis=1)
                err = np.sqrt((errors[:, side, 1] ** 2).sum(axis=1)) / len(side)
                ax.errorbar(x, sim * cos_o, yerr=err * cos_o, fmt="o", ms=3,
                            color="tab:blue", ecolor="tab:blue", elinewidth=1,
                            label="simulated" if sign > 0 else None)
                ax.plot(x, avg[:, side, 1].mean(axis=1) * cos_o, "-", color="tab:red",
                        label=model_label if sign > 0 else None)
            label = f"θi = {np.degrees(table.theta_i[k]):.0f}°"
            if not table.isotropic:
                label += f", φi = {np.degrees(table.phi_i[j]):.0f}°"
            ax.set_title(label)
            ax.set_xlabel("θo in the plane of incidence (°)")
            ax.set_xlim(-90, 90)
            ax.grid(alpha=0.3)
        axes[j, 0].set_ylabel("f_r cos θo (1/sr), green")
    axes[0, 0].legend(loc="upper left", fontsize=8)
    if title:
        fig.suptitle(_wrapped(title, fig, 10), fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def half_difference_slices(table: BRDFTable, model: Model, path: str | Path,
                           component: str = "total", title: str = "", n: int = 90) -> None:
    """θh–θd images at φd = 90° (the MERL / BRDF Explorer view): simulation
    (``table.eval``), model, and log10 of their ratio; white where a direction is below
    the horizon."""
    plt = _pyplot()
    t = np.radians((np.arange(n) + 0.5) * 90.0 / n)
    th, td = np.meshgrid(t, t, indexing="ij")
    wi, wo = half_difference(th, td, np.pi / 2)
    sim = table.eval(wi, wo, component).mean(axis=-1)
    mod = np.asarray(model.eval(wi, wo), float)
    mod = mod.mean(axis=-1) if mod.ndim == 3 else mod
    valid = (wi[..., 2] > 0) & (wo[..., 2] > 0)
    ratio = np.full(sim.shape, np.nan)
    # the ratio only where the model holds at least 1% of its peak at the same θd: further
    # out it shows how the table's bins smear the lobe's edge, not how model and
    # simulation differ (one peak for the whole image would follow the grazing θd alone)
    peak = np.max(np.where(valid, mod, 0.0), axis=0, keepdims=True)
    both = valid & (sim > 0) & (mod > 0.01 * peak)
    ratio[both] = np.log10(sim[both] / mod[both])
    floor = max(np.nanmax(np.where(valid, mod, np.nan)) * 1e-4, 1e-6)
    images = [np.log10(np.where(valid, np.maximum(sim, floor), np.nan)),
              np.log10(np.where(valid, np.maximum(mod, floor), np.nan)), ratio]
    names = ["simulated log10 f_r", "model log10 f_r",
             "log10(simulated / model),\nmodel ≥ 1% of its peak at that θd"]
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.8))
    lo = np.nanmin(images[1])
    hi = np.nanmax(images[1])
    for ax, img, name in zip(axes, images, names, strict=True):
        ratio_panel = name.startswith("log10(")
        im = ax.imshow(img.T, origin="lower", extent=(0, 90, 0, 90),
                       cmap="RdBu_r" if ratio_panel else "viridis",
                       vmin=-0.5 if ratio_panel else lo, vmax=0.5 if ratio_panel else hi)
        ax.set_xlabel("θh (°)")
        ax.set_ylabel("θd (°)")
        ax.set_title(name, fontsize=9)
        fig.colorbar(im, ax=ax, shrink=0.8)
    if title:
        fig.suptitle(_wrapped(title + "  (φd = 90°)", fig, 10), fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def z_maps(table: BRDFTable, model_bins: np.ndarray, path: str | Path,
           component: str = "total", title: str = "",
           model_err: np.ndarray | None = None) -> None:
    """Per incidence, z = (simulated − model) / standard error over (φo, θo) bins
    (green channel), clipped to ±4; grey where the error is undefined. With ``model_err``
    (a Monte Carlo model's (a, b, nt, np, 3) standard errors) both errors combine."""
    plt = _pyplot()
    n = len(table.theta_i)
    fig, axes = plt.subplots(1, n, figsize=(3.2 * n + 1.2, 3.6), squeeze=False, sharey=True,
                             layout="constrained")
    te, pe = np.degrees(table.bins.theta_edges), np.degrees(table.bins.phi_edges)
    for k, ax in enumerate(axes[0]):
        err = table.errors[component][k, 0, ..., 1]
        if model_err is not None:
            err = np.hypot(err, model_err[k, 0, ..., 1])
        z = (table.values[component][k, 0, ..., 1] - model_bins[k, 0, ..., 1]) / err
        ax.set_facecolor("0.8")
        im = ax.pcolormesh(pe, te, np.ma.masked_invalid(z), cmap="RdBu_r", vmin=-4, vmax=4)
        ax.set_title(f"θi = {np.degrees(table.theta_i[k]):.0f}°")
        ax.set_xlabel("φo − φi (°)")
        ax.set_xticks(np.arange(0, 361, 90))
    axes[0, 0].set_ylabel("θo (°)")
    fig.colorbar(im, ax=axes[0].tolist(), shrink=0.8, label="z")
    if title:
        fig.suptitle(_wrapped(title, fig, 10), fontsize=10)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def albedo_plot(table: BRDFTable, model_bins: np.ndarray, path: str | Path,
                title: str = "", component: str = "total") -> None:
    """Directional albedo against θi: every simulated component (±1 standard error) and
    the model of ``component`` (Σ bin average × projected solid angle), mean over RGB."""
    plt = _pyplot()
    theta = np.degrees(table.theta_i)
    proj = table.bins.projected_solid_angle[None, :, :, None]
    model = (model_bins[:, 0] * proj).sum(axis=(1, 2)).mean(axis=-1)
    fig, ax = plt.subplots(figsize=(5.5, 4))
    for comp in table.components:
        label = "simulated, all orders" if comp == "total" else f"simulated, {comp}"
        ax.errorbar(theta, table.albedo_of[comp][:, 0].mean(axis=-1),
                    yerr=np.nan_to_num(table.albedo_err_of[comp][:, 0].mean(axis=-1)),
                    fmt="o-", ms=4, label=label)
    ax.plot(theta, model, "s--", color="black", label=f"model ({component})")
    ax.set_xlabel("θi (°)")
    ax.set_ylabel("albedo ∫ f_r cos θo dωo")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    if title:
        ax.set_title(_wrapped(title, fig, 9), fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def ndf_plot(theta_deg: np.ndarray, measured: np.ndarray, stderr: np.ndarray,
             model: np.ndarray | None, path: str | Path, title: str = "") -> None:
    """Measured NDF bins (±1 standard error) against a model's bin averages, log scale.

    Parameters
    ----------
    theta_deg : (k,) float
        Bin centres, degrees.
    measured, stderr : (k,) float
        NDF estimate and its standard error, 1/sr.
    model : (k,) float or None
        The model's bin averages.
    path : str or Path
        PNG to write.
    title : str
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 4))
    ax.errorbar(theta_deg, measured, yerr=stderr, fmt="o", ms=3, label="facets of the tile")
    if model is not None:
        ax.plot(theta_deg, model, "-", color="tab:red", label="Beckmann, realised α")
    ax.set_yscale("log")
    ax.set_xlabel("θh (°)")
    ax.set_ylabel("D (1/sr)")
    ax.grid(alpha=0.3)
    ax.legend()
    if title:
        ax.set_title(_wrapped(title, fig, 9), fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def sh_error_plot(rows: list[dict[str, Any]], table: BRDFTable, path: str | Path,
                  component: str = "total", title: str = "") -> None:
    """Two panels, written atomically as PNG. Left: relative L2 error of truncated
    spherical harmonics against the table per order (``microsim.tables.sh_error.order_errors``
    rows): hemisphere and lobe, with and without the window, and the two noise floors.
    Right: f_r cos θo in the plane of incidence at the last (most grazing) incidence, the
    table's bins (±1 standard error) against the series at each order, with the window;
    green channel."""

    plt = _pyplot()
    order = [r["order"] for r in rows]
    fig, (ax, lobe) = plt.subplots(1, 2, figsize=(11, 4))
    window = rows[0]["window"]
    ax.plot(order, [r["rel_l2_error"] for r in rows], "o-", label=f"hemisphere ({window})")
    ax.plot(order, [r["rel_l2_error_lobe"] for r in rows], "s-", label=f"lobe ({window})")
    if window != "none":
        ax.plot(order, [r["rel_l2_error_unwindowed"] for r in rows], "o--",
                label="hemisphere (none)")
        ax.plot(order, [r["rel_l2_error_lobe_unwindowed"] for r in rows], "s--",
                label="lobe (none)")
    ax.plot(order, [r["table_noise"] for r in rows], ":", color="grey", label="table noise")
    ax.plot(order, [r["sh_noise"] for r in rows], "-.", color="grey", label="SH noise")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xlabel("SH order L ((L+1)² coefficients)")
    ax.set_ylabel("relative L2 error of f_r cos θo")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)

    k = len(table.theta_i) - 1
    back, forward = incidence_plane_bins(table)
    theta = np.degrees(table.bins.theta_centers)
    cos_o = np.cos(table.bins.theta_centers)
    for side, sign in ((back, -1), (forward, 1)):
        err = np.nan_to_num(table.errors[component][k, 0][:, side, 1])
        lobe.errorbar(sign * theta,
                      table.values[component][k, 0][:, side, 1].mean(axis=1) * cos_o,
                      yerr=np.sqrt((err**2).sum(axis=1)) / len(side) * cos_o,
                      fmt="o", ms=3, color="black", label="table" if sign > 0 else None)
    signed = np.linspace(-89.5, 89.5, 359)
    phi = np.where(signed < 0, 0.0, np.pi)                # the azimuths of the bins drawn
    for row in rows:
        c = sh.truncate(table.sh[component][k, 0], row["order"])[:, 1] * sh.window(
            row["order"], window)
        lobe.plot(signed, sh.basis(row["order"], np.cos(np.radians(signed)), phi) @ c,
                  label=f"L = {row['order']}")
    lobe.axhline(0.0, color="grey", lw=0.5)
    lobe.set_xlim(-90, 90)
    lobe.set_xlabel("θo in the plane of incidence (°), forward > 0")
    lobe.set_ylabel("f_r cos θo (1/sr), green")
    lobe.set_title(f"θi = {np.degrees(table.theta_i[k]):.0f}°, window {window}", fontsize=9)
    lobe.grid(alpha=0.3)
    lobe.legend(fontsize=7)
    if title:
        fig.suptitle(_wrapped(title, fig, 10), fontsize=10)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format=Path(path).suffix.lstrip(".").lower() or "png")
    plt.close(fig)
