"""Bins of outgoing directions over the hemisphere, equal in projected solid angle.

In the coordinates u = sin²θ and φ the projected solid angle is uniform,
cos θ dω = cos θ sin θ dθ dφ = ½ du dφ, so bins uniform in u and φ all have the same
projected solid angle ½ Δu Δφ: the pole and the horizon get the same share of the rays a
cosine lobe sends, and a Lambertian surface fills every bin equally.
"""

from __future__ import annotations

import numpy as np

TWO_PI = 2.0 * np.pi


class HemisphereBins:
    """``theta_bins`` uniform in sin²θo times ``phi_bins`` uniform in φo.

    Parameters
    ----------
    theta_bins : int
        Bins in θo over [0, π/2].
    phi_bins : int
        Bins in φo over [0, phi_period).
    phi_period : float
        2π; or π for a table folded by mirror symmetry φ → −φ (azimuths in (π, 2π) are
        reflected to 2π − φ).

    Attributes
    ----------
    theta_edges : (nt + 1,) float
        θ_k = arcsin √(k / nt), radians.
    phi_edges : (np + 1,) float
        Radians.
    theta_centers : (nt,) float
        Centres in u: arcsin √((k + ½) / nt) (the mid-point of the bin's projected solid
        angle, not of its θ range).
    phi_centers : (np,) float
    projected_solid_angle : (nt, np) float
        ∫_bin cos θ dω = ½ (sin²θ_b − sin²θ_a) Δφ, sr.
    """

    def __init__(self, theta_bins: int, phi_bins: int, phi_period: float = TWO_PI) -> None:
        if theta_bins < 1 or phi_bins < 1:
            raise ValueError("theta_bins and phi_bins must be >= 1")
        if not (np.isclose(phi_period, TWO_PI) or np.isclose(phi_period, np.pi)):
            raise ValueError("phi_period must be 2 pi or pi")
        self.theta_bins = int(theta_bins)
        self.phi_bins = int(phi_bins)
        self.phi_period = float(phi_period)
        self.u_edges = np.linspace(0.0, 1.0, self.theta_bins + 1)
        self.theta_edges = np.arcsin(np.sqrt(self.u_edges))
        self.phi_edges = np.linspace(0.0, self.phi_period, self.phi_bins + 1)
        self.theta_centers = np.arcsin(np.sqrt(0.5 * (self.u_edges[:-1] + self.u_edges[1:])))
        self.phi_centers = 0.5 * (self.phi_edges[:-1] + self.phi_edges[1:])
        self.projected_solid_angle = 0.5 * np.outer(np.diff(self.u_edges),
                                                    np.diff(self.phi_edges))

    def __eq__(self, other: object) -> bool:
        """Bins are equal when their counts and azimuth period are (their edges follow)."""
        if not isinstance(other, HemisphereBins):
            return NotImplemented
        return (self.theta_bins, self.phi_bins, self.phi_period) == (
            other.theta_bins, other.phi_bins, other.phi_period)

    def __hash__(self) -> int:
        return hash((self.theta_bins, self.phi_bins, self.phi_period))

    @property
    def shape(self) -> tuple[int, int]:
        """(theta_bins, phi_bins)."""
        return self.theta_bins, self.phi_bins

    @property
    def size(self) -> int:
        """Number of bins."""
        return self.theta_bins * self.phi_bins

    @property
    def folded(self) -> bool:
        """Whether azimuths are folded by mirror symmetry (phi_period = π)."""
        return self.phi_period < 4.0

    def relative_phi(self, phi: np.ndarray) -> np.ndarray:
        """Azimuths wrapped to [0, 2π) and, when folded, reflected into [0, π].

        Parameters
        ----------
        phi : (...) float
            Azimuths (relative to the incident azimuth for isotropic tables), radians.

        Returns
        -------
        (...) float
        """
        phi = np.mod(phi, TWO_PI)
        return np.minimum(phi, TWO_PI - phi) if self.folded else phi

    def index(self, wo: np.ndarray, phi_ref: float | np.ndarray = 0.0) -> np.ndarray:
        """Flat bin index ``it * phi_bins + ip`` of each direction.

        Parameters
        ----------
        wo : (n, 3) float
            Unit directions.
        phi_ref : float or (n,) float
            Azimuth subtracted from each direction's azimuth (φi for isotropic tables).

        Returns
        -------
        (n,) int64
            The bin, or −1 for directions with z ≤ 0 (on or below the horizon).
        """
        wo = np.asarray(wo, float)
        u = np.clip(wo[:, 0] ** 2 + wo[:, 1] ** 2, 0.0, 1.0)
        it = np.minimum((u * self.theta_bins).astype(np.int64), self.theta_bins - 1)
        phi = self.relative_phi(np.arctan2(wo[:, 1], wo[:, 0]) - phi_ref)
        ip = np.minimum((phi * (self.phi_bins / self.phi_period)).astype(np.int64),
                        self.phi_bins - 1)
        return np.where(wo[:, 2] > 0, it * self.phi_bins + ip, -1)

    def sample(self, flat_index: np.ndarray, u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
        """Directions uniform in projected solid angle inside the given bins.

        Parameters
        ----------
        flat_index : (n,) int
            Bins (as returned by ``index``).
        u1, u2 : (n,) float
            Uniform random numbers in [0, 1).

        Returns
        -------
        (n, 3) float
            Unit directions (azimuth relative to the table's reference).
        """
        it, ip = np.divmod(np.asarray(flat_index, np.int64), self.phi_bins)
        u = self.u_edges[it] + u1 * (self.u_edges[it + 1] - self.u_edges[it])
        phi = self.phi_edges[ip] + u2 * (self.phi_edges[ip + 1] - self.phi_edges[ip])
        s = np.sqrt(u)
        return np.stack([s * np.cos(phi), s * np.sin(phi), np.sqrt(1.0 - u)], axis=-1)

    def to_dict(self) -> dict[str, object]:
        """JSON-able description (edges in radians) for table files."""
        return {"theta_o": {"edges": self.theta_edges.tolist(), "unit": "rad",
                            "spacing": "uniform in sin^2(theta_o)"},
                "phi_o": {"edges": self.phi_edges.tolist(), "unit": "rad",
                          "folded": self.folded}}

    @classmethod
    def from_dict(cls, data: dict) -> HemisphereBins:
        """Inverse of ``to_dict``."""
        phi_edges = data["phi_o"]["edges"]
        return cls(len(data["theta_o"]["edges"]) - 1, len(phi_edges) - 1, phi_edges[-1])
