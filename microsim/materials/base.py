"""What every facet material kind is: its recipe keys, its scattering event in the
transport kernel, and what comparisons read from it.

A kind is a frozen dataclass subclass of ``Material`` in a module of its own under
``microsim.materials``; its fields are its recipe keys (each with its ``schema.Key``:
type, default, range, meaning) and its class attributes say the rest:

- ``kind``, ``doc``: the recipe name and one sentence for docs/recipes.md;
- ``scatter``: its scattering event in kernel language (scalar Python the transport
  kernel compiles with numba: ``microsim.kernel.events``), and ``blocks``, how many blocks
  of four uniform random numbers the event reads;
- ``parameters``, ``medium``, ``tabulated``: what the kernel packs for it;
- ``fresnel``, ``diffuse_albedo``, ``model_defaults``: what the analytic models it is
  compared with take from it (``microsim.comparison.metrics``).

The kernel's per-part parameters are a (PARAMS, C) block: a column per quantity, an entry
per channel of the run (C = 3 for an RGB table, one per wavelength for a spectral one;
``Channels``). A kind's own ``parameters`` fill the first ``KIND_COLUMNS``; then the
Beer-Lambert absorption of the medium a refracting part's faces enclose
(``P_ABSORPTION``), whether they enclose one (``P_MEDIUM``), whether its event is a perfect
mirror's (``P_MIRROR``), whether it disperses (``P_DISPERSIVE``: its event's direction
depends on the channel's wavelength, so a path follows one wavelength from there,
``microsim.kernel.transport``; ``DISPERSION_*``), which the transport reads, and each channel's
wavelength (``P_WAVELENGTH``, for coatings). Kernel-language functions
are marked with ``kernel``, so the kernel can compile every one of them (numba's
``register_jitable``) while this package imports nothing heavy: ``microsim check`` reads
the recipe keys of every kind.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from microsim.analytic.fresnel import Fresnel
from microsim.errors import InputError
from microsim.materials.coating import Coating
from microsim.schema import Key, Value, check_section, record_from_json, record_json, schema_of
from microsim.spectra import measured
from microsim.spectra.channels import RGB, Channels
from microsim.spectra.spectrum import Spectrum, parse_spectrum

KIND_COLUMNS = 4
"""Columns of the kernel's parameter block that a kind's ``parameters`` fill."""
P_ABSORPTION = 4
"""Column of the absorption (per channel, per tile unit of path length) of a part's
medium."""
P_MEDIUM = 5
"""Column that is 1 where a part's faces enclose a medium (a refracting dielectric)."""
P_MIRROR = 6
"""Column that is 1 where a part's event is a perfect mirror's (``mirror``)."""
P_DISPERSIVE = 7
"""Column that is 1 where a part's event direction depends on the wavelength."""
P_WAVELENGTH = 8
"""Column of each channel's wavelength, nm (0 in an RGB table)."""
PARAMS = 9
"""Columns of the kernel's parameter block of a part."""

WEIGHTED, KEPT, HERO, TRANSMITTING = range(4)
"""What a scattering event did to the path's weight: multiplied each channel's by its
factor in ``fac``'s row 0, the rest absorbed (row 1 unwritten); kept it as it is (factor
1, nothing transmitted: ``fac`` unwritten); kept it, and from here the path follows its
hero wavelength alone (a direction that depends on the wavelength:
``microsim.kernel.transport``); multiplied it by row 0 and transmitted row 1 of it into
the facet (a non-refracting dielectric), the rest absorbed."""
DISPERSION_NONE, DISPERSION_ALWAYS, DISPERSION_REFRACTED = range(3)
"""``P_DISPERSIVE`` of a part: its events' directions do not depend on the wavelength;
they may, at every event (the path follows its hero before each); only where the event
refracts (it says so itself, ``HERO``: a reflection keeps every channel, weighted by its
reflectance over the hero's)."""

KERNEL_FUNCTIONS: list[Callable[..., Any]] = []
"""Every kernel-language helper of the material kinds, in the order they were marked."""


