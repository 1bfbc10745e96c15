"""BRDF tables as OpenEXR files (docs/table-format.md describes the layout).

One scanline image of float32 channels ``{component}{,_err}.{R,G,B}`` for every component
(``total``, ``order1``, …, ``order{N}+``). Image rows run over (θi, φi, θo) in row-major
order, columns over φo. The string attribute ``microsim`` holds JSON with the axes (bin
edges in radians), the channel layout, the per-incidence albedo of every component, errors
and lost energy at full precision, and the caller's metadata. Format 1 files (components
``total`` and ``single``) still read, with ``single`` as ``order1``. A table with
spherical harmonics is a two-part file: the bins in part 0 (``table``), the coefficients
in part 1 (``sh``: rows over (θi, φi), columns over the flat index l² + l + m, the same
channel names, and a ``microsim_sh`` JSON attribute). Stored wavelets are one more part
(``wavelet``: rows over (θi, φi), columns over kept coefficients, float32 values and uint32
indices, a ``microsim_wavelet`` JSON attribute; ``microsim.tables.wavelets``). Files are
written atomically: a temporary file in the same folder, renamed over the target.
"""

from __future__ import annotations

import ctypes
import json
import math
import os
import sys
import warnings
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager, redirect_stderr, redirect_stdout
from pathlib import Path
from typing import Any

import numpy as np

from microsim.errors import InputError, InputWarning
from microsim.files import atomic_path
from microsim.tables import wavelets
from microsim.tables.table import BRDFTable, ComponentEstimate
from microsim.tables.validation import check_header, check_pixels, check_sh_header

FORMAT_VERSION = 2
"""Written; 2 added the order components (1 held ``total`` and ``single``)."""
ATTRIBUTE = "microsim"
SH_ATTRIBUTE = "microsim_sh"
SH_PART = "sh"
WAVELET_ATTRIBUTE = "microsim_wavelet"
WAVELET_PART = "wavelet"
MAGIC = b"v/1\x01"
"""The first four bytes of every OpenEXR file."""
MULTIPART = 0x1000
"""Bit of the version field (bytes 4-7) set in multi-part files (a table with harmonics)."""


def _jsonable(x: Any) -> Any:
    """NaN and infinities become null; numpy arrays and scalars become lists and numbers."""
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_jsonable(v) for v in x]
    if hasattr(x, "tolist"):
        return _jsonable(x.tolist())
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def header_json(table: BRDFTable) -> dict[str, Any]:
    """The ``microsim`` attribute of a table file, as a dict."""
    a, b = table.rays.shape
    nt, np_ = table.bins.shape
    return _jsonable({
        "format_version": FORMAT_VERSION,
        "parameterisation": ("theta_i,theta_o,phi_o-phi_i" if table.isotropic
                             else "theta_i,phi_i,theta_o,phi_o"),
        "isotropic": table.isotropic,
        "axes": {"theta_i": {"values": table.theta_i, "unit": "rad"},
                 "phi_i": {"values": table.phi_i, "unit": "rad"},
                 **table.bins.to_dict()},
        "layout": {"rows": ["theta_i", "phi_i", "theta_o"], "columns": ["phi_o"],
                   "shape": [a, b, nt, np_],
                   "row": "(i_theta_i * n_phi_i + i_phi_i) * n_theta_o + i_theta_o",
                   "channels": _channel_names(table),
                   "value": "f_r in 1/sr (never times cos theta_o); *_err: standard error, "
                            "NaN where undefined (no ray landed in the bin)"},
        "components": table.components,
        "orders": table.orders,
        **({"wavelengths": table.channels.to_json()} if table.channels.spectral else {}),
        "rays": table.rays,
        "albedo": table.albedo, "albedo_err": table.albedo_err,
        "order_albedo": {c: table[c].albedo for c in table.components[1:]},
        "order_albedo_err": {c: table[c].albedo_err for c in table.components[1:]},
        "lost_energy": table.lost_energy,
        "error_model": table.error_model,
        "realisations": table.realisations,
        "dof": {c: e.dof for c, e in table.estimates.items()},
        "inflation": None if table["total"].inflation is None else {
            c: e.inflation for c, e in table.estimates.items()},
        "meta": table.meta.to_json(),
    })


def sh_header_json(table: BRDFTable) -> dict[str, Any]:
    """The ``microsim_sh`` attribute of the ``sh`` part, as a dict."""
    a, b = table.rays.shape
    return {"order": table.sh_order, "coefficients": (table.sh_order + 1) ** 2,
            "function": "f_r(wi, wo) cos(theta_o) over wo on the whole sphere (0 below "
                        "the horizon)",
            "basis": "real orthonormal spherical harmonics, Condon-Shortley phase in "
                     "P_l^m; Y_l0 = N P_l^0, Y_lm = sqrt2 N P_l^m cos(m phi), "
                     "Y_l,-m = sqrt2 N P_l^m sin(m phi) for m > 0",
            "index": "l * l + l + m",
            "azimuth": "phi_o - phi_i" if table.isotropic else "phi_o",
            "rows": "i_theta_i * n_phi_i + i_phi_i", "shape": [a, b],
            "channels": _channel_names(table),
            "value": "*_err: standard error of the coefficient"}


