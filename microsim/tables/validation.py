"""A table file is untrusted input: its header JSON and its pixels checked before use.

``read_table`` (``microsim.tables.exr``) hands every file it reads to ``check_header`` and
``check_pixels``; ``write_table`` hands every table it writes to ``check_pixels``, so a
file with values a reader would refuse is never written. Each failure is one
``InputError`` naming the file, the header key or channel, and what is allowed
(docs/table-format.md lists the keys): a table edited by hand, or damaged, is refused
before anything indexes into it, and no command turns it into a traceback or a NaN.

What a valid table is:

- header: ``format_version`` 1 or 2; ``isotropic`` a boolean; ``axes.theta_i.values``
  distinct, increasing, in [0, π/2]; ``axes.phi_i.values`` distinct, increasing, in
  [0, 2π) (one value, 0, when isotropic); the θo and φo bin edges exactly those of
  ``HemisphereBins`` (the reader rebuilds them from their counts); ``layout.shape`` the
  lengths of those axes; ``components`` ``"total"`` and order components, each once, in
  stored order, matching ``orders``; ``rays`` integers >= 0 and ``realisations`` >= 1 per
  incidence; albedos, lost energy, ``dof`` and ``inflation`` of shape
  (n_theta_i, n_phi_i, 3), finite and non-negative (errors, ``dof`` and ``inflation``
  may be null); ``error_model`` ``"rays"`` or ``"ensemble"``; ``meta`` an object that
  ``TableMeta.from_json`` reads; the harmonics' ``order`` and ``coefficients``
  consistent with each other and with their part's pixels; ``wavelengths`` absent or
  null (an RGB table) or a non-empty list of distinct increasing wavelengths in
  [``WAVELENGTH_MIN``, ``WAVELENGTH_MAX``] nm (a spectral table: its per-channel arrays
  have one entry per wavelength instead of three).
- pixels: every channel ``{component}{,_err}.{R,G,B}`` (a spectral table:
  ``.{wavelength}nm``, ``microsim.spectra.channels``) present, of shape
  (n_theta_i · n_phi_i · theta_bins, phi_bins); values finite and >= 0; errors finite
  and >= 0, NaN only where the bin is empty (value 0). Harmonic coefficients finite,
  their errors finite and >= 0, or NaN where undefined (the batch means of a component
  that too few realisations reached: ``microsim.tables.estimator``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from microsim.errors import InputError
from microsim.spectra.channels import RGB_NAMES, Channels
from microsim.tables.binning import TWO_PI, HemisphereBins
from microsim.tables.components import canonical_component, order_components
from microsim.tables.estimator import ENSEMBLE, RAYS
from microsim.tables.meta import TableMeta
from microsim.tables.table import components_of

READ_VERSIONS = (1, 2)
"""Format versions ``read_table`` reads."""
FORMAT1_COMPONENTS = ("total", "single")
"""The components a format 1 file stores."""
MAX_BINS_PER_AXIS = 1 << 16
"""Most θo or φo bins a header may claim (the recipe allows 2048 and 4096)."""
ANGLE_TOLERANCE = 1e-9
"""Radians: how far a header's bin edge may be from ``HemisphereBins``'s."""
COLOURS = RGB_NAMES
WAVELENGTH_MIN, WAVELENGTH_MAX = 200.0, 5000.0
"""nm: the wavelengths a spectral table may have (those ``[table] wavelengths`` allows)."""
SHOWN = 60
"""Characters of a bad value an error message shows."""


def _cut(text: str) -> str:
    """``text`` cut to ``SHOWN`` characters, the last one "…" where it was cut."""
    return text if len(text) <= SHOWN else text[:SHOWN - 1] + "…"


def _shown(value: Any) -> str:
    """A value as an error message shows it: its repr, cut to ``SHOWN`` characters."""
    return _cut(repr(value))


class _Where:
    """The file a check is about, to name it in its errors."""

    def __init__(self, path: Any) -> None:
        self.path = path

    def bad(self, name: str, value: Any, allowed: str) -> InputError:
        """``{path}: header {name} = {value}: must be {allowed}``."""
        return InputError(f"{self.path}: header {name} = {_shown(value)}: must be {allowed}")

    def get(self, data: Any, name: str, key: str, default: Any = ...) -> Any:
        """``data[key]`` of the header object ``name``; a missing key is an error unless
        a default is given."""
        if not isinstance(data, dict):
            raise self.bad(name, data, "an object")
        if key not in data:
            if default is not ...:
                return default
            full = f"{name}.{key}" if name else key
            raise InputError(f"{self.path}: header has no {full}")
        return data[key]


def _is_number(x: Any) -> bool:
    """A JSON number (not a boolean) that float64 holds finitely."""
    if isinstance(x, bool) or not isinstance(x, int | float):
        return False
    try:
        return math.isfinite(float(x))
    except OverflowError:
        return False


def _tree(value: Any, shape: Sequence[int], nulls: bool) -> bool:
    """Whether ``value`` is nested lists of ``shape`` whose leaves are numbers (or null
    with ``nulls``)."""
    if not shape:
        return (nulls and value is None) or _is_number(value)
    return (isinstance(value, list) and len(value) == shape[0]
            and all(_tree(v, shape[1:], nulls) for v in value))


def numbers(where: _Where, value: Any, name: str, shape: Sequence[int], *,
            nulls: bool = False, low: float | None = 0.0, integer: bool = False
            ) -> np.ndarray:
    """A header array checked: nested lists of ``shape``, numbers >= ``low`` (integers
    with ``integer``; null, read as NaN, where ``nulls``).

    Returns
    -------
    ndarray of ``shape``
        float64 (int64 with ``integer``).
    """
    kind = "integers" if integer else "numbers"
    allowed = (f"{kind}{'' if low is None else f' >= {low:g}'}"
               f"{' or null' if nulls else ''}, nested as {list(shape)}")
    if not _tree(value, shape, nulls):
        raise where.bad(name, value, allowed)
    array = np.array(value, dtype=float).reshape(shape)  # null → NaN
    finite = array[np.isfinite(array)]
    if (low is not None and (finite < low).any()) or (
            integer and not (np.isfinite(array).all() and (array == np.round(array)).all())):
        raise where.bad(name, value, allowed)
    return array.astype(np.int64) if integer else array


def _count(where: _Where, value: Any, name: str, low: int, high: int) -> int:
    """An integer in [low, high]."""
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise where.bad(name, value, f"an integer in [{low}, {high}]")
    return value


def _angles(where: _Where, axes: Any, name: str, high: float, high_open: bool) -> list[float]:
    """``axes[name].values``: a non-empty list of distinct increasing angles in
    [0, high] (or [0, high))."""
    values = where.get(where.get(axes, "axes", name), f"axes.{name}", "values")
    full = f"axes.{name}.values"
    bound = f"{'<' if high_open else '<='} {high:.10g}"
    allowed = f"a non-empty list of distinct increasing angles >= 0 and {bound} (radians)"
    if not isinstance(values, list) or not values or not all(map(_is_number, values)):
        raise where.bad(full, values, allowed)
    x = np.array(values, float)
    top = x[-1] >= high if high_open else x[-1] > high + ANGLE_TOLERANCE
    if x[0] < 0 or top or (np.diff(x) <= 0).any():
        raise where.bad(full, values, allowed)
    return [float(v) for v in values]


def _bins(where: _Where, axes: Any) -> HemisphereBins:
    """The outgoing bins the header's θo and φo edges describe."""
    theta = where.get(where.get(axes, "axes", "theta_o"), "axes.theta_o", "edges")
    phi_o = where.get(axes, "axes", "phi_o")
    phi = where.get(phi_o, "axes.phi_o", "edges")
    folded = where.get(phi_o, "axes.phi_o", "folded", False)
    if not isinstance(folded, bool):
        raise where.bad("axes.phi_o.folded", folded, "true or false")
    for name, edges in (("theta_o", theta), ("phi_o", phi)):
        if not (isinstance(edges, list) and 2 <= len(edges) <= MAX_BINS_PER_AXIS + 1
                and all(map(_is_number, edges))):
            raise where.bad(f"axes.{name}.edges", edges, "a list of 2 to "
                            f"{MAX_BINS_PER_AXIS + 1} numbers (radians)")
    bins = HemisphereBins(len(theta) - 1, len(phi) - 1, np.pi if folded else TWO_PI)
    for name, edges, want, what in (
            ("theta_o", theta, bins.theta_edges, "arcsin(sqrt(k / theta_bins))"),
            ("phi_o", phi, bins.phi_edges,
             f"uniform over [0, {'pi' if folded else '2 pi'}] (folded = "
             f"{str(folded).lower()})")):
        if not np.allclose(edges, want, rtol=0.0, atol=ANGLE_TOLERANCE):
            raise where.bad(f"axes.{name}.edges", edges, f"the bin edges {what}, k = 0 … "
                            f"{len(edges) - 1}, in radians")
    return bins


