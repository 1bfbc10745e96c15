"""Tabulated facet materials: a simulated BRDF table as the reflectance of facets one
scale up (Westin, Arvo & Torrance 1992, "Predicting reflectance functions from complex
surfaces", SIGGRAPH '92, sec. 3: hierarchies of scale).

A ray hitting a facet of kind ``table`` leaves in a direction importance-sampled from the
table in the facet's local frame (``microsim.materials.table.scatter``, which this
class's ``packed`` layout feeds), and its weight is multiplied by the estimator's ratio
f_r cos θo / pdf (the importance-sampled Monte Carlo estimator: Pharr, Jakob & Humphreys,
PBR 4th ed., sec. 2.2.2). docs/materials.md derives the weights; in short, with a table of
bins b (projected solid angle Ω_b, values f_b,c for colour channel c) at one incidence
node:

- a bin is chosen with probability P_b = g_b / Σ g, g_b = mean_c(f_b,c) Ω_b (the mean
  over R, G, B: every channel with energy in a bin gives the bin a positive probability);
- the direction is uniform in projected solid angle inside the bin, so its pdf with
  respect to projected solid angle is P_b / Ω_b;
- the weight per channel is f_b,c / (P_b / Ω_b) = a_c (f_b,c Ω_b / a_c) / P_b: the
  channel's directional albedo a_c = Σ_b f_b,c Ω_b times the ratio of the bin's share of
  that channel's energy to the share it was sampled with. For a grey table (or one whose
  channels are proportional) the ratio is 1 and the weight is the albedo itself.

Incidence between the table's θi nodes picks the lower or upper node at random with the
linear-interpolation weights (a one-sample estimate of the two-term mixture
(1 − w) f(θ0) + w f(θ1)), which makes the estimator unbiased for the BRDF linearly
interpolated in θi (and in φi, periodic, for anisotropic tables); incidence outside the
nodes' range clamps to the nearest node. Within a bin the BRDF is taken as constant (the
table's own piecewise-constant model), so an estimate made over a table reproduces the
table's bin values exactly in expectation.

The facet frame: normal n (the face's unit normal), bitangent b the projection of the
material's ``axis`` (+y by default, +x, or the face's own tangent from the generator, such
as a velvet fibre's axis) onto the facet plane, normalised (another axis where n lies
along it), tangent t = b × n. The table's x axis (φ = 0) lies along t,
its y axis along b. An isotropic table's azimuths are relative to the incidence's, so only
an anisotropic table depends on this choice. On a flat facet the default frame is the
world's; a facet of a V-groove or a cylinder along y keeps b along the groove or the
cylinder, and a yarn's facets keep b along the yarn when its part names the axis the yarn
runs along (docs/materials.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from microsim.errors import InputError
from microsim.files import file_digest
from microsim.materials import table as ev
from microsim.materials.table import AXES
from microsim.tables.exr import read_table
from microsim.tables.table import BRDFTable


@dataclass(frozen=True)
class TableSource:
    """The file a table material read: its absolute path, its SHA-256 and the component
    taken (the provenance a table simulated with the material records,
    ``microsim.tables.meta.TableInput``)."""

    path: str
    sha256: str
    component: str


class TabulatedMaterial:
    """Importance sampling of one BRDF table as a facet material.

    Parameters
    ----------
    table : BRDFTable
        The lower-scale BRDF (values must be finite and non-negative).
    component : str
        ``"total"`` (all scattering orders of the lower scale), ``"single"``, or another
        of the table's components.
    axis : str
        ``"y"`` or ``"x"``: the world axis whose projection onto a facet is the table's
        y axis (``microsim.materials.table.facet_frame``); ``"tangent"``: the facet's own
        tangent (``Tile.tangents``) projected so.
    source : TableSource or None
        Provenance recorded by tables made with this material.

    Attributes
    ----------
    cdf : (a·b, nt·np) float
        Per incidence node (θi index · n_phi_i + φi index), the cumulative bin
        probabilities, the last exactly 1.
    weight : (a·b, nt·np, 3) float
        Per node and bin, the RGB weight f_r / (pdf per projected solid angle); zero for
        bins that are never chosen.
    albedo : (a, b, 3) float
        Directional albedo Σ_b f_b Ω_b of the piecewise-constant table per node.
    """

    def __init__(self, table: BRDFTable, component: str = "total", axis: str = "y",
                 source: TableSource | None = None) -> None:
        component = table.component(component)
        if axis not in AXES:
            raise ValueError(f"axis must be one of {AXES}, got {axis!r}")
        self.uses_tangents = axis == "tangent"
        self.axis = 1 if self.uses_tangents else AXES.index(axis)
        values = table[component].values
        if not np.all(np.isfinite(values)) or np.any(values < 0):
            raise ValueError("a table material needs finite, non-negative values")
        self.table = table
        self.component = component
        self.source = source
        bins = table.bins
        # a folded bin stands for itself and its mirror image φ → −φ
        omega = bins.projected_solid_angle.ravel() * (2.0 if bins.folded else 1.0)
        a, b = len(table.theta_i), len(table.phi_i)
        channels = values.shape[-1]
        energy = values.reshape(a * b, bins.size, channels) * omega[:, None]  # f_b,c Ω_b
        self.albedo = energy.sum(axis=1).reshape(a, b, channels)
        g = energy.mean(axis=2)
        total = g.sum(axis=1, keepdims=True)
        empty = total[:, 0] <= 0
        # a node without energy: any bin (uniform), weight 0 (the facet absorbs)
        g[empty] = 1.0
        total[empty] = bins.size
        cdf = np.cumsum(g, axis=1) / total
        cdf[:, -1] = 1.0
        self.cdf = cdf
        with np.errstate(divide="ignore", invalid="ignore"):
            self.weight = np.where(g[..., None] > 0, energy * (total / g)[..., None], 0.0)

    @classmethod
    def load(cls, path: str | Path, component: str, key: str, axis: str = "y"
             ) -> TabulatedMaterial:
        """Read a table file for a facet material.

        Parameters
        ----------
        path : str or Path
            The table (``microsim.tables.exr`` format).
        component : str
            A component of the table (``"total"``, ``"single"``, ``"order2"``, …).
        key : str
            The recipe key naming the file, for error messages (``material.<part>.path``).
        axis : str
            ``"y"``, ``"x"`` or ``"tangent"`` (see the class).

        Raises
        ------
        InputError
            If the file is missing, unreadable or not usable as a material.
        """
        try:
            table = read_table(path)
        except InputError as exc:
            raise InputError(f"{key}: {exc}") from None
        source = TableSource(str(Path(path).resolve()), file_digest(path), component)
        try:
            return cls(table, component, axis, source)
        except ValueError as exc:
            raise InputError(f"{key} = {str(path)!r}: {exc}") from None

    def packed(self, at: int) -> tuple[np.ndarray, np.ndarray]:
        """The table laid out for the transport kernel (``microsim.materials.table``).

        Parameters
        ----------
        at : int
            Where the returned floats will start in the kernel's ``tab_f``.

        Returns
        -------
        row : (TABLE_COLUMNS,) int
            The ``T_*`` columns, offsets counted from the start of ``tab_f``.
        data : (q,) float
            θi nodes, φi nodes, u = sin²θo edges, φo edges, cumulative probabilities
            (node-major), weights (node-major, one per channel and bin).
        """
        table, bins = self.table, self.table.bins
        parts = [table.theta_i, table.phi_i, bins.u_edges, bins.phi_edges, self.cdf.ravel(),
                 self.weight.ravel()]
        starts = at + np.concatenate([[0], np.cumsum([len(p) for p in parts])[:-1]])
        row = np.zeros(ev.TABLE_COLUMNS, np.int64)
        row[ev.T_THETA_N], row[ev.T_THETA_AT] = len(table.theta_i), starts[0]
        row[ev.T_PHI_N], row[ev.T_PHI_AT] = len(table.phi_i), starts[1]
        row[ev.T_ISOTROPIC], row[ev.T_FOLDED] = table.isotropic, bins.folded
        row[ev.T_THETA_BINS], row[ev.T_PHI_BINS] = bins.theta_bins, bins.phi_bins
        row[ev.T_U_EDGES_AT], row[ev.T_PHI_EDGES_AT] = starts[2], starts[3]
        row[ev.T_CDF_AT], row[ev.T_WEIGHT_AT] = starts[4], starts[5]
        row[ev.T_AXIS], row[ev.T_TANGENT] = self.axis, self.uses_tangents
        return row, np.concatenate(parts).astype(float)