def _channel_names(table: BRDFTable) -> list[str]:
    """``{component}{,_err}.{R,G,B}`` (or ``.{wavelength}nm``) for every component of the
    table."""
    return [f"{c}{s}.{k}" for c in table.components for s in ("", "_err")
            for k in table.channels.names]


def _channels(pairs: Mapping[str, tuple[np.ndarray, np.ndarray]], rows: int,
              names: Sequence[str]) -> dict[str, np.ndarray]:
    """float32 channels ``{c}{,_err}.{name}`` of (..., columns, C) arrays, a pair of
    values and errors per component ``c``, as images of ``rows`` rows, a channel per
    name."""
    channels = {}
    for c, (values, errors) in pairs.items():
        for suffix, data in (("", values), ("_err", errors)):
            image = data.reshape(rows, -1, len(names))
            for k, colour in enumerate(names):
                channels[f"{c}{suffix}.{colour}"] = np.ascontiguousarray(image[..., k],
                                                                         np.float32)
    return channels


def write_table(table: BRDFTable, path: str | Path) -> None:
    """Write ``table`` to ``path`` atomically.

    Parameters
    ----------
    table : BRDFTable
    path : str or Path
        Target file; its folder is created if missing. A crash never leaves a partial
        file under this name, and an existing file is replaced only by a complete one.

    Raises
    ------
    InputError
        If ``read_table`` would refuse the file (``microsim.tables.validation``: e.g. a
        value or albedo that is not finite); nothing is written.
    """
    import OpenEXR

    a, b = table.rays.shape
    nt, np_ = table.bins.shape
    names = table.channels.names
    channels = _channels({c: (e.values, e.errors) for c, e in table.estimates.items()},
                         a * b * nt, names)
    info = header_json(table)
    # what is written is what read_table reads: a table it would refuse is not written
    refused = f"{path}: not written"
    check_header(info, refused)
    check_pixels(channels, table.components, a * b * nt, np_, refused, names=names)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage,
              ATTRIBUTE: json.dumps(info)}
    # every part of a multi-part file shares the display window
    window = (np.array([0, 0], np.int32), np.array([np_ - 1, a * b * nt - 1], np.int32))
    parts = [OpenEXR.Part(header, channels, "table")]
    if table.has_sh:
        sh_channels = _channels({c: (e.sh, e.sh_err) for c, e in table.estimates.items()},
                                a * b, names)
        check_pixels(sh_channels, table.components, a * b, (table.sh_order + 1) ** 2,
                     refused, harmonics=True, names=names)
        sh_header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage,
                     SH_ATTRIBUTE: json.dumps(sh_header_json(table)), "displayWindow": window}
        parts.append(OpenEXR.Part(sh_header, sh_channels, SH_PART))
    if table.wavelets is not None:
        wavelet_header = {"compression": OpenEXR.ZIP_COMPRESSION,
                          "type": OpenEXR.scanlineimage, "displayWindow": window,
                          WAVELET_ATTRIBUTE: json.dumps(_jsonable(
                              wavelets.part_header(table.wavelets, (a, b))))}
        parts.append(OpenEXR.Part(wavelet_header, wavelets.part_channels(table.wavelets),
                                  WAVELET_PART))
    image = OpenEXR.File(header, channels) if len(parts) == 1 else OpenEXR.File(parts)
    with atomic_path(path) as tmp:
        image.write(str(tmp))


@contextmanager
def _output_silenced() -> Iterator[None]:
    """Silence what OpenEXR prints, through Python's streams and C's file descriptors 1
    and 2, for the duration of the block: it reports damaged parts there, which would
    corrupt ``--json`` on stdout. ``read_table`` reports the damage itself."""
    sys.stdout.flush()
    sys.stderr.flush()
    libc = ctypes.CDLL(None)
    saved = os.dup(1), os.dup(2)
    with open(os.devnull, "w") as null, redirect_stdout(null), redirect_stderr(null):
        try:
            os.dup2(null.fileno(), 1)
            os.dup2(null.fileno(), 2)
            yield
        finally:
            libc.fflush(None)  # C stdio buffers, before the descriptors point back
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])


