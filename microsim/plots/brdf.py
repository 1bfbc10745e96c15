"""Matplotlib figures of simulated BRDF tables against analytic models (the layout they
share: ``microsim.plots.layout``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from microsim.comparison.metrics import Model, channels_of
from microsim.geometry import half_difference
from microsim.plots.layout import (
    THETA_O_LABEL,
    colour_strip,
    component_text,
    luminance,
    luminance_err,
    outer_labels,
    panel_grid,
    panel_title,
    pyplot,
    save,
    suptitle,
    y_note,
)
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


def incidence_plane(table: BRDFTable, model_bins: np.ndarray, path: str | Path,
                    component: str = "single", title: str = "",
                    model_label: str = "model", incidences: list[int] | None = None
                    ) -> None:
    """Plot f_r cos θo of luminance Y (``layout.luminance``: BT.709's of RGB, CIE Y of a
    spectral table) in the plane of incidence, simulation against model:
    one panel per incident direction, in a grid of at most four columns (``layout``),
    under a strip of the table's colour.

    The simulated bins (with ±1 standard error bars) and the model averaged over the
    same bins (``compare.compare_table``'s ``model``) are drawn against the signed θo of
    the bin centre: negative on the back-scattering side (towards the light), positive on
    the forward side (towards the mirror direction); where the plane runs along a bin
    edge, the mean of the bins on either side (``incidence_plane_bins``).

    Parameters
    ----------
    table : BRDFTable
    model_bins : (a, b, nt, np, C) float
        The model's bin averages, in the table's C channels.
    path : str or Path
        Image file to write (its suffix names the format), atomically.
    component : str
        A component of the table (``"single"``, ``"total"``, ``"order2"``, …).
    title : str
        Figure title (what is compared); a second line says what is drawn.
    model_label : str
        Legend entry of the model's curve (e.g. the fitted model's name).
    incidences : list of int or None
        Indices of the polar angles to draw (default: all).
    """
    theta = np.degrees(table.bins.theta_centers)
    cos_o = np.cos(table.bins.theta_centers)
    chosen = list(range(len(table.theta_i))) if incidences is None else list(incidences)
    directions = [(k, j) for j in range(len(table.phi_i)) for k in chosen]
    ch = table.channels
    fig, axes, strip = panel_grid(len(directions), strip=True)
    colour_strip(strip, table, component)
    for (k, j), ax in zip(directions, axes, strict=True):
        back, forward = incidence_plane_bins(table, 0.0 if table.isotropic
                                             else float(table.phi_i[j]))
        avg = luminance(model_bins[k, j], ch)
        values = luminance(table[component].values[k, j], ch)
        errors = luminance_err(np.nan_to_num(table[component].errors[k, j]), ch)
        for side, sign in ((back, -1), (forward, 1)):
            x = sign * theta
            sim = values[:, side].mean(axis=1)
            err = np.sqrt((errors[:, side] ** 2).sum(axis=1)) / len(side)
            ax.errorbar(x, sim * cos_o, yerr=err * cos_o, fmt="o", ms=2.5,
                        color="tab:blue", ecolor="tab:blue", elinewidth=0.8,
                        label="simulated" if sign > 0 else None)
            ax.plot(x, avg[:, side].mean(axis=1) * cos_o, "-", color="tab:red",
                    label=model_label if sign > 0 else None)
        ax.axvline(0.0, color="grey", lw=0.5)
        ax.set_title(panel_title(table, k, j), fontsize=9)
        ax.set_xlim(-90, 90)
        ax.set_xticks([-90, -45, 0, 45, 90])
        ax.tick_params(labelsize=8)
        ax.grid(alpha=0.3)
    outer_labels(axes, THETA_O_LABEL, "f_r cos θo (1/sr), Y")
    axes[0].legend(loc="best", fontsize=7)
    suptitle(fig, title, f"{y_note(table)}; simulated ±1 standard error")
    save(fig, path)


def half_difference_slices(table: BRDFTable, model: Model, path: str | Path,
                           component: str = "total", title: str = "", n: int = 90) -> None:
    """θh–θd images of luminance at φd = 90° (the MERL / BRDF Explorer view): simulation
    (``table.eval``), model, and log10 of their ratio; white where a direction is below
    the horizon.

    Near θd = 90° both directions graze (cos θi = cos θo = cos θd cos θh at φd = 90°).
    At small θh f_r of a microfacet lobe grows there as D G F / (4 cos θi cos θo), faster
    than masking falls, with Fresnel rising towards 1: the model's bright corner. Across
    all θh the simulated image is bright above the dashed line, θd = the last θo ring's
    lower edge: above it both directions lie in that ring, which holds the grazing mirror
    peak, and a bin there spans half vectors from θh ≈ 0 to beyond 60° (the θh–θd map
    stretches without bound as θd → 90°), so the table's value is that bin's average, not
    the surface's f_r at (θh, θd) (docs/compare.md, "The half-difference view").
    """
    t = np.radians((np.arange(n) + 0.5) * 90.0 / n)
    th, td = np.meshgrid(t, t, indexing="ij")
    wi, wo = half_difference(th, td, np.pi / 2)
    ch = table.channels
    sim = luminance(table.eval(wi, wo, component), ch)
    mod = np.asarray(model.eval(wi, wo), float)
    mod = luminance(channels_of(mod, ch.count), ch) if mod.ndim == 3 else mod
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
    names = ["simulated log10 f_r (Y)", "model log10 f_r (Y)",
             "log10(simulated / model),\nmodel ≥ 1% of its peak at that θd"]
    ring = float(np.degrees(table.bins.theta_edges[-2]))
    fig, axes, strip = panel_grid(3, strip=True, panel=(3.6, 3.3), columns=3)
    colour_strip(strip, table, component)
    lo = np.nanmin(images[1])
    hi = np.nanmax(images[1])
    for ax, img, name in zip(axes, images, names, strict=True):
        ratio_panel = name.startswith("log10(")
        im = ax.imshow(img.T, origin="lower", extent=(0, 90, 0, 90), aspect="auto",
                       cmap="RdBu_r" if ratio_panel else "viridis",
                       vmin=-0.5 if ratio_panel else lo, vmax=0.5 if ratio_panel else hi)
        ax.axhline(ring, color="white", ls="--", lw=0.8)
        ax.set_title(name, fontsize=9)
        ax.tick_params(labelsize=8)
        fig.colorbar(im, ax=ax, shrink=0.8)
    outer_labels(axes, "θh (°)", "θd (°)")
    suptitle(fig, title, f"{y_note(table)}; φd = 90°; above the dashed line (θd = {ring:.1f}°) "
             "both directions lie in the table's last θo ring")
    save(fig, path)


def z_maps(table: BRDFTable, model_bins: np.ndarray, path: str | Path,
           component: str = "total", title: str = "",
           model_err: np.ndarray | None = None) -> None:
    """Per incident direction, z = (simulated − model) / standard error of luminance Y
    over the (φo, θo) bins, clipped to ±4; grey where the error is undefined. Y's error is
    Σ_c w_c σ_c (``microsim.plots.layout``: never smaller than the channels' correlated
    error allows, so |z| is never overstated). With ``model_err`` (a Monte Carlo model's
    (a, b, nt, np, C) standard errors) both errors combine per channel first."""
    ch = table.channels
    directions = [(k, j) for j in range(len(table.phi_i)) for k in range(len(table.theta_i))]
    fig, axes, _ = panel_grid(len(directions), extra_width=0.9)
    te, pe = np.degrees(table.bins.theta_edges), np.degrees(table.bins.phi_edges)
    image = None
    for (k, j), ax in zip(directions, axes, strict=True):
        err = table[component].errors[k, j]
        if model_err is not None:
            err = np.hypot(err, model_err[k, j])
        z = (luminance(table[component].values[k, j], ch)
             - luminance(model_bins[k, j], ch)) / luminance_err(err, ch)
        ax.set_facecolor("0.8")
        image = ax.pcolormesh(pe, te, np.ma.masked_invalid(z), cmap="RdBu_r", vmin=-4,
                              vmax=4)
        ax.set_title(panel_title(table, k, j), fontsize=9)
        ax.set_xticks(np.arange(0, 361, 90))
        ax.tick_params(labelsize=8)
    outer_labels(axes, "φo (°)" if not table.isotropic else "φo − φi (°)", "θo (°)")
    fig.colorbar(image, ax=axes, shrink=0.6, label="z of Y")
    suptitle(fig, title, f"z of {y_note(table)}, clipped to ±4; grey: no error")
    save(fig, path)


def albedo_plot(table: BRDFTable, model_bins: np.ndarray, path: str | Path,
                title: str = "", component: str = "total") -> None:
    """Directional albedo of luminance Y against θi (φi = the first): every simulated
    component (±1 standard error) and the model of ``component`` (Σ bin average ×
    projected solid angle), under a strip of the table's colour.

    A spectral table's figure has a panel before that one: the albedo of ``component``
    against wavelength, one curve per incidence with its ±1 standard error band and the
    model's dashed in the same colour, each θi of the colour strip above (its swatch)
    labelled in its curve's colour (``spectral_albedo``).
    """
    theta = np.degrees(table.theta_i)
    ch = table.channels
    proj = table.bins.projected_solid_angle[None, :, :, None]
    model_albedo = (model_bins[:, 0] * proj).sum(axis=(1, 2))              # (a, C)
    model = luminance(model_albedo, ch)
    if ch.spectral:
        fig, (spectra, ax), strip = panel_grid(2, strip=True, panel=(5.0, 4.0), columns=2)
        colours = spectral_albedo(spectra, table, model_albedo, component)
        colour_strip(strip, table, component, colours)
    else:
        fig, (ax,), strip = panel_grid(1, strip=True, panel=(6.0, 4.0))
        colour_strip(strip, table, component)
    for comp in table.components:
        ax.errorbar(theta, luminance(table[comp].albedo[:, 0], ch),
                    yerr=luminance_err(np.nan_to_num(table[comp].albedo_err[:, 0]), ch),
                    fmt="o-", ms=4, label=f"simulated, {component_text(comp)}")
    ax.plot(theta, model, "s--", color="black", label=f"model ({component_text(component)})")
    ax.set_xlabel("θi (°)")
    ax.set_ylabel("albedo ∫ f_r cos θo dωo, Y")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    if ch.spectral:
        ax.set_title(f"{y_note(table)} against θi", fontsize=9)
        note = (f"left: albedo per wavelength, {component_text(component)} (band: ±1 "
                f"standard error; dashed: model); right: {y_note(table)}; ±1 standard "
                "error")
    else:
        note = f"{y_note(table)}; ±1 standard error"
    suptitle(fig, title, note)
    save(fig, path)


LEGEND_CURVES = 6
"""``spectral_albedo`` names each incidence's curve in a legend up to this many curves,
and gives a θi colour bar beyond."""
CURVE_RANGE = 0.75
"""The curves' colours run over viridis from 0 to this (its yellow end is faint on white,
on the curves and on the colour strip's labels)."""


