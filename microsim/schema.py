"""The vocabulary of recipe keys: a key's type, default, range, and its validation.

Every section of a recipe (and every surface kind) is a mapping of names to ``Key``.
``check_section`` validates a user's table against such a mapping: unknown keys are
errors with a did-you-mean, types and ranges are checked, NaN and infinities are refused,
and defaults are filled in. Pure Python, imports nothing heavy.
"""

from __future__ import annotations

import copy
import dataclasses
import datetime
import difflib
import math
import tomllib
from collections.abc import Callable, Container, Iterable, Mapping
from dataclasses import dataclass
from typing import Any, TypeVar

from microsim.errors import InputError

R = TypeVar("R")

REQUIRED: Any = "<required>"
"""Marker for a key without a default."""

Toml = (str | int | float | bool | datetime.datetime | datetime.date | datetime.time
        | list["Toml"] | dict[str, "Toml"])
"""A value as ``tomllib`` reads it."""

Value = float | int | bool | str | list[float] | dict[str, Toml]
"""A key's value as ``check_value`` returns it: a number, a bool, a string, a list of
numbers (the list kinds, and a number given for a colour or a ``"floats"`` key), or a
table (``"coating"``, and a ``"spectrum"`` or ``"index"`` as ``{ nm, value }``) as read,
which its own reader checks further."""


@dataclass(frozen=True)
class Key:
    """One recipe key: its type, default, allowed range and meaning.

    Parameters
    ----------
    kind : str
        ``"float"``, ``"int"``, ``"bool"``, ``"str"``, ``"path"``, ``"floats"`` (a list of
        numbers), ``"rgb"`` (a number or a list of three), ``"spectrum"`` (a number, a list
        of three, or a table ``{ nm = [...], value = [...] }``: a spectrum, whose values
        the bounds apply to; ``microsim.spectra.spectrum`` checks the rest), ``"pair"`` (a
        list of two numbers), ``"channels"`` (a number, or a list of numbers, one per colour
        channel: R, G, B or a spectral table's wavelengths), ``"index"`` (a number, or a
        spectrum table as for ``"spectrum"``: one value at every wavelength, or one per
        wavelength), ``"coating"`` (a table
        ``{ thickness, eta }``, which ``microsim.materials.coating`` checks).
    default : Any
        The default value; ``REQUIRED`` if the key must be given; ``None`` if the key is
        optional and has no default (it is then absent unless given).
    doc : str
        One sentence for docs/recipes.md and error messages.
    unit : str
        ``"deg"`` for angles, ``"length"`` for tile units, ``""`` for dimensionless.
    low, high : float or None
        Inclusive bounds (exclusive where ``low_open``/``high_open``), applied to every
        element of list kinds.
    choices : tuple of str
        Allowed values of a ``"str"`` key (empty: any string).
    length : int or None
        Required list length for ``"floats"`` (None: any non-empty length).
    increasing : bool
        A ``"floats"`` list must be strictly increasing (its values distinct), as the
        axes of a table are.
    """

    kind: str
    default: Any = REQUIRED
    doc: str = ""
    unit: str = ""
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    choices: tuple[str, ...] = ()
    length: int | None = None
    increasing: bool = False

    def allowed(self) -> str:
        """Describe the allowed values in words, for error messages and docs."""
        if self.choices:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        what = {
            "float": "a number",
            "int": "an integer",
            "bool": "true or false",
            "str": "a string",
            "path": "a file path (string)",
            "floats": "a number or a non-empty list of numbers",
            "rgb": "a number or a list of 3 numbers",
            "spectrum": "a number, a list of 3 numbers (R, G, B) or a spectrum "
                        "{ nm = [...], value = [...] }",
            "pair": "a list of 2 numbers",
            "channels": "a number or a list of numbers, one per colour channel (R, G, B, or "
                        "the table's wavelengths)",
            "coating": "a table { thickness = <nm>, eta = <index or spectrum> }",
            "index": "a number or a spectrum { nm = [...], value = [...] }",
        }[self.kind]
        if self.kind == "floats" and self.length:
            what = f"a list of {self.length} numbers"
        bounds = []
        number = (lambda v: str(int(v))) if self.kind == "int" else (lambda v: f"{v:g}")
        if self.low is not None:
            bounds.append(f"{'>' if self.low_open else '>='} {number(self.low)}")
        if self.high is not None:
            bounds.append(f"{'<' if self.high_open else '<='} {number(self.high)}")
        if bounds:
            what += " " + " and ".join(bounds)
        if self.unit == "deg":
            what += " (degrees)"
        if self.increasing:
            what += ", distinct and increasing"
        return what


LENGTH_MIN, LENGTH_MAX = 1e-9, 1e9
"""Bounds of every length key (``unit = "length"``), in tile units: lengths are scale-free
(only ratios matter), and this range holds any unit from nanometres to kilometres while
squares and products of lengths stay far inside float64 (and a tile's coordinates inside
float32)."""


