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
  compared with take from it (``microsim.compare``).

The kernel's per-part parameter row has ``PARAMS`` columns: the kind's own
``parameters`` in the first ``KIND_COLUMNS``, then the Beer-Lambert absorption of the
medium a refracting part's faces enclose (``P_ABSORPTION``, RGB) and whether they enclose
one (``P_MEDIUM``), and whether its event is a perfect mirror's (``P_MIRROR``), which the
transport reads. Kernel-language functions are marked with
``kernel``, so the kernel can compile every one of them (numba's ``register_jitable``)
while this package imports nothing heavy: ``microsim check`` reads the recipe keys of
every kind.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from microsim.schema import Key, check_section, schema_of

KIND_COLUMNS = 9
"""Columns of the kernel's parameter row that a kind's ``parameters`` fill."""
P_ABSORPTION = 9
"""Column of the absorption (RGB, per tile unit of path length) of a part's medium."""
P_MEDIUM = 12
"""Column that is 1 where a part's faces enclose a medium (a refracting dielectric)."""
P_MIRROR = 13
"""Column that is 1 where a part's event is a perfect mirror's (``mirror``)."""
PARAMS = 14
"""Columns of the kernel's parameter row of a part."""

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
    """``scatter(params, tab_int, tab_f, part, dx, dy, dz, nx, ny, nz, ex, ey, ez, u)``:
    one scattering event at a facet of unit normal n (d·n < 0, except at a refracting
    facet) for a path of unit direction of travel d, with the part's ``params`` row, the
    packed tables (``tab_int``, ``tab_f``: the ``table`` kind), the face's tangent e and
    ``u``, eight uniform random numbers (the first ``4 · blocks`` of them drawn for this
    ray and event). Returns the new unit direction, the factor (RGB) the path weight is
    multiplied by, and the fraction (RGB) transmitted into a non-refracting dielectric;
    the rest, 1 − factor − transmitted, is absorbed."""
    blocks: ClassVar[int] = 0
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
        material = cls(**{k: cls.convert(k, v) for k, v in values.items()})
        material.check(where)
        return material

    @classmethod
    def convert(cls, name: str, value: Any) -> Any:
        """A validated key's value as the field holds it (RGB keys as triples)."""
        return rgb(value) if cls.keys()[name].kind == "rgb" else value

    def check(self, where: str) -> None:
        """Rules between keys; raises ``InputError`` naming the key (none by default)."""

    def to_json(self) -> dict[str, Any]:
        """The section as a recipe holds it: ``kind`` and every key (RGB as lists)."""
        out: dict[str, Any] = {"kind": self.kind}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            out[f.name] = list(value) if isinstance(value, tuple) else value
        return out

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Material:
        """Inverse of ``to_json`` (the keys a table file's recipe holds; keys it lacks
        take their defaults)."""
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: cls.convert(k, v) for k, v in data.items() if k in names})

    # --- the transport kernel -----------------------------------------------------------
    def parameters(self) -> tuple[float, ...]:
        """The kind's columns of its kernel parameter row (at most ``KIND_COLUMNS``)."""
        return ()

    def medium(self) -> tuple[float, float, float] | None:
        """The absorption (RGB) of the medium the part's faces enclose, or None when they
        enclose none (rays reflect off them, or are absorbed)."""
        return None

    def tabulated(self) -> Any:
        """The table the kernel samples for this material (the ``table`` kind: an object
        with ``path``, ``component``, ``axis``), or None."""
        return None

    # --- comparisons ----------------------------------------------------------------------
    def fresnel(self) -> tuple | None:
        """The ``TorranceSparrow`` Fresnel argument of a specular facet: None for F = 1,
        ``("conductor", eta, k)`` or ``("dielectric", eta)``.

        Raises
        ------
        ValueError
            For a kind that no microfacet model describes.
        """
        raise ValueError(f"a {self.kind} facet has no microfacet model")

    def diffuse_albedo(self) -> tuple[float, float, float] | None:
        """The albedo of a diffusely reflecting facet (RGB), None for other kinds."""
        return None

    def model_defaults(self) -> dict[str, Any]:
        """Model parameters this material implies (``eta``, ``k``, ``albedo``)."""
        return {}