def spectral_albedo(ax: Any, table: BRDFTable, model_albedo: np.ndarray,
                    component: str) -> list[Any]:
    """A spectral table's directional albedo of ``component`` against wavelength at each
    θi (φi = the first): a solid curve with a ±1 standard error band per incidence, the
    model's albedo (``model_albedo``) dashed in the same colour.

    Parameters
    ----------
    ax : matplotlib Axes
    table : BRDFTable
        Spectral.
    model_albedo : (a, C) float
        The model's albedo per incidence and wavelength.
    component : str

    Returns
    -------
    list
        The curves' colours, one per θi (for the labels of the colour strip).
    """
    plt = pyplot()
    nm = np.asarray(table.channels.wavelengths)
    theta = np.degrees(table.theta_i)
    albedo = table[component].albedo[:, 0]
    err = np.nan_to_num(table[component].albedo_err[:, 0])
    cmap = plt.get_cmap("viridis")
    span = max(float(theta.max() - theta.min()), 1e-9)
    colours = [cmap(CURVE_RANGE * (t - theta.min()) / span) for t in theta]
    for k, colour in enumerate(colours):
        ax.fill_between(nm, albedo[k] - err[k], albedo[k] + err[k], color=colour,
                        alpha=0.3, lw=0)
        ax.plot(nm, albedo[k], "-", marker="o" if len(nm) == 1 else None, ms=3,
                color=colour, label=f"θi = {theta[k]:.0f}°")
        ax.plot(nm, model_albedo[k], "--", color=colour)
    if len(theta) <= LEGEND_CURVES:
        handles, labels = ax.get_legend_handles_labels()
        model = plt.Line2D([], [], ls="--", color="black")
        ax.legend([*handles, model], [*labels, "model"], fontsize=7)
    else:
        from matplotlib.colors import LinearSegmentedColormap, Normalize

        shown = LinearSegmentedColormap.from_list(
            "curves", [cmap(x) for x in np.linspace(0, CURVE_RANGE, 64)])
        bar = plt.cm.ScalarMappable(Normalize(theta.min(), theta.max()), shown)
        ax.figure.colorbar(bar, ax=ax, label="θi (°)", shrink=0.8)
    ax.set_xlabel("wavelength (nm)")
    ax.set_ylabel("albedo ∫ f_r cos θo dωo")
    ax.set_title(f"albedo per wavelength, {component_text(component)}", fontsize=9)
    ax.grid(alpha=0.3)
    return colours


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
        Image to write (its suffix names the format), atomically.
    title : str
    """
    fig, (ax,), _ = panel_grid(1, panel=(6.0, 4.2))
    ax.errorbar(theta_deg, measured, yerr=stderr, fmt="o", ms=3, label="facets of the tile")
    if model is not None:
        ax.plot(theta_deg, model, "-", color="tab:red", label="Beckmann, realised α")
    ax.set_yscale("log")
    ax.set_xlabel("θh (°)")
    ax.set_ylabel("D (1/sr)")
    ax.grid(alpha=0.3)
    ax.legend()
    suptitle(fig, title, fontsize=9)
    save(fig, path)


def sh_error_plot(rows: list[dict[str, Any]], table: BRDFTable, path: str | Path,
                  component: str = "total", title: str = "") -> None:
    """Two panels, written atomically in the format of the suffix. Left: relative L2
    error of truncated spherical harmonics against the table per order
    (``microsim.tables.sh_error.order_errors`` rows): hemisphere and lobe, with and
    without the window, and the two noise floors. Right: f_r cos θo of luminance Y
    (``layout.luminance``: BT.709's of RGB, CIE Y of a spectral table) in the
    plane of incidence at the last (most grazing) incidence, the table's bins (±1
    standard error) against the series at each order, with the window."""
    order = [r["order"] for r in rows]
    fig, (ax, lobe), _ = panel_grid(2, panel=(5.2, 4.0), columns=2)
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
    ch = table.channels
    values = luminance(table[component].values[k, 0], ch)
    errors = luminance_err(np.nan_to_num(table[component].errors[k, 0]), ch)
    for side, sign in ((back, -1), (forward, 1)):
        lobe.errorbar(sign * theta, values[:, side].mean(axis=1) * cos_o,
                      yerr=np.sqrt((errors[:, side] ** 2).sum(axis=1)) / len(side) * cos_o,
                      fmt="o", ms=3, color="black", label="table" if sign > 0 else None)
    signed = np.linspace(-89.5, 89.5, 359)
    phi = np.where(signed < 0, 0.0, np.pi)                # the azimuths of the bins drawn
    for row in rows:
        c = luminance(sh.truncate(table[component].sh[k, 0], row["order"]), ch) * sh.window(
            row["order"], window)
        lobe.plot(signed, sh.basis(row["order"], np.cos(np.radians(signed)), phi) @ c,
                  label=f"L = {row['order']}")
    lobe.axhline(0.0, color="grey", lw=0.5)
    lobe.set_xlim(-90, 90)
    lobe.set_xlabel(THETA_O_LABEL)
    lobe.set_ylabel("f_r cos θo (1/sr), Y")
    lobe.set_title(f"θi = {np.degrees(table.theta_i[k]):.0f}°, window {window}", fontsize=9)
    lobe.grid(alpha=0.3)
    lobe.legend(fontsize=7)
    suptitle(fig, title, f"right: {y_note(table)}")
    save(fig, path)