def _components(where: _Where, info: Mapping[str, Any]) -> tuple[str, ...]:
    """The stored components: format 1's, or a version 2 header's ``components``
    (``"total"`` first, order components from the lowest, each once), matching
    ``orders``."""
    if info["format_version"] == 1:
        return FORMAT1_COMPONENTS
    stored = where.get(info, "", "components")
    allowed = ("a list of 'total' then the order components from the lowest, each once "
               "(e.g. ['total', 'order1', 'order2', 'order3+'])")
    if not (isinstance(stored, list) and stored and all(isinstance(c, str) for c in stored)):
        raise where.bad("components", stored, allowed)
    try:
        ordered = components_of({canonical_component(c): None for c in stored})
    except ValueError:
        raise where.bad("components", stored, allowed) from None
    if tuple(stored) != ordered or len(set(stored)) != len(stored):
        raise where.bad("components", stored, allowed)
    n = len(stored) - 1
    implied = n if n and tuple(stored[1:]) == order_components(n) else None
    orders = where.get(info, "", "orders", None)
    if isinstance(orders, bool) or orders != implied:
        raise where.bad("orders", orders, f"{implied if implied else 'null'} (the "
                        f"components {stored})")
    return tuple(stored)


def _per_component(where: _Where, data: Any, name: str, components: Sequence[str],
                   shape: Sequence[int], nulls: bool) -> dict[str, np.ndarray]:
    """An object with one array of ``shape`` per component."""
    if not isinstance(data, dict) or set(data) != set(components):
        raise where.bad(name, data, f"an object with one entry per component "
                        f"({', '.join(components)})")
    return {c: numbers(where, data[c], f"{name}.{c}", shape, nulls=nulls)
            for c in components}


