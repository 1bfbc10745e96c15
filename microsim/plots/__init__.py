"""Matplotlib figures of simulated BRDF tables against analytic models: the figures
(``microsim.plots.brdf``) and the layout they share (``microsim.plots.layout``)."""

from microsim.plots.brdf import (
    albedo_plot,
    half_difference_slices,
    incidence_plane,
    incidence_plane_bins,
    ndf_plot,
    sh_error_plot,
    z_maps,
)

__all__ = ["albedo_plot", "half_difference_slices", "incidence_plane",
           "incidence_plane_bins", "ndf_plot", "sh_error_plot", "z_maps"]