def read_table(path: str | Path, require_sh: bool = False) -> BRDFTable:
    """Read a table file written by ``write_table``.

    Parameters
    ----------
    path : str or Path
    require_sh : bool
        A damaged spherical-harmonics part (a truncated file whose bins are intact) is an
        error; False: it is a warning (``InputWarning``) and the table is read without
        harmonics.

    Returns
    -------
    BRDFTable
        Without raw sums (a read table does not merge); ``meta`` is the writer's.

    Raises
    ------
    InputError
        If the file is missing, not OpenEXR, damaged, not a microsim table, or its
        header or pixels are not those of a valid table (``microsim.tables.validation``).
    """
    import OpenEXR

    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    with open(path, "rb") as f:
        start = f.read(8)
    if len(start) < 8 or start[:4] != MAGIC:
        raise InputError(f"{path}: not an OpenEXR file")
    damaged = f"{path}: damaged (truncated or corrupt) OpenEXR file"
    try:
        with _output_silenced(), OpenEXR.File(str(path), separate_channels=True) as f:
            # copies: the file's header and pixel views do not outlive the file object
            parts = {p.name(): (dict(p.header), {name: np.array(ch.pixels)
                                                 for name, ch in p.channels.items()})
                     for p in f.parts}
    except (RuntimeError, ValueError, OSError):
        raise InputError(f"{damaged}: its header cannot be read") from None
    header, pixels = next((part for part in parts.values() if ATTRIBUTE in part[0]),
                          ({}, {}))
    if not parts or (not header and int.from_bytes(start[4:8], "little") & MULTIPART):
        raise InputError(f"{damaged}: the bins cannot be read")
    sh_header, sh_pixels = parts.get(SH_PART, ({}, {}))
    if (int.from_bytes(start[4:8], "little") & MULTIPART and SH_PART not in parts
            and WAVELET_PART not in parts):
        message = (f"{damaged}: its spherical-harmonics part cannot be read (the bins "
                   "can)")
        if require_sh:
            raise InputError(message)
        warnings.warn(f"{message}; reading the bins only", InputWarning, stacklevel=2)
    if ATTRIBUTE not in header:
        raise InputError(f"{path}: not a microsim table (no '{ATTRIBUTE}' attribute)")
    info = _parse_json(header[ATTRIBUTE], path, ATTRIBUTE)
    checked = check_header(info, path)
    stored, shape = checked["components"], checked["shape"]
    names = checked["channels"].names
    a, b, nt, np_ = shape
    check_pixels(pixels, stored, a * b * nt, np_, path, names=names)

    def load(name: str, source: dict[str, np.ndarray] = pixels,
             shape: tuple[int, ...] = shape) -> np.ndarray:
        return np.stack([source[f"{name}.{k}"] for k in names], axis=-1).astype(
            float).reshape(shape + (len(names),))

    harmonics = dict.fromkeys(stored, {})
    if SH_ATTRIBUTE in sh_header:
        coefficients = check_sh_header(_parse_json(sh_header[SH_ATTRIBUTE], path,
                                                   SH_ATTRIBUTE), path, shape)
        check_pixels(sh_pixels, stored, a * b, coefficients, path, harmonics=True,
                     names=names)
        sh_shape = (a, b, coefficients)
        harmonics = {c: {"sh": load(c, sh_pixels, sh_shape),
                         "sh_err": load(f"{c}_err", sh_pixels, sh_shape)} for c in stored}
    wavelet_header, wavelet_pixels = parts.get(WAVELET_PART, ({}, {}))
    stored_wavelets = None
    if WAVELET_ATTRIBUTE in wavelet_header:
        # parsed first: its InputError already names the file (and is a ValueError)
        wavelet_info = _parse_json(wavelet_header[WAVELET_ATTRIBUTE], path,
                                   WAVELET_ATTRIBUTE)
        try:
            stored_wavelets = wavelets.from_part(wavelet_info, wavelet_pixels, stored,
                                                 (a, b), names)
        except ValueError as exc:
            raise InputError(f"{path}: wavelet part: {exc}") from None

    dof, inflation = checked["dof"] or {}, checked["inflation"] or {}
    estimates = {c: ComponentEstimate(
        load(c), load(f"{c}_err"), checked["albedo"][c], checked["albedo_err"][c],
        dof=dof.get(c), inflation=inflation.get(c), **harmonics[c]) for c in stored}
    return BRDFTable(
        checked["bins"], checked["theta_i"], checked["phi_i"], checked["isotropic"],
        estimates, checked["rays"], checked["lost_energy"], checked["meta"],
        error_model=checked["error_model"], realisations=checked["realisations"],
        wavelets=stored_wavelets, channels=checked["channels"])


def _parse_json(text: Any, path: Path, attribute: str) -> Any:
    """A JSON string attribute of a table file, parsed.

    Raises
    ------
    InputError
        If it is not JSON, nests too deeply or holds a number Python refuses to read
        (an integer of more than 4300 digits).
    """
    try:
        return json.loads(text)
    except (TypeError, ValueError, RecursionError):
        raise InputError(f"{path}: the '{attribute}' attribute is not JSON that this "
                         "microsim reads (malformed, nested too deeply or with a number "
                         "too long)") from None