def length(doc: str, default: Any = REQUIRED, zero: bool = False) -> Key:
    """A length key: in [LENGTH_MIN, LENGTH_MAX] tile units (or 0 with ``zero``)."""
    return Key("float", default, doc, unit="length", low=0.0 if zero else LENGTH_MIN,
               high=LENGTH_MAX)


def key(kind: str, default: Any = REQUIRED, doc: str = "", **kw: Any) -> Any:
    """A dataclass field that is a recipe key: its ``Key`` in the field's metadata, its
    default the key's (lists as tuples; none for a required key).

    Parameters
    ----------
    kind, default, doc, **kw
        As for ``Key``.
    """
    return key_field(Key(kind, default, doc, **kw))


def key_field(spec: Key) -> Any:
    """A dataclass field for the recipe key ``spec`` (see ``key``): one ``Key`` shared by
    the records whose field it is."""
    metadata = {"key": spec}
    default = spec.default
    if default is REQUIRED:
        return dataclasses.field(metadata=metadata)
    if isinstance(default, list):
        return dataclasses.field(default=tuple(default), metadata=metadata)
    if spec.kind in ("rgb", "spectrum", "channels") and isinstance(default, int | float):
        return dataclasses.field(default=(float(default),) * 3, metadata=metadata)
    return dataclasses.field(default=default, metadata=metadata)


def schema_of(cls: type) -> dict[str, Key]:
    """The recipe keys of a dataclass whose fields were made with ``key``, in field
    order."""
    return {f.name: f.metadata["key"] for f in dataclasses.fields(cls) if "key" in f.metadata}


def record_json(record: Any, leave_out: Container[str] = ()) -> dict[str, Any]:
    """A dataclass record (a recipe section, a material, a tile's facts) as JSON: every
    field that is set, in field order (None and the fields ``leave_out`` left out); a
    value with a ``to_json`` as that, a tuple as a list.

    Parameters
    ----------
    record : dataclass instance
    leave_out : container of str
        Field names not written.

    Returns
    -------
    dict of str to JSON value
    """
    out = {}
    for f in dataclasses.fields(record):
        value = getattr(record, f.name)
        if value is None or f.name in leave_out:
            continue
        out[f.name] = (value.to_json() if hasattr(value, "to_json") else
                       list(value) if isinstance(value, tuple) else value)
    return out


def record_from_json(cls: type[R], data: Mapping[str, Any],
                     value: Callable[[dataclasses.Field, Any], Any] | None = None) -> R:
    """Inverse of ``record_json``: a ``cls`` of the entries of ``data`` that are its fields
    (others ignored; fields absent take their defaults), each read by ``value(field, v)``
    (default: a list as a tuple).

    Parameters
    ----------
    cls : dataclass type
    data : mapping of str to JSON value
    value : callable or None

    Returns
    -------
    cls
    """
    read = value or (lambda _, v: tuple(v) if isinstance(v, list) else v)
    return cls(**{f.name: read(f, data[f.name]) for f in dataclasses.fields(cls)
                  if f.name in data})


