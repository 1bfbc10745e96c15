"""A tile's facet materials packed for the transport kernel.

Each face carries a material id (an index into the tile's parts); each part has a
material (``microsim.materials``), whose kind code, parameter row and packed table (the
``table`` kind) the compiled kernel reads (``microsim.kernel.events`` has the events).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict

import numpy as np

from microsim.errors import InputError
from microsim.kernel import events
from microsim.kernel.rng import key_of
from microsim.kernel.shading import curved_table
from microsim.kernel.tabulated import TabulatedMaterial
from microsim.materials import Material, code_of
from microsim.materials.base import (
    DISPERSION_NONE,
    KIND_COLUMNS,
    P_ABSORPTION,
    P_DISPERSIVE,
    P_MEDIUM,
    P_MIRROR,
    P_WAVELENGTH,
    PARAMS,
)
from microsim.materials.table import TABLE_COLUMNS
from microsim.spectra.channels import RGB, Channels
from microsim.tables.meta import TableInput


class FacetMaterials:
    """The materials of one tile's faces, packed for the transport kernel.

    Parameters
    ----------
    face_material : (m,) int
        Material id per face (index into ``parts``).
    parts : sequence of str
        Part names.
    materials : mapping of str to Material
        The material of every part.
    tangents : (m, 3) float or None
        Unit tangent per face from the generator (``Tile.tangents``), for table materials
        with ``axis = "tangent"``.
    curved : (m, 3, 3) float or None
        The tube each face approximates (``Tile.curved``), for shading normals.
    channels : Channels
        The run's channels (RGB, or one per wavelength): each part's parameters are
        sampled there, and a table material must have the same channels.

    Attributes
    ----------
    tables : dict of int to TabulatedMaterial
        The loaded table of each part whose material samples one (by material id).
    inputs : list of TableInput
        Provenance of those tables.
    divides_weight : bool
        Whether some part's event sends part of a path's weight elsewhere than into its
        absorption or its end: transmits it (a dielectric that does not refract) or ends
        it (a dispersive part, for every channel but the hero). Only then do the energy
        blocks of a run depend on which rays share them (``slots.add_energy``), so only
        then is each batch traced in a beam of its own (``goniometer._beams``).
    kind : (p,) int
        Kernel code per part (``microsim.materials.code_of``).
    params : (p, PARAMS, C) float
        Per part and channel: its kind's ``parameters``, the absorption inside the medium
        its faces enclose, whether they enclose one, whether its event is a perfect
        mirror's and whether it disperses (``microsim.materials.base``).
    tab_int : (p, TABLE_COLUMNS) int
        Per table part, its layout in ``tab_f`` (zeros for the others).
    tab_f : (q,) float
        The tables' nodes, bin edges, cumulative probabilities and weights.
    tangents : (m, 3) float
        The faces' tangents (zeros when the tile gives none).
    curved : (m, 9) or (0, 9) float
        The faces' tubes for the kernel (``microsim.kernel.shading.curved_table``: parts
        that enclose a medium flat; no rows when no face is curved).

    Raises
    ------
    InputError
        If a table file is missing or unusable (naming ``material.<part>.path``).
    """

    def __init__(self, face_material: np.ndarray, parts: Sequence[str],
                 materials: Mapping[str, Material], tangents: np.ndarray | None = None,
                 curved: np.ndarray | None = None, channels: Channels = RGB) -> None:
        self.face_material = np.ascontiguousarray(face_material, np.int64)
        specs = [materials[p] for p in parts]
        self.tables = {m: TabulatedMaterial.load(t.path, t.component,
                                                 f"material.{parts[m]}.path", t.axis)
                       for m, t in enumerate(s.tabulated() for s in specs) if t is not None}
        for m, table in self.tables.items():
            if table.uses_tangents and tangents is None:
                raise InputError(f"material.{parts[m]}.axis = 'tangent': this surface gives "
                                 "its faces no tangents (velvet does); use 'x' or 'y'")
        self.inputs = [TableInput(parts[m], **asdict(t.source)) for m, t in self.tables.items()]
        self.tangents = np.zeros((len(self.face_material), 3)) if tangents is None else \
            np.ascontiguousarray(tangents, float)
        for m, table in self.tables.items():
            if table.table.channels != channels:
                raise InputError(f"material.{parts[m]}.path: the table's channels "
                                 f"({', '.join(table.table.channels.names)}) are not the "
                                 f"run's ({', '.join(channels.names)})")
        self.channels = channels
        self.divides_weight = any(s.transmits or s.dispersion(channels) != DISPERSION_NONE
                                  for s in specs)
        self.kind = np.array([code_of(s) for s in specs], np.int64)
        self.params = np.zeros((len(specs), PARAMS, channels.count))
        for m, spec in enumerate(specs):
            own = spec.parameters(channels)
            if len(own) > KIND_COLUMNS:
                raise ValueError(f"a {spec.kind} material has more than {KIND_COLUMNS} "
                                 "kernel parameters")
            if own:
                self.params[m, :len(own)] = own
            self.params[m, P_MIRROR] = 1.0 if spec.mirror else 0.0
            self.params[m, P_DISPERSIVE] = spec.dispersion(channels)
            self.params[m, P_WAVELENGTH] = channels.wavelengths or 0.0
            medium = spec.medium(channels)
            if medium is not None:
                self.params[m, P_ABSORPTION] = medium
                self.params[m, P_MEDIUM] = 1.0
        self.tab_int = np.zeros((len(specs), TABLE_COLUMNS), np.int64)
        chunks: list[np.ndarray] = [np.zeros(1)]
        used = 1
        for m, table in self.tables.items():
            self.tab_int[m], data = table.packed(used)
            chunks.append(data)
            used += len(data)
        self.tab_f = np.concatenate(chunks)
        self.curved = curved_table(curved,
                                   self.params[self.face_material, P_MEDIUM, 0] != 0.0)

    def scatter(self, faces: np.ndarray, d: np.ndarray, n: np.ndarray,
                seed: np.random.SeedSequence, event: int = 1
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Scatter rays at the faces they hit, with the kernel's own events.

        Parameters
        ----------
        faces : (k,) int
            Faces hit.
        d : (k, 3) float
            Unit directions of travel (``d . n < 0``, except at refracting faces, which
            are hit from either side).
        n : (k, 3) float
            Unit normals of the faces.
        seed : numpy.random.SeedSequence
            Key of the random numbers; ray i draws those of ray i, event ``event``.
        event : int
            The events' number (a path's bounce, from 1).

        Returns
        -------
        out : (k, 3) float
            New unit directions.
        factor : (k, C) float
            Weight factor per channel, in [0, 1] (one ray's channel of a ``table`` may
            exceed 1; its mean does not).
        transmitted : (k, C) float
            Fraction of the weight refracted into the material (dielectrics), in [0, 1].

        The hero channel of ray i is ``i mod C``, as in the transport.
        """
        out = np.empty((len(faces), 3))
        fac = np.empty((len(faces), 2, self.channels.count))
        events.scatter_all(np.ascontiguousarray(faces, np.int64),
                           np.ascontiguousarray(d, float), np.ascontiguousarray(n, float),
                           self.face_material, self.tangents, self.kind, self.params,
                           self.tab_int, self.tab_f, key_of(seed), event, out, fac)
        return out, fac[:, 0], fac[:, 1]
