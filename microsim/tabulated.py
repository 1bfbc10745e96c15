"""Tabulated facet materials: a simulated BRDF table as the reflectance of facets one
scale up (Westin, Arvo & Torrance 1992, "Predicting reflectance functions from complex
surfaces", SIGGRAPH '92, sec. 3: hierarchies of scale).

A ray hitting a facet of kind ``table`` leaves in a direction importance-sampled from the
table in the facet's local frame, and its weight is multiplied by the estimator's ratio
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

from pathlib import Path
from typing import Any

import numpy as np

from microsim.errors import InputError
from microsim.files import file_digest
from microsim.tables.binning import TWO_PI
from microsim.tables.exr import read_table
from microsim.tables.interpolation import linear_weights
from microsim.tables.table import BRDFTable

AXES = ("x", "y", "tangent")
"""What a table material's ``axis`` may name: a world axis, or the per-face tangent a
generator gives (``Tile.tangents``: a velvet fibre's axis)."""


def _frame_along(n: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray]:
    """b = (e − (n·e) n) / r and t = b × n = (e × n) / r for the unit axis e = e_axis
    (x or y), r = |e − (n·e) n| = √(sum of the squares of n's other two components)."""
    nx, ny, nz = n[:, 0], n[:, 1], n[:, 2]
    b = -n[:, axis, None] * n
    b[:, axis] += 1.0
    if axis == 0:
        r = np.sqrt(ny * ny + nz * nz)
        t = np.stack([np.zeros_like(nx), -nz, ny], axis=1)
    else:
        r = np.sqrt(nx * nx + nz * nz)
        t = np.stack([nz, np.zeros_like(ny), -nx], axis=1)
    return t / r[:, None], b / r[:, None]


def facet_frame(n: np.ndarray, axis: int = 1, tangents: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray]:
    """Tangent and bitangent of each facet (the convention in the module docstring).

    Parameters
    ----------
    n : (k, 3) float
        Unit facet normals.
    axis : int
        0 (x) or 1 (y): the world axis whose projection onto the facet plane is the
        bitangent. Where n lies along it (|n·e| > 1 − 1e-6) the other axis is used.
    tangents : (k, 3) float or None
        Per-facet unit directions to project instead of the world axis (a recipe's
        ``axis = "tangent"``);
        where one lies along n (|n·e| > 1 − 1e-6) the world y axis is used.

    Returns
    -------
    t, b : (k, 3) float
        Unit tangent t = b × n (the table's x axis) and bitangent b (its y axis), so that
        (t, b, n) is right-handed.
    """
    if tangents is not None:
        e_n = np.einsum("ij,ij->i", tangents, n)
        b = tangents - e_n[:, None] * n
        r = np.linalg.norm(b, axis=1)
        ok = 1.0 - np.abs(e_n) >= 1e-6
        b = np.divide(b, r[:, None], out=np.zeros_like(b), where=ok[:, None])
        t = np.cross(b, n)
        if not ok.all():
            t[~ok], b[~ok] = facet_frame(n[~ok])
        return t, b
    t, b = _frame_along(n, axis)
    along = 1.0 - np.abs(n[:, axis]) < 1e-6
    if along.any():
        t2, b2 = _frame_along(n[along], 1 - axis)
        t[along], b[along] = t2, b2
    return t, b


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
        y axis (``facet_frame``); ``"tangent"``: the facet's own tangent (``scatter``'s
        ``tangents``) projected so.
    source : dict or None
        Provenance recorded by tables made with this material (path, digest, component).

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
                 source: dict[str, Any] | None = None) -> None:
        component = table.component(component)
        if axis not in AXES:
            raise ValueError(f"axis must be one of {AXES}, got {axis!r}")
        self.uses_tangents = axis == "tangent"
        self.axis = 1 if self.uses_tangents else AXES.index(axis)
        values = table.values[component]
        if not np.all(np.isfinite(values)) or np.any(values < 0):
            raise ValueError("a table material needs finite, non-negative values")
        self.table = table
        self.component = component
        self.source = dict(source or {})
        bins = table.bins
        # a folded bin stands for itself and its mirror image φ → −φ
        omega = bins.projected_solid_angle.ravel() * (2.0 if bins.folded else 1.0)
        a, b = len(table.theta_i), len(table.phi_i)
        energy = values.reshape(a * b, bins.size, 3) * omega[:, None]  # f_b,c Ω_b
        self.albedo = energy.sum(axis=1).reshape(a, b, 3)
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
        source = {"path": str(Path(path).resolve()), "sha256": file_digest(path),
                  "component": component}
        try:
            return cls(table, component, axis, source)
        except ValueError as exc:
            raise InputError(f"{key} = {str(path)!r}: {exc}") from None

    def scatter(self, d: np.ndarray, n: np.ndarray, rng: np.random.Generator,
                tangents: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Sample outgoing directions and weights at facets of this material.

        Parameters
        ----------
        d : (k, 3) float
            Unit directions of travel (towards the facet, ``d . n < 0``).
        n : (k, 3) float
            Unit facet normals.
        rng : numpy.random.Generator
            Six uniform numbers are drawn per ray.
        tangents : (k, 3) float or None
            The facets' tangents; required with ``axis = "tangent"``, unused otherwise.

        Returns
        -------
        out : (k, 3) float
            Unit outgoing directions (above the facet).
        factor : (k, 3) float
            RGB weight f_r cos θo / pdf (its mean over rays is the table's interpolated
            albedo; a single ray's channel may exceed 1 where the channels' lobes differ).
        """
        table, bins = self.table, self.table.bins
        u = rng.random((len(d), 6))
        if self.uses_tangents and tangents is None:
            raise ValueError("this table material follows the facets' tangents: give them")
        t, b = facet_frame(n, self.axis, tangents if self.uses_tangents else None)
        wi = -d
        x, y = np.einsum("ij,ij->i", wi, t), np.einsum("ij,ij->i", wi, b)
        theta = np.arccos(np.clip(np.einsum("ij,ij->i", wi, n), -1.0, 1.0))
        phi = np.mod(np.arctan2(y, x), TWO_PI)
        i0, i1, w1 = linear_weights(theta, table.theta_i)
        it = np.where(u[:, 0] < w1, i1, i0)
        if table.isotropic:
            node = it
        else:
            j0, j1, v1 = linear_weights(phi, table.phi_i, period=TWO_PI)
            node = it * len(table.phi_i) + np.where(u[:, 1] < v1, j1, j0)
        flat = np.empty(len(d), np.int64)
        for k in np.unique(node):  # a loop over the table's nodes, not over rays
            sel = np.flatnonzero(node == k)
            flat[sel] = np.searchsorted(self.cdf[k], u[sel, 2], side="right")
        local = bins.sample(flat, u[:, 3], u[:, 4])
        if bins.folded:
            local[:, 1] *= np.where(u[:, 5] < 0.5, -1.0, 1.0)
        if table.isotropic:  # the table's azimuths are φo − φi
            c, s = np.cos(phi), np.sin(phi)
            local[:, 0], local[:, 1] = (c * local[:, 0] - s * local[:, 1],
                                        s * local[:, 0] + c * local[:, 1])
        out = local[:, :1] * t + local[:, 1:2] * b + local[:, 2:] * n
        return out, self.weight[node, flat]
