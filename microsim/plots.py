"""Matplotlib figures of simulated BRDF tables against analytic models."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from microsim.compare import Model, bin_average, direction
from microsim.tables.table import BRDFTable


def incidence_plane_bins(table: BRDFTable) -> tuple[int, int]:
    """The φo bins nearest the plane of incidence: (back-scattering side φ ≈ 0, forward
    side φ ≈ π), for an isotropic table whose azimuths are relative to φi."""
    centres = table.bins.phi_centers
    back = int(np.argmin(np.abs(np.angle(np.exp(1j * centres)))))
    forward = int(np.argmin(np.abs(np.angle(np.exp(1j * (centres - np.pi))))))
    return back, forward


def incidence_plane(table: BRDFTable, models: Sequence[Model], path: str | Path,
                    component: str = "single", title: str = "") -> None:
    """Plot f_r cos θo in the plane of incidence, simulation against model, one panel
    per incidence.

    The simulated bins (with ±1 standard error bars) and the model averaged over the
    same bins (``compare.bin_average``) are drawn against the signed θo of the bin centre:
    negative on the back-scattering side (towards the light), positive on the forward
    side (towards the mirror direction).

    Parameters
    ----------
    table : BRDFTable
        An isotropic table.
    models : sequence of Model
        One model per ``table.theta_i``.
    path : str or Path
        PNG file to write.
    component : str
        ``"single"`` or ``"total"``.
    title : str
        Figure title.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    back, forward = incidence_plane_bins(table)
    theta = np.degrees(table.bins.theta_centers)
    cos_o = np.cos(table.bins.theta_centers)
    n = len(table.theta_i)
    fig, axes = plt.subplots(1, n, figsize=(3.6 * n, 3.4), squeeze=False, sharey=False)
    for k, (ax, model) in enumerate(zip(axes[0], models, strict=True)):
        wi = direction(table.theta_i[k], 0.0)
        avg = bin_average(model, wi, table.bins.theta_edges, table.bins.phi_edges)
        values = table.values[component][k, 0]
        errors = np.nan_to_num(table.errors[component][k, 0])
        for side, sign in ((back, -1), (forward, 1)):
            x = sign * theta
            ax.errorbar(x, values[:, side, 1] * cos_o, yerr=errors[:, side, 1] * cos_o,
                        fmt="o", ms=3, color="tab:blue", ecolor="tab:blue", elinewidth=1,
                        label="simulated" if sign > 0 else None)
            ax.plot(x, avg[:, side, 1] * cos_o, "-", color="tab:red",
                    label="model" if sign > 0 else None)
        ax.set_title(f"θi = {np.degrees(table.theta_i[k]):.0f}°")
        ax.set_xlabel("θo in the plane of incidence (°)")
        ax.set_xlim(-90, 90)
        ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("f_r cos θo (1/sr)")
    axes[0, 0].legend(loc="upper left", fontsize=8)
    if title:
        fig.suptitle(title, fontsize=10)
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
        ax.set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