def _channels(where: _Where, info: Mapping[str, Any]) -> Channels:
    """The table's channels: RGB without ``wavelengths``, else one per wavelength."""
    values = info.get("wavelengths")
    if values is None:
        return Channels()
    allowed = (f"null (RGB) or a non-empty list of distinct increasing wavelengths in "
               f"[{WAVELENGTH_MIN:g}, {WAVELENGTH_MAX:g}] nm")
    if not isinstance(values, list) or not values or not all(map(_is_number, values)):
        raise where.bad("wavelengths", values, allowed)
    x = np.array(values, float)
    if x[0] < WAVELENGTH_MIN or x[-1] > WAVELENGTH_MAX or (np.diff(x) <= 0).any():
        raise where.bad("wavelengths", values, allowed)
    return Channels(tuple(float(v) for v in values))


def check_header(info: Any, path: Any) -> dict[str, Any]:
    """Check a table's ``microsim`` attribute (parsed JSON) and gather what it says.

    Parameters
    ----------
    info : Any
        The parsed JSON.
    path : Any
        The file, to name in errors.

    Returns
    -------
    dict
        ``components`` (stored names), ``bins`` (``HemisphereBins``), ``theta_i``,
        ``phi_i`` ((a,), (b,) float, radians), ``isotropic``, ``shape``
        (a, b, nt, np), ``rays`` and ``realisations`` ((a, b) int; realisations None
        when absent), ``channels`` (``Channels``: C of them), ``albedo`` and
        ``albedo_err`` (dicts of (a, b, C) float per stored component), ``lost_energy``
        ((a, b, C)), ``error_model``, ``dof`` and ``inflation`` (dicts, or None),
        ``meta`` (``TableMeta``).

    Raises
    ------
    InputError
        Naming the first key that is missing or wrong, and what is allowed.
    """
    where = _Where(path)
    version = info.get("format_version") if isinstance(info, dict) else None
    if isinstance(version, bool) or version not in READ_VERSIONS:
        raise InputError(f"{path}: table format version {_shown(version)}; this microsim "
                         f"reads versions {', '.join(map(str, READ_VERSIONS))}")
    components = _components(where, info)
    isotropic = where.get(info, "", "isotropic")
    if not isinstance(isotropic, bool):
        raise where.bad("isotropic", isotropic, "true or false")
    axes = where.get(info, "", "axes")
    theta_i = _angles(where, axes, "theta_i", np.pi / 2, high_open=False)
    phi_i = _angles(where, axes, "phi_i", TWO_PI, high_open=True)
    if isotropic and phi_i != [0.0]:
        raise where.bad("axes.phi_i.values", phi_i, "[0] (the table is isotropic)")
    bins = _bins(where, axes)
    a, b = len(theta_i), len(phi_i)
    shape = (a, b, bins.theta_bins, bins.phi_bins)
    stated = where.get(where.get(info, "", "layout"), "layout", "shape")
    if stated != list(shape):
        raise where.bad("layout.shape", stated, f"{list(shape)} (n_theta_i, n_phi_i, "
                        "theta_bins, phi_bins of the axes)")
    channels = _channels(where, info)
    rgb = (a, b, channels.count)
    rays = numbers(where, where.get(info, "", "rays"), "rays", (a, b), integer=True)
    realisations = where.get(info, "", "realisations", None)
    if realisations is not None:
        realisations = numbers(where, realisations, "realisations", (a, b), low=1,
                               integer=True)
    if version == 1:
        albedo = {"total": where.get(info, "", "albedo"),
                  "single": where.get(info, "", "single_albedo")}
        albedo_err = {"total": where.get(info, "", "albedo_err"),
                      "single": where.get(info, "", "single_albedo_err")}
        albedo_names = {"total": "albedo", "single": "single_albedo"}
    else:
        order_albedo = where.get(info, "", "order_albedo")
        order_err = where.get(info, "", "order_albedo_err")
        for name, data in (("order_albedo", order_albedo), ("order_albedo_err", order_err)):
            if not isinstance(data, dict) or set(data) != set(components[1:]):
                raise where.bad(name, data, "an object with one entry per order component "
                                f"({', '.join(components[1:])})")
        albedo = {"total": where.get(info, "", "albedo"), **order_albedo}
        albedo_err = {"total": where.get(info, "", "albedo_err"), **order_err}
        albedo_names = {"total": "albedo", **{c: f"order_albedo.{c}" for c in components[1:]}}
    albedo = {c: numbers(where, albedo[c], albedo_names[c], rgb) for c in components}
    albedo_err = {c: numbers(where, albedo_err[c], albedo_names[c].replace(
        "albedo", "albedo_err", 1), rgb, nulls=True) for c in components}
    error_model = where.get(info, "", "error_model", RAYS)
    if error_model not in (RAYS, ENSEMBLE):
        raise where.bad("error_model", error_model, f"{RAYS!r} or {ENSEMBLE!r}")
    dof, inflation = (None if info.get(name) is None else _per_component(
        where, info[name], name, components, rgb, nulls=True) for name in ("dof", "inflation"))
    meta = where.get(info, "", "meta")
    if not isinstance(meta, dict):
        raise where.bad("meta", meta, "an object")
    try:
        table_meta = TableMeta.from_json(meta)
    except (KeyError, TypeError, ValueError, AttributeError, IndexError,
            OverflowError) as exc:
        raise InputError(f"{path}: header meta cannot be read ({type(exc).__name__}: "
                         f"{_cut(repr(str(exc))[1:-1])})") from None
    return {"components": components, "bins": bins, "theta_i": np.array(theta_i),
            "phi_i": np.array(phi_i), "isotropic": isotropic, "shape": shape,
            "rays": rays, "realisations": realisations, "channels": channels,
            "albedo": albedo,
            "albedo_err": albedo_err,
            "lost_energy": numbers(where, where.get(info, "", "lost_energy"), "lost_energy",
                                   rgb),
            "error_model": error_model, "dof": dof, "inflation": inflation,
            "meta": table_meta}