def suggest(name: str, options: Iterable[str]) -> str:
    """``" (did you mean 'x'?)"`` for the closest option, or ``""``."""
    close = difflib.get_close_matches(name, list(options), n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""


def unknown_key(where: str, name: str, options: Iterable[str]) -> InputError:
    options = sorted(options)
    return InputError(f"{where}{name}: unknown key{suggest(name, options)}; "
                      f"allowed: {', '.join(options) if options else 'none'}")


def unknown_kind(where: str, kind: Any, kinds: Iterable[str]) -> InputError:
    """The error for a missing (None) or unknown ``kind`` of a section (``where``, e.g.
    ``"surface."``), naming the ``kinds`` allowed."""
    kinds = list(kinds)
    allowed = ", ".join(repr(k) for k in kinds)
    if kind is None:
        return InputError(f"{where}kind: missing; must be one of {allowed}")
    return InputError(f"{where}kind = {kind!r}: must be one of {allowed}"
                      + suggest(str(kind), kinds))


def parse_kind(kinds: Mapping[str, type[R]], raw: Mapping[str, Any], where: str) -> R:
    """A section with ``kind`` validated into that kind's record: ``kinds[kind].parse``
    of the other keys (a material, a surface; ``kinds``: the record type of each kind).

    Raises
    ------
    InputError
        For a missing or unknown kind (naming ``where`` and the kinds), or a bad key.
    """
    kind = raw.get("kind")
    if not isinstance(kind, str) or kind not in kinds:
        raise unknown_kind(where, kind, kinds)
    return kinds[kind].parse({k: v for k, v in raw.items() if k != "kind"}, where)


def kind_from_json(kinds: Mapping[str, type[R]], data: Mapping[str, Any], what: str) -> R:
    """The record of the JSON a table file holds of a section with ``kind``
    (``kinds[kind].from_json`` of the other keys; ``what`` names the section)."""
    kind = data.get("kind")
    if kind not in kinds:
        raise InputError(f"{what} kind {kind!r}: this microsim knows " + ", ".join(kinds))
    return kinds[kind].from_json({k: v for k, v in data.items() if k != "kind"})


def _number(value: Any, name: str, key: Key, integer: bool = False) -> float | int:
    """Check one number (type, finiteness, bounds) and return it."""
    bad = InputError(f"{name} = {value!r}: must be {key.allowed()}")
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise bad
    if integer and not isinstance(value, int):
        if not float(value).is_integer():
            raise bad
        value = int(value)
    try:
        finite = math.isfinite(value)
    except OverflowError:  # an integer beyond float64
        finite = False
    if not integer and not finite:
        raise bad
    if key.low is not None and (value < key.low or (key.low_open and value == key.low)):
        raise bad
    if key.high is not None and (value > key.high or (key.high_open and value == key.high)):
        raise bad
    return value if integer else float(value)


def check_value(value: Any, name: str, key: Key) -> Value:
    """Validate one value against its key and return it in canonical form.

    Parameters
    ----------
    value : Any
        The value from TOML or from ``--set``.
    name : str
        Dotted name for the error message, e.g. ``"surface.alpha"``.
    key : Key
        The schema entry.

    Returns
    -------
    Value
        ``float`` for floats, ``int`` for ints, a list of floats for list kinds (``"rgb"``
        always becomes three floats), a copy of the table for a table.
    """
    bad = InputError(f"{name} = {value!r}: must be {key.allowed()}")
    if key.kind == "float":
        return _number(value, name, key)
    if key.kind == "int":
        return _number(value, name, key, integer=True)
    if key.kind == "bool":
        if not isinstance(value, bool):
            raise bad
        return value
    if key.kind in ("str", "path"):
        if not isinstance(value, str) or not value:
            raise bad
        if key.choices and value not in key.choices:
            raise InputError(f"{name} = {value!r}: must be {key.allowed()}"
                             f"{suggest(value, key.choices)}")
        return value
    if key.kind == "coating":
        if not isinstance(value, dict):
            raise bad
        return dict(value)
    if key.kind in ("spectrum", "index") and isinstance(value, dict):
        values = value.get("value")
        if isinstance(values, list):
            for i, v in enumerate(values):
                _number(v, f"{name}.value[{i}]", key)
        return dict(value)
    if key.kind == "index":
        return _number(value, name, key)
    if key.kind in ("rgb", "spectrum", "channels") and not isinstance(value, list):
        return [_number(value, name, key)] * 3
    if key.kind == "floats" and key.length in (None, 1) and isinstance(value, int | float) \
            and not isinstance(value, bool):
        return [_number(value, name, key)]  # one number is a list of one
    if not isinstance(value, list) or not value:
        raise bad
    want = {"rgb": 3, "spectrum": 3, "pair": 2}.get(key.kind, key.length)
    if want is not None and len(value) != want:
        raise bad
    numbers = [_number(v, f"{name}[{i}]", key) for i, v in enumerate(value)]
    if key.increasing and any(b <= a for a, b in zip(numbers, numbers[1:], strict=False)):
        raise bad
    return numbers


def check_section(raw: Mapping[str, Any], keys: Mapping[str, Key], where: str
                  ) -> dict[str, Value]:
    """Validate a table against a schema and fill in defaults.

    Parameters
    ----------
    raw : mapping
        The user's table.
    keys : mapping of str to Key
        The schema.
    where : str
        Prefix for error messages, e.g. ``"surface."``.

    Returns
    -------
    dict of str to Value
        Every key of the schema that is given or has a default.
    """
    for name in raw:
        if name not in keys:
            raise unknown_key(where, name, keys)
    out = {}
    for name, key in keys.items():
        if name in raw:
            out[name] = check_value(raw[name], where + name, key)
        elif key.default is REQUIRED:
            raise InputError(f"{where}{name}: missing; must be {key.allowed()}")
        elif key.default is not None:
            out[name] = copy.deepcopy(key.default)
    return out


TOML_LIMITS = ("nested too deeply or holding an integer of more than 4300 digits "
               "(Python's limit)")
"""Why TOML that parses as text still cannot be read."""


def parse_value(text: str, name: str = "value") -> Toml:
    """A command-line value read as TOML (``0.3``, ``[0, 45]``, ``"x"``, ``true``); a bare
    word that is not valid TOML is taken as a string.

    Raises
    ------
    InputError
        Naming ``name``, for a value past Python's limits (``TOML_LIMITS``).
    """
    text = text.strip()
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text
    except (ValueError, RecursionError):
        raise InputError(f"{name} = {text[:20]}…: cannot be read: {TOML_LIMITS}") from None