def kernel(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Mark a scalar function as kernel language: the transport kernel compiles it
    (inlined into its callers) when it is first loaded; from Python it runs as it is."""
    KERNEL_FUNCTIONS.append(fn)
    return fn


def rgb(value: Any) -> tuple[float, float, float]:
    """A number or three numbers as an (R, G, B) triple of floats."""
    if isinstance(value, int | float):
        return (float(value),) * 3
    r, g, b = (float(v) for v in value)
    return r, g, b


@dataclass(frozen=True, kw_only=True)
class Material:
    """A resolved ``[material.<part>]`` section: one subclass per kind."""

    kind: ClassVar[str]
    doc: ClassVar[str]
    scatter: ClassVar[Callable[..., tuple[float, ...]]]
    """``scatter(params, tab_int, tab_f, part, dx, dy, dz, nx, ny, nz, ex, ey, ez, u,
    hero, fac)``: one scattering event at a facet of unit normal n (d·n < 0, except at a
    refracting facet) for a path of unit direction of travel d, with every part's
    parameter block ``params`` ((p, PARAMS, C)), the packed tables (``tab_int``,
    ``tab_f``: the ``table`` kind), the face's tangent e, ``u``, eight uniform random
    numbers (the first ``4 · blocks`` of them drawn for this ray and event), and the
    path's ``hero`` channel (the one whose wavelength decides a dispersive event). Fills
    ``fac`` ((2, C)) with the factor each channel's weight is multiplied by (row 0) and,
    for ``TRANSMITTING``, the fraction transmitted into a non-refracting dielectric (row
    1); the rest, 1 − factor − transmitted, is absorbed. Returns the new unit direction
    and what the event did to the weight: ``WEIGHTED`` (by row 0, nothing transmitted),
    ``TRANSMITTING`` (by row 0, row 1 transmitted), ``KEPT`` (factor 1 in every channel,
    nothing transmitted: ``fac`` is then left unwritten and the transport skips the
    weight's bookkeeping) or ``HERO`` (kept, and the path follows its hero alone from
    here)."""
    blocks: ClassVar[int] = 0
    replaced_by_data: ClassVar[tuple[str, ...]] = ()
    """The keys a kind's ``data`` key (shipped measurements) stands in for."""
    data_kind: ClassVar[str | None] = None
    """The kind of shipped data its ``data`` key names (``microsim.spectra.measured``)."""
    mirror: ClassVar[bool] = False
    """The event is a perfect mirror's: specular reflection, factor 1, nothing transmitted.
    The transport then reflects inline and skips the weight's bookkeeping (the commonest
    event's shortcut; ``tests/test_kernel.py`` checks that such a kind's own event agrees)."""

    @classmethod
    def keys(cls) -> dict[str, Key]:
        """The kind's recipe keys (its fields' ``Key``)."""
        return schema_of(cls)

    @classmethod
    def parse(cls, raw: Mapping[str, Any], where: str) -> Material:
        """Validate a section without ``kind`` against the kind's keys (errors name
        ``where`` + the key) and check the kind's cross-key rules."""
        values = check_section(raw, cls.keys(), where)
        material = cls(**{k: cls.convert(k, v, where + k) for k, v in values.items()})
        given = frozenset(raw)
        both = given & set(cls.replaced_by_data)
        if getattr(material, "data", None) is not None and both:
            raise InputError(f"{where}data = {material.data!r}: gives "
                             f"{' and '.join(cls.replaced_by_data)}; leave out "
                             f"{' and '.join(sorted(both))}")
        material.check(where, given)
        return material

    @classmethod
    def convert(cls, name: str, value: Any, where: str) -> Any:
        """A validated key's value as the field holds it: RGB keys as triples, a spectrum
        key's table as a ``Spectrum`` (``where`` names the key in its errors)."""
        kind = cls.keys()[name].kind
        if kind == "coating":
            return Coating.parse(value, where)
        if kind in ("spectrum", "index") and isinstance(value, Mapping):
            return (Spectrum.from_json(value, where) if "source" in value
                    else parse_spectrum(value, where))
        return rgb(value) if kind in ("rgb", "spectrum") else value

    def check(self, where: str, given: frozenset[str]) -> None:
        """Rules between keys (``given``: the keys the recipe gave); raises
        ``InputError`` naming the key (none by default)."""

    def to_json(self) -> dict[str, Any]:
        """The section as a recipe holds it: ``kind`` and every key given or defaulted
        but those ``data`` stands in for (RGB as lists, spectra as their ``to_json``)."""
        replaced = self.replaced_by_data if getattr(self, "data", None) is not None else ()
        # an optional key not given, or one that ``data`` stands in for, is left out
        return {"kind": self.kind, **record_json(self, leave_out=replaced)}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Material:
        """Inverse of ``to_json`` (the keys a table file's recipe holds; keys it lacks
        take their defaults)."""
        return record_from_json(cls, data,
                                lambda f, v: cls.convert(f.name, v, f"material.{f.name}"))

    # --- the transport kernel -----------------------------------------------------------
    def parameters(self, channels: Channels, where: str = "material."
                   ) -> tuple[tuple[float, ...], ...]:
        """The kind's columns of its kernel parameter block (at most ``KIND_COLUMNS``),
        each C floats, one per channel (an error names ``where`` + the key).

        Raises
        ------
        InputError
            For a key that does not fit the channels (a spectrum in an RGB table, three
            numbers in a spectral one, wavelengths outside a spectrum's range).
        """
        return ()

    def medium(self, channels: Channels, where: str = "material."
               ) -> tuple[float, ...] | None:
        """The absorption (C floats) of the medium the part's faces enclose, or None when
        they enclose none (rays reflect off them, or are absorbed)."""
        return None

    @property
    def encloses_medium(self) -> bool:
        """Whether the part's faces enclose a medium (``medium`` is not None); False by
        default."""
        return False

    @property
    def transmits(self) -> bool:
        """Whether its event sends part of a path's weight out as transmitted
        (``TRANSMITTING``); False by default."""
        return False

    def dispersion(self, channels: Channels) -> int:
        """Whether and where the event's direction depends on the channel (η varies with
        the wavelength): ``DISPERSION_NONE`` (by default), ``DISPERSION_ALWAYS`` or
        ``DISPERSION_REFRACTED``."""
        return DISPERSION_NONE

    def tabulated(self) -> Any:
        """The table the kernel samples for this material (the ``table`` kind: an object
        with ``path``, ``component``, ``axis``), or None."""
        return None

    def sources(self) -> dict[str, str]:
        """Where the kind's spectra come from, by key (a spectrum's ``source``; a
        coating's index as ``coating.eta``; the shipped data's citation as ``data``)."""
        out = {}
        if self.data_kind is not None and getattr(self, "data", None) is not None:
            out["data"] = measured.source(self.data_kind, self.data)
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(value, Spectrum):
                out[f.name] = value.source
            elif isinstance(value, Coating) and isinstance(value.eta, Spectrum):
                out[f"{f.name}.eta"] = value.eta.source
        return out

    # --- comparisons ----------------------------------------------------------------------
    def fresnel(self, channels: Channels = RGB) -> Fresnel | None:
        """The Fresnel record a microfacet model of this specular facet takes
        (``microsim.analytic.fresnel``; ``TorranceSparrow``'s ``fresnel``): None for
        F = 1, a ``ConductorFresnel``, ``DielectricFresnel`` or ``CoatedFresnel``.

        Raises
        ------
        ValueError
            For a kind that no microfacet model describes.
        """
        raise ValueError(f"a {self.kind} facet has no microfacet model")

    def diffuse_albedo(self, channels: Channels = RGB) -> tuple[float, ...] | None:
        """The albedo of a diffusely reflecting facet (per channel), None for other
        kinds."""
        return None

    def model_defaults(self, channels: Channels = RGB) -> dict[str, Value]:
        """Model parameters this material implies (``eta``, ``k``, ``albedo``), per
        channel."""
        return {}