def check_sh_header(sh_info: Any, path: Any, shape: Sequence[int]) -> int:
    """Check the ``microsim_sh`` attribute of a table's harmonics part.

    Parameters
    ----------
    sh_info : Any
        Its parsed JSON.
    path : Any
    shape : sequence of int
        The table's (a, b, nt, np).

    Returns
    -------
    int
        The number of coefficients, (order + 1)².
    """
    where = _Where(path)
    order = _count(where, where.get(sh_info, "sh", "order"), "sh.order", 0, 1 << 12)
    coefficients = where.get(sh_info, "sh", "coefficients")
    if coefficients != (order + 1) ** 2 or isinstance(coefficients, bool):
        raise where.bad("sh.coefficients", coefficients, f"{(order + 1) ** 2} ((order + 1)^2 "
                        f"for order {order})")
    stated = where.get(sh_info, "sh", "shape", list(shape[:2]))
    if stated != list(shape[:2]):
        raise where.bad("sh.shape", stated, f"{list(shape[:2])} (n_theta_i, n_phi_i)")
    return coefficients


def check_pixels(pixels: Mapping[str, np.ndarray], components: Sequence[str],
                 rows: int, columns: int, path: Any, harmonics: bool = False,
                 names: Sequence[str] = COLOURS) -> None:
    """Check a table's channels: present, of their shape, and of allowed values.

    Parameters
    ----------
    pixels : mapping of str to (rows, columns) array
        The channels by name (``{component}{,_err}.{R,G,B}``).
    components : sequence of str
        The stored components.
    rows, columns : int
        The image's size.
    path : Any
        The file, to name in errors.
    harmonics : bool
        The channels are harmonic coefficients (any sign, errors NaN where undefined),
        not bin values (>= 0, errors NaN only where the bin is empty).
    names : sequence of str
        The colour channels' names (``Channels.names``: R, G, B by default).

    Raises
    ------
    InputError
        Naming the first channel that is missing, of another shape, or holding a value
        that is not allowed.
    """
    part = "harmonics channel" if harmonics else "channel"
    for c in components:
        for colour in names:
            channel = {}
            for suffix in ("", "_err"):
                name = f"{c}{suffix}.{colour}"
                if name not in pixels:
                    raise InputError(f"{path}: {part} {name} is missing")
                data = np.asarray(pixels[name])
                if data.shape != (rows, columns):
                    raise InputError(f"{path}: {part} {name} has shape {data.shape}; the "
                                     f"header's axes give ({rows}, {columns})")
                channel[suffix] = data.astype(float)
            value, error = channel[""], channel["_err"]
            bad_value = ~np.isfinite(value) if harmonics else ~(value >= 0) | np.isinf(value)
            undefined = np.isnan(error) & (True if harmonics else value == 0)
            bad_error = ~((error >= 0) & np.isfinite(error) | undefined)
            empty = ("undefined" if harmonics else "the bin is empty (value 0)")
            for suffix, bad, allowed in (
                    ("", bad_value, "finite" if harmonics else "finite and >= 0"),
                    ("_err", bad_error, f"finite and >= 0, or NaN where {empty}")):
                if bad.any():
                    row, column = np.argwhere(bad)[0]
                    found = float(channel[suffix][row, column])
                    raise InputError(f"{path}: {part} {c}{suffix}.{colour} holds {found!r} "
                                     f"at row {row}, column {column} ({int(bad.sum())} such "
                                     f"pixels): must be {allowed}")
