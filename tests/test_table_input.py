"""Tables are untrusted input: an edited or damaged header or pixel is one ``error:`` line
(exit 2) in every command that reads tables, never a traceback and never a NaN written or
printed with exit 0 (microsim.tables.validation).

The property-based tests edit a small simulated table's header JSON (a key removed, a
value replaced by one of another type, an extreme number, a list lengthened or cut) and
its channels (a pixel set to NaN, ±inf, a negative or huge number; a channel removed or
of another shape), hypothesis drawing ``EXAMPLES`` edits from a fixed seed
(``derandomize``): ``read_table`` either refuses the file with an ``InputError`` or returns
a table whose values, errors, albedos and harmonics are what docs/table-format.md allows,
and that ``eval`` turns into finite numbers.
"""

from __future__ import annotations

import copy
import json
import math
from collections.abc import Callable
from datetime import timedelta
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from refusals import refused
from test_robustness import GAUSSIAN, SMALL, one_error_line

import microsim
from microsim.errors import InputError
from microsim.tables import validation

EXAMPLES = 150
PROPERTY = settings(max_examples=EXAMPLES, deadline=timedelta(seconds=30), derandomize=True,
                    suppress_health_check=[HealthCheck.function_scoped_fixture,
                                           HealthCheck.too_slow])


@pytest.fixture(scope="module")
def table_file(tmp_path_factory) -> Path:
    """A small simulated table with harmonics (2 incidences, 8 × 16 bins, order 4)."""
    from microsim.cli import main

    path = tmp_path_factory.mktemp("table") / "small.exr"
    assert main(["simulate", GAUSSIAN, *SMALL, "--rays", "2000", "-o", str(path)]) == 0
    return path


def parts_of(path: Path) -> list[tuple[str, dict, dict[str, np.ndarray]]]:
    """(name, header, channels) of every part of an OpenEXR file."""
    import OpenEXR

    with OpenEXR.File(str(path), separate_channels=True) as f:
        return [(p.name(), dict(p.header), {n: np.array(c.pixels) for n, c in p.channels.items()})
                for p in f.parts]


def rewrite(source: Path, target: Path, edit_header: Callable[[dict], Any] | None = None,
            edit_pixels: Callable[[dict[str, np.ndarray]], None] | None = None,
            attribute: str | None = None,
            edit_sh_header: Callable[[dict], None] | None = None) -> Path:
    """``source`` written to ``target`` with its ``microsim`` JSON edited in place by
    ``edit_header`` (or replaced by its return value when not None, or by the raw text
    ``attribute``), the bins' channels by ``edit_pixels`` and the harmonics part's
    ``microsim_sh`` JSON in place by ``edit_sh_header``."""
    import OpenEXR

    parts = parts_of(source)
    out = []
    for name, header, channels in parts:
        header = {k: v for k, v in header.items()
                  if k in ("compression", "type", "displayWindow", "microsim", "microsim_sh")}
        if "microsim" in header:
            info = json.loads(header["microsim"])
            if edit_header is not None:
                replaced = edit_header(info)
                info = info if replaced is None else replaced
            header["microsim"] = attribute if attribute is not None else json.dumps(info)
            if edit_pixels is not None:
                edit_pixels(channels)
        if "microsim_sh" in header and edit_sh_header is not None:
            info = json.loads(header["microsim_sh"])
            edit_sh_header(info)
            header["microsim_sh"] = json.dumps(info)
        channels = {n: np.ascontiguousarray(c) for n, c in channels.items()}
        out.append(OpenEXR.Part(header, channels, name))
    OpenEXR.File(out).write(str(target))
    return target


def read_or_refuse(path: Path) -> microsim.BRDFTable | None:
    """The table, or None when ``read_table`` refuses it with one line naming the file."""
    try:
        return microsim.read_table(path)
    except InputError as exc:
        message = str(exc)
        assert str(path) in message and "\n" not in message, message
        return None


def assert_valid(table: microsim.BRDFTable) -> None:
    """What docs/table-format.md allows of a table that was read."""
    assert np.all(np.diff(table.theta_i) > 0)
    assert table.theta_i[0] >= 0 and table.theta_i[-1] <= np.pi / 2
    assert np.all(table.rays >= 0)
    for c in table.components:
        v, e = table[c].values, table[c].errors
        assert np.all(np.isfinite(v) & (v >= 0))
        assert np.all(np.isfinite(e) & (e >= 0) | np.isnan(e) & (v == 0))
        assert np.all(np.isfinite(table[c].albedo) & (table[c].albedo >= 0))
        if table.has_sh:
            s, se = table[c].sh, table[c].sh_err
            assert np.all(np.isfinite(s))
            assert np.all(np.isfinite(se) & (se >= 0) | np.isnan(se))
    rng = np.random.default_rng(0)
    wi = rng.normal(size=(64, 3))
    wo = rng.normal(size=(64, 3))
    wi[:, 2], wo[:, 2] = np.abs(wi[:, 2]), np.abs(wo[:, 2])
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    assert np.all(np.isfinite(table.eval(wi, wo)))
    if table.has_sh:
        assert np.all(np.isfinite(table.eval(wi, wo, representation="sh")))


# --- the header: named cases, through every command that reads tables --------------------
def _set(path: str, value: Any) -> Callable[[dict], None]:
    """An edit setting the dotted ``path`` of the header JSON to ``value``."""
    def edit(info: dict) -> None:
        *head, last = path.split(".")
        node = info
        for k in head:
            node = node[k]
        node[last] = value
    return edit


def _drop(path: str) -> Callable[[dict], None]:
    def edit(info: dict) -> None:
        *head, last = path.split(".")
        node = info
        for k in head:
            node = node[k]
        del node[last]
    return edit


HEADERS = {
    "only a version": (lambda info: {"format_version": 2}, "header has no components"),
    "version true": (_set("format_version", True), "format version True"),
    "components unknown": (_set("components", ["total", "bounce1"]), "header components"),
    "components repeated": (_set("components", ["total", "order1", "order1"]),
                            "header components"),
    "orders wrong": (_set("orders", 5), "header orders = 5"),
    "theta_i repeated": (_set("axes.theta_i.values", [0.5, 0.5]), "axes.theta_i.values"),
    "theta_i decreasing": (_set("axes.theta_i.values", [1.0, 0.0]), "axes.theta_i.values"),
    "theta_i past 90": (_set("axes.theta_i.values", [0.0, 2.0]), "axes.theta_i.values"),
    "theta_i strings": (_set("axes.theta_i.values", ["0", "1"]), "axes.theta_i.values"),
    "theta_i missing": (_drop("axes.theta_i"), "header has no axes.theta_i"),
    "phi_i of isotropic": (_set("axes.phi_i.values", [0.0, 1.0]), "axes.phi_i.values"),
    "edges not increasing": (_set("axes.theta_o.edges", [0.0] * 9), "axes.theta_o.edges"),
    "edges cut": (_set("axes.phi_o.edges", [0.0, 1.0]), "axes.phi_o.edges"),
    "edges empty": (_set("axes.theta_o.edges", []), "axes.theta_o.edges"),
    "folded a string": (_set("axes.phi_o.folded", "no"), "axes.phi_o.folded"),
    "shape wrong": (_set("layout.shape", [2, 1, 8, 15]), "layout.shape"),
    "layout missing": (_drop("layout"), "header has no layout"),
    "rays negative": (_set("rays", [[-1], [5]]), "header rays"),
    "rays fractional": (_set("rays", [[1.5], [5]]), "header rays"),
    "rays a string": (_set("rays", "many"), "header rays"),
    "isotropic a string": (_set("isotropic", "yes"), "header isotropic"),
    "albedo null": (_set("albedo", [[[None] * 3], [[1, 1, 1]]]), "header albedo"),
    "albedo short": (_set("albedo", [[[1, 1]], [[1, 1, 1]]]), "header albedo"),
    "order albedo missing a component": (_drop("order_albedo.order2"), "order_albedo"),
    "realisations zero": (_set("realisations", [[0], [4]]), "header realisations"),
    "error model unknown": (_set("error_model", "bootstrap"), "error_model"),
    "dof of other components": (_set("dof", {"total": [[[1, 1, 1]], [[1, 1, 1]]]}), "dof"),
    "meta a list": (_set("meta", [1]), "header meta"),
    "meta directions malformed": (_set("meta.directions", [{"rays": "x"}]), "header meta"),
    "meta input without its sha256": (
        _set("meta.inputs", [{"part": "base", "path": "a.exr", "component": "total"}]),
        "header meta cannot be read (KeyError: 'sha256')"),
    "huge integer": (_set("rays", [[10**400], [1]]), "header rays"),
}


@pytest.mark.parametrize("case", sorted(HEADERS))
def test_an_edited_header_is_one_error_line_in_read_table(table_file, tmp_path, case):
    edit, needle = HEADERS[case]
    path = rewrite(table_file, tmp_path / "edited.exr", edit)
    with pytest.raises(InputError) as info:
        microsim.read_table(path)
    assert needle in str(info.value) and str(path) in str(info.value), str(info.value)


@pytest.mark.parametrize(("attribute", "needle"), [
    ("{not json", "not JSON"),
    ("[" * 5000 + "]" * 5000, "nested too deeply"),
    ('{"format_version": 2, "rays": ' + "9" * 5000 + "}", "too long"),
])
def test_an_attribute_that_is_not_readable_json_is_one_error_line(table_file, tmp_path,
                                                                   attribute, needle):
    path = rewrite(table_file, tmp_path / "edited.exr", attribute=attribute)
    with pytest.raises(InputError, match=needle):
        microsim.read_table(path)


def _nan_value(channels: dict[str, np.ndarray]) -> None:
    channels["total.G"][3, 2] = np.nan


PIXELS = {
    "NaN value": (_nan_value, "channel total.G holds nan at row 3, column 2"),
    "negative value": (lambda ch: ch["order2.R"].__setitem__((0, 0), -1.0),
                       "channel order2.R holds -1.0"),
    "infinite value": (lambda ch: ch["total.B"].__setitem__((1, 1), np.inf),
                       "channel total.B holds inf"),
    "NaN error of a full bin": (lambda ch: ch["total_err.R"].__setitem__(
        (0, 0), np.nan), "channel total_err.R holds nan"),
    "negative error": (lambda ch: ch["order1_err.R"].__setitem__((0, 0), -0.5),
                       "channel order1_err.R holds -0.5"),
    "channel missing": (lambda ch: ch.pop("order3+_err.B"), "channel order3+_err.B is missing"),
}


@pytest.mark.parametrize("case", sorted(PIXELS))
def test_bad_pixels_are_one_error_line_in_read_table(table_file, tmp_path, case):
    edit, needle = PIXELS[case]
    path = rewrite(table_file, tmp_path / "edited.exr", edit_pixels=edit)
    with pytest.raises(InputError) as info:
        microsim.read_table(path)
    assert needle in str(info.value), str(info.value)


def test_harmonics_of_another_order_than_their_header_are_refused(table_file, tmp_path):
    path = rewrite(table_file, tmp_path / "sh.exr",
                   edit_sh_header=lambda info: info.update(order=3, coefficients=16))
    with pytest.raises(InputError, match=r"harmonics channel total\.R has shape \(2, 25\)"):
        microsim.read_table(path)


READERS = {
    "compare": ["compare", "{t}", "--model", "beckmann"],
    "fit": ["fit", "{t}", "--model", "beckmann"],
    "sh": ["sh", "{t}"],
    "export": ["export", "{t}", "--format", "rgl", "-o", "{tmp}/out.bsdf"],
    "view": ["view", "{t}", "--screenshot", "{tmp}/v.png"],
    "render": ["render", "{t}", "-o", "{tmp}/r.png"],
}


@pytest.mark.parametrize("command", sorted(READERS))
@pytest.mark.parametrize("case", ["only a version", "theta_i repeated", "NaN value"])
def test_every_reading_command_refuses_a_bad_table_in_one_line(cli, table_file, tmp_path,
                                                               command, case):
    if case in HEADERS:
        edit, needle = HEADERS[case]
        path = rewrite(table_file, tmp_path / "edited.exr", edit)
    else:
        edit, needle = PIXELS[case]
        path = rewrite(table_file, tmp_path / "edited.exr", edit_pixels=edit)
    argv = [a.format(t=path, tmp=tmp_path) for a in READERS[command]]
    code, _, err = cli(*argv)
    one_error_line(code, err, str(path), needle)


def test_a_table_material_refuses_a_bad_table_in_one_line(cli, table_file, tmp_path):
    path = rewrite(table_file, tmp_path / "edited.exr", HEADERS["only a version"][0])
    code, _, err = cli("simulate", GAUSSIAN, *SMALL, "--rays", "100",
                       "--set", "material.kind=table", "--set", f"material.path={path}",
                       "-o", str(tmp_path / "out.exr"))
    one_error_line(code, err, "header has no components")
    assert not (tmp_path / "out.exr").exists()


def test_a_table_that_read_table_would_refuse_is_not_written(table_file, tmp_path):
    table = microsim.read_table(table_file)
    table["order1"].values[0, 0, 0, 0, 0] = np.nan
    with pytest.raises(InputError, match="not written: channel order1.R holds nan"):
        microsim.write_table(table, tmp_path / "nan.exr")
    assert not (tmp_path / "nan.exr").exists()
    table = microsim.read_table(table_file)
    table["total"].albedo[1, 0, 2] = np.inf
    with pytest.raises(InputError, match="not written: header albedo"):
        microsim.write_table(table, tmp_path / "inf.exr")


# --- the header and the pixels: property-based ------------------------------------------
JUNK = st.one_of(
    st.none(), st.booleans(), st.text(max_size=4),
    st.sampled_from([0, -1, 1, 2, 0.5, -1e-300, 1e300, -1e300, 2**63, 10**30, math.pi / 2,
                     2 * math.pi, 1e-12]),
    st.floats(allow_nan=False, allow_infinity=False),
    st.lists(st.integers(-3, 3), max_size=3),
    st.dictionaries(st.sampled_from(["total", "order1", "x"]), st.integers(0, 2),
                    max_size=2),
)


def paths_of(node: Any, prefix: tuple = ()) -> list[tuple]:
    """Every path (keys and indices) into a JSON value, its leaves and inner nodes; lists
    longer than 3 give their first, second and last items."""
    out = [prefix] if prefix else []
    if isinstance(node, dict):
        for k, v in node.items():
            out += paths_of(v, prefix + (k,))
    elif isinstance(node, list):
        picks = sorted({0, 1, len(node) - 1}) if len(node) > 3 else range(len(node))
        for i in picks:
            if i >= 0:
                out += paths_of(node[i], prefix + (i,))
    return out


@st.composite
def header_edits(draw, info: dict) -> Callable[[dict], None]:
    """1-3 edits of a header: a key or item removed, a value replaced by junk, a number
    scaled or negated, a list duplicated in part or cut."""
    edits = []
    paths = paths_of(info)
    for _ in range(draw(st.integers(1, 3))):
        path = draw(st.sampled_from(paths))
        how = draw(st.sampled_from(["remove", "junk", "junk", "number", "list"]))
        edits.append((path, how, draw(JUNK), draw(st.sampled_from([-1.0, 0.0, 0.5, 2.0, 1e9])),
                      draw(st.integers(-2, 2))))

    def edit(header: dict) -> None:
        for path, how, junk, factor, shift in edits:
            parent, node = None, header
            for k in path:
                ok = (isinstance(node, dict) and k in node) or (
                    isinstance(node, list) and isinstance(k, int) and k < len(node))
                if not ok:
                    break
                parent, node = node, node[k]
            else:
                key = path[-1]
                if how == "remove":
                    del parent[key]
                elif how == "number" and isinstance(node, int | float) and not isinstance(
                        node, bool):
                    parent[key] = node * factor
                elif how == "list" and isinstance(node, list):
                    parent[key] = node[:shift] if shift < 0 else node + node[:shift]
                else:
                    parent[key] = junk
    return edit


@PROPERTY
@given(data=st.data())
def test_any_edit_of_the_header_is_refused_or_reads_a_valid_table(table_file, tmp_path, data):
    info = json.loads(dict(parts_of(table_file)[0][1])["microsim"])
    edit = data.draw(header_edits(copy.deepcopy(info)))
    path = rewrite(table_file, tmp_path / "edited.exr", edit)
    table = read_or_refuse(path)
    if table is not None:
        assert_valid(table)


PIXEL_VALUES = st.sampled_from([np.nan, np.inf, -np.inf, -1.0, -1e-30, 0.0, 1e-30, 1e30,
                                3.0e38, 7.0])


@st.composite
def pixel_edits(draw, names: list[str], shape: tuple[int, int]
                ) -> Callable[[dict[str, np.ndarray]], None]:
    """1-3 edits of the bins' channels: pixels set to a drawn value, a channel removed or
    set to zero. (An OpenEXR file cannot hold channels of different sizes; a header whose
    shape is not its channels' is a case of its own.)"""
    edits = []
    for _ in range(draw(st.integers(1, 3))):
        name = draw(st.sampled_from(names))
        how = draw(st.sampled_from(["pixels", "pixels", "pixels", "remove", "zero"]))
        cells = draw(st.lists(st.tuples(st.integers(0, shape[0] - 1),
                                        st.integers(0, shape[1] - 1)), min_size=1, max_size=4))
        edits.append((name, how, cells, draw(PIXEL_VALUES)))

    def edit(channels: dict[str, np.ndarray]) -> None:
        for name, how, cells, value in edits:
            if name not in channels:
                continue
            if how == "remove":
                del channels[name]
            elif how == "zero":
                channels[name] = np.zeros_like(channels[name])
            else:
                data = channels[name].copy()
                for cell in cells:
                    if cell[0] < data.shape[0] and cell[1] < data.shape[1]:
                        data[cell] = value
                channels[name] = data
    return edit


@PROPERTY
@given(data=st.data())
def test_any_edit_of_the_pixels_is_refused_or_reads_a_valid_table(table_file, tmp_path, data):
    _, _, channels = parts_of(table_file)[0]
    shape = next(iter(channels.values())).shape
    edit = data.draw(pixel_edits(sorted(channels), shape))
    path = rewrite(table_file, tmp_path / "edited.exr", edit_pixels=edit)
    table = read_or_refuse(path)
    if table is not None:
        assert_valid(table)


# --- the checks one by one: each refusal's whole message --------------------------------
# check_header, check_sh_header and check_pixels are what read_table runs on a file's
# ``microsim`` and ``microsim_sh`` attributes and its channels; the message of their
# InputError, with the file's path as given, is the ``error:`` line a command prints
# (docs/table-format.md, "What a reader accepts"). The headers here are written out key by
# key: 2 incidences, 2 × 4 bins, the components of orders = 3.
COMPONENTS = ["total", "order1", "order2", "order3+"]
WHERE = "t.exr"


def header(isotropic: bool = True, wavelengths: list | None = None, folded: bool = False,
           theta_bins: int = 2, phi_bins: int = 4) -> dict:
    """A valid version 2 ``microsim`` attribute (the JSON, parsed): θi 0 and 0.5, φi 0
    (isotropic) or 0 and 3, the θo edges arcsin √(k / theta_bins), the φo edges uniform
    over [0, 2π] ([0, π] folded), an RGB table or one of ``wavelengths``."""
    b = 1 if isotropic else 2
    n = 3 if wavelengths is None else len(wavelengths)

    def per(value: Any) -> list:
        return [[[value] * n for _ in range(b)] for _ in range(2)]

    period = math.pi if folded else 2 * math.pi
    info = {
        "format_version": 2, "isotropic": isotropic,
        "axes": {"theta_i": {"values": [0.0, 0.5]},
                 "phi_i": {"values": [0.0] if isotropic else [0.0, 3.0]},
                 "theta_o": {"edges": [math.asin(math.sqrt(k / theta_bins))
                                       for k in range(theta_bins + 1)]},
                 "phi_o": {"edges": [period * k / phi_bins for k in range(phi_bins + 1)],
                           "folded": folded}},
        "layout": {"shape": [2, b, theta_bins, phi_bins]},
        "components": list(COMPONENTS), "orders": 3,
        "rays": [[10] * b, [20] * b], "realisations": [[2] * b, [3] * b],
        "albedo": per(0.5), "albedo_err": per(0.01),
        "order_albedo": {c: per(0.1) for c in COMPONENTS[1:]},
        "order_albedo_err": {c: per(None) for c in COMPONENTS[1:]},
        "lost_energy": per(0.0), "error_model": "ensemble",
        "dof": {c: per(3.0) for c in COMPONENTS}, "inflation": {c: per(None) for c in COMPONENTS},
        "meta": {"seed": 1},
    }
    if wavelengths is not None:
        info["wavelengths"] = wavelengths
    return info


def format1_header() -> dict:
    """A valid version 1 attribute: no components or orders; total and single albedos."""
    info = header()
    for key in ("components", "orders", "order_albedo", "order_albedo_err", "dof",
                "inflation", "realisations", "error_model"):
        del info[key]
    info.update(format_version=1, single_albedo=info["albedo"],
                single_albedo_err=info["albedo_err"])
    return info


def _with(*edits: Callable[[dict], Any], base: Callable[[], dict] = header
          ) -> Callable[[], dict]:
    """A header made by ``base`` and changed by ``edits`` in turn (an edit that returns a
    value replaces the header)."""
    def make() -> dict:
        info = base()
        for edit in edits:
            replaced = edit(info)
            info = info if replaced is None else replaced
        return info
    return make


ANGLES = "a non-empty list of distinct increasing angles >= 0 and "
WAVES = ("null (RGB) or a non-empty list of distinct increasing wavelengths in [200, 5000] "
         "nm")
PER_RGB = "nested as [2, 1, 3]"
COMPONENTS_RULE = ("a list of 'total' then the order components from the lowest, each once "
                   "(e.g. ['total', 'order1', 'order2', 'order3+'])")
THETA_O = "the bin edges arcsin(sqrt(k / theta_bins)), k = 0 … 2, in radians"
EDGES_COUNT = "a list of 2 to 65537 numbers (radians)"
HEADER_REFUSALS = {
    # the version
    "not an object": (_with(lambda info: [2]), "t.exr: table format version None; this microsim reads versions 1, 2"),
    "version 3": (_with(_set("format_version", 3)), "t.exr: table format version 3; this microsim reads versions 1, 2"),
    "version true": (_with(_set("format_version", True)), "t.exr: table format version True; this microsim reads versions 1, 2"),
    # the components and orders
    "no components": (_with(_drop("components")), "t.exr: header has no components"),
    "components a number": (_with(_set("components", 5)), "t.exr: header components = 5: must be " + COMPONENTS_RULE),
    "components a string": (_with(_set("components", "total")), "t.exr: header components = 'total': must be " + COMPONENTS_RULE),
    "components empty": (_with(_set("components", [])), "t.exr: header components = []: must be " + COMPONENTS_RULE),
    "components not strings": (_with(_set("components", ["total", 1])), "t.exr: header components = ['total', 1]: must be " + COMPONENTS_RULE),
    "components unknown": (_with(_set("components", ["total", "bounce1"])), "t.exr: header components = ['total', 'bounce1']: must be " + COMPONENTS_RULE),
    "components out of order": (_with(_set("components", ["total", "order2", "order1"])), "t.exr: header components = ['total', 'order2', 'order1']: must be " + COMPONENTS_RULE),
    "components repeated": (_with(_set("components", ["total", "order1", "order1"])), "t.exr: header components = ['total', 'order1', 'order1']: must be " + COMPONENTS_RULE),
    "components without total": (_with(_set("components", ["order1", "order2+"])), "t.exr: header components = ['order1', 'order2+']: must be " + COMPONENTS_RULE),
    "orders wrong": (_with(_set("orders", 5)), "t.exr: header orders = 5: must be 3 (the components ['total', 'order1', 'order2', 'order3+'])"),
    "orders missing": (_with(_drop("orders")), "t.exr: header orders = None: must be 3 (the components ['total', 'order1', 'order2', 'order3+'])"),
    "orders true for one order": (_with(_set("components", ["total", "order1+"]), _set("orders", True)), "t.exr: header orders = True: must be 1 (the components ['total', 'order1+'])"),
    "orders of a split that implies none": (_with(_set("components", ["total", "order1", "order2"])), "t.exr: header orders = 3: must be null (the components ['total', 'order1', 'order2'])"),
    "orders of total alone": (_with(_set("components", ["total"]), _set("orders", 0)), "t.exr: header orders = 0: must be null (the components ['total'])"),
}
HEADER_REFUSALS.update({
    "no isotropic": (_with(_drop("isotropic")), "t.exr: header has no isotropic"),
    "isotropic a string": (_with(_set("isotropic", "yes")), "t.exr: header isotropic = 'yes': must be true or false"),
    "no axes": (_with(_drop("axes")), "t.exr: header has no axes"),
    "axes a list": (_with(_set("axes", [1])), "t.exr: header axes = [1]: must be an object"),
    "no theta_i": (_with(_drop("axes.theta_i")), "t.exr: header has no axes.theta_i"),
    "theta_i a number": (_with(_set("axes.theta_i", 5)), "t.exr: header axes.theta_i = 5: must be an object"),
    "no theta_i values": (_with(_set("axes.theta_i", {})), "t.exr: header has no axes.theta_i.values"),
    "theta_i values a number": (_with(_set("axes.theta_i.values", 5)), "t.exr: header axes.theta_i.values = 5: must be " + ANGLES + "<= 1.570796327 (radians)"),
    "theta_i values empty": (_with(_set("axes.theta_i.values", [])), "t.exr: header axes.theta_i.values = []: must be " + ANGLES + "<= 1.570796327 (radians)"),
    "theta_i values strings": (_with(_set("axes.theta_i.values", ["0", "1"])), "t.exr: header axes.theta_i.values = ['0', '1']: must be " + ANGLES + "<= 1.570796327 (radians)"),
    "theta_i negative": (_with(_set("axes.theta_i.values", [-1e-300, 0.5])), "t.exr: header axes.theta_i.values = [-1e-300, 0.5]: must be " + ANGLES + "<= 1.570796327 (radians)"),
    "theta_i past 90 degrees": (_with(_set("axes.theta_i.values", [0.0, math.pi / 2 + 2e-9])), "t.exr: header axes.theta_i.values = [0.0, 1.5707963287948965]: must be " + ANGLES + "<= 1.570796327 (radians)"),
    "theta_i repeated": (_with(_set("axes.theta_i.values", [0.5, 0.5])), "t.exr: header axes.theta_i.values = [0.5, 0.5]: must be " + ANGLES + "<= 1.570796327 (radians)"),
    "theta_i decreasing": (_with(_set("axes.theta_i.values", [0.5, 0.0])), "t.exr: header axes.theta_i.values = [0.5, 0.0]: must be " + ANGLES + "<= 1.570796327 (radians)"),
    "phi_i at 2 pi": (_with(_set("axes.phi_i.values", [0.0, 2 * math.pi]), base=lambda: header(isotropic=False)), "t.exr: header axes.phi_i.values = [0.0, 6.283185307179586]: must be " + ANGLES + "< 6.283185307 (radians)"),
    "phi_i of an isotropic table": (_with(_set("axes.phi_i.values", [1.0])), "t.exr: header axes.phi_i.values = [1.0]: must be [0] (the table is isotropic)"),
})
HEADER_REFUSALS.update({
    "no theta_o": (_with(_drop("axes.theta_o")), "t.exr: header has no axes.theta_o"),
    "theta_o a list": (_with(_set("axes.theta_o", [0])), "t.exr: header axes.theta_o = [0]: must be an object"),
    "no theta_o edges": (_with(_set("axes.theta_o", {})), "t.exr: header has no axes.theta_o.edges"),
    "no phi_o": (_with(_drop("axes.phi_o")), "t.exr: header has no axes.phi_o"),
    "phi_o a list": (_with(_set("axes.phi_o", [0])), "t.exr: header axes.phi_o = [0]: must be an object"),
    "no phi_o edges": (_with(_drop("axes.phi_o.edges")), "t.exr: header has no axes.phi_o.edges"),
    "folded a string": (_with(_set("axes.phi_o.folded", "no")), "t.exr: header axes.phi_o.folded = 'no': must be true or false"),
    "theta_o edges a number": (_with(_set("axes.theta_o.edges", 2)), "t.exr: header axes.theta_o.edges = 2: must be " + EDGES_COUNT),
    "theta_o edges one": (_with(_set("axes.theta_o.edges", [0.0])), "t.exr: header axes.theta_o.edges = [0.0]: must be " + EDGES_COUNT),
    "theta_o edges strings": (_with(_set("axes.theta_o.edges", ["0", "1"])), "t.exr: header axes.theta_o.edges = ['0', '1']: must be " + EDGES_COUNT),
    "phi_o edges one": (_with(_set("axes.phi_o.edges", [0.0])), "t.exr: header axes.phi_o.edges = [0.0]: must be " + EDGES_COUNT),
    "theta_o edges too many": (_with(_set("axes.theta_o.edges", [0.0] * 65538)), "t.exr: header axes.theta_o.edges = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0…: must be " + EDGES_COUNT),
    "theta_o edges not arcsin": (_with(_set("axes.theta_o.edges", [0.0, 0.5, math.pi / 2])), "t.exr: header axes.theta_o.edges = [0.0, 0.5, 1.5707963267948966]: must be " + THETA_O),
    "theta_o edge off by 2e-9": (_with(lambda info: info["axes"]["theta_o"]["edges"].__setitem__(1, math.pi / 4 + 2e-9)), "t.exr: header axes.theta_o.edges = [0.0, 0.7853981653974483, 1.5707963267948966]: must be " + THETA_O),
    "phi_o edges of a folded table": (_with(_set("axes.phi_o.edges", [0.0, 1.0, 2.0, 3.0, 4.0])), "t.exr: header axes.phi_o.edges = [0.0, 1.0, 2.0, 3.0, 4.0]: must be the bin edges uniform over [0, 2 pi] (folded = false), k = 0 … 4, in radians"),
    "phi_o edges over 2 pi when folded": (_with(_set("axes.phi_o.folded", True)), "t.exr: header axes.phi_o.edges = [0.0, 1.5707963267948966, 3.141592653589793, 4.712388980384…: must be the bin edges uniform over [0, pi] (folded = true), k = 0 … 4, in radians"),
    "no layout": (_with(_drop("layout")), "t.exr: header has no layout"),
    "layout a list": (_with(_set("layout", [])), "t.exr: header layout = []: must be an object"),
    "no layout shape": (_with(_set("layout", {})), "t.exr: header has no layout.shape"),
    "layout shape wrong": (_with(_set("layout.shape", [2, 1, 8, 15])), "t.exr: header layout.shape = [2, 1, 8, 15]: must be [2, 1, 2, 4] (n_theta_i, n_phi_i, theta_bins, phi_bins of the axes)"),
})
HEADER_REFUSALS.update({
    "wavelengths a string": (_with(_set("wavelengths", "500")), "t.exr: header wavelengths = '500': must be " + WAVES),
    "wavelengths empty": (_with(_set("wavelengths", [])), "t.exr: header wavelengths = []: must be " + WAVES),
    "wavelengths not numbers": (_with(_set("wavelengths", [500.0, True])), "t.exr: header wavelengths = [500.0, True]: must be " + WAVES),
    "wavelength below 200 nm": (_with(_set("wavelengths", [199.99, 500.0])), "t.exr: header wavelengths = [199.99, 500.0]: must be " + WAVES),
    "wavelength above 5000 nm": (_with(_set("wavelengths", [500.0, 5000.01])), "t.exr: header wavelengths = [500.0, 5000.01]: must be " + WAVES),
    "wavelengths repeated": (_with(_set("wavelengths", [500.0, 500.0])), "t.exr: header wavelengths = [500.0, 500.0]: must be " + WAVES),
    "wavelengths decreasing": (_with(_set("wavelengths", [600.0, 500.0, 700.0])), "t.exr: header wavelengths = [600.0, 500.0, 700.0]: must be " + WAVES),
    "no rays": (_with(_drop("rays")), "t.exr: header has no rays"),
    "rays a string": (_with(_set("rays", "many")), "t.exr: header rays = 'many': must be integers >= 0, nested as [2, 1]"),
    "rays negative": (_with(_set("rays", [[-1], [5]])), "t.exr: header rays = [[-1], [5]]: must be integers >= 0, nested as [2, 1]"),
    "rays fractional": (_with(_set("rays", [[1.5], [5]])), "t.exr: header rays = [[1.5], [5]]: must be integers >= 0, nested as [2, 1]"),
    "rays null": (_with(_set("rays", [[None], [5]])), "t.exr: header rays = [[None], [5]]: must be integers >= 0, nested as [2, 1]"),
    "rays true": (_with(_set("rays", [[True], [5]])), "t.exr: header rays = [[True], [5]]: must be integers >= 0, nested as [2, 1]"),
    "rays beyond float64": (_with(_set("rays", [[10**400], [5]])), "t.exr: header rays = [[100000000000000000000000000000000000000000000000000000000…: must be integers >= 0, nested as [2, 1]"),
    "realisations zero": (_with(_set("realisations", [[0], [4]])), "t.exr: header realisations = [[0], [4]]: must be integers >= 1, nested as [2, 1]"),
    "realisations flat": (_with(_set("realisations", [2, 3])), "t.exr: header realisations = [2, 3]: must be integers >= 1, nested as [2, 1]"),
    "no albedo": (_with(_drop("albedo")), "t.exr: header has no albedo"),
    "no albedo error": (_with(_drop("albedo_err")), "t.exr: header has no albedo_err"),
    "no order albedo": (_with(_drop("order_albedo")), "t.exr: header has no order_albedo"),
    "no order albedo error": (_with(_drop("order_albedo_err")), "t.exr: header has no order_albedo_err"),
    "albedo negative": (_with(_set("albedo", [[[0.5, 0.5, -1.0]], [[0.4, 0.4, 0.4]]])), "t.exr: header albedo = [[[0.5, 0.5, -1.0]], [[0.4, 0.4, 0.4]]]: must be numbers >= 0, " + PER_RGB),
    "albedo null": (_with(_set("albedo", [[[None] * 3], [[1, 1, 1]]])), "t.exr: header albedo = [[[None, None, None]], [[1, 1, 1]]]: must be numbers >= 0, " + PER_RGB),
    "albedo short": (_with(_set("albedo", [[[1, 1]], [[1, 1, 1]]])), "t.exr: header albedo = [[[1, 1]], [[1, 1, 1]]]: must be numbers >= 0, " + PER_RGB),
    "albedo error negative": (_with(_set("albedo_err", [[[None, 0.0, -0.1]], [[0, 0, 0]]])), "t.exr: header albedo_err = [[[None, 0.0, -0.1]], [[0, 0, 0]]]: must be numbers >= 0 or null, " + PER_RGB),
    "an order's albedo a string": (_with(_set("order_albedo.order2", "x")), "t.exr: header order_albedo.order2 = 'x': must be numbers >= 0, " + PER_RGB),
    "an order's albedo error negative": (_with(_set("order_albedo_err.order3+", [[[-1, 0, 0]], [[0, 0, 0]]])), "t.exr: header order_albedo_err.order3+ = [[[-1, 0, 0]], [[0, 0, 0]]]: must be numbers >= 0 or null, " + PER_RGB),
    "order albedo a list": (_with(_set("order_albedo", [])), "t.exr: header order_albedo = []: must be an object with one entry per order component (order1, order2, order3+)"),
    "order albedo missing a component": (_with(_drop("order_albedo.order2")), "t.exr: header order_albedo = {'order1': [[[0.1, 0.1, 0.1]], [[0.1, 0.1, 0.1]]], 'order3+…: must be an object with one entry per order component (order1, order2, order3+)"),
    "order albedo error with total": (_with(_set("order_albedo_err.total", 0)), "t.exr: header order_albedo_err = {'order1': [[[None, None, None]], [[None, None, None]]], 'o…: must be an object with one entry per order component (order1, order2, order3+)"),
    "lost energy infinite": (_with(_set("lost_energy", [[[0, 0, 1e999]], [[0, 0, 0]]])), "t.exr: header lost_energy = [[[0, 0, inf]], [[0, 0, 0]]]: must be numbers >= 0, " + PER_RGB),
    "no lost energy": (_with(_drop("lost_energy")), "t.exr: header has no lost_energy"),
    "error model unknown": (_with(_set("error_model", "bootstrap")), "t.exr: header error_model = 'bootstrap': must be 'rays' or 'ensemble'"),
    "dof a list": (_with(_set("dof", [1])), "t.exr: header dof = [1]: must be an object with one entry per component (total, order1, order2, order3+)"),
    "dof of other components": (_with(_set("dof", {"total": 0})), "t.exr: header dof = {'total': 0}: must be an object with one entry per component (total, order1, order2, order3+)"),
    "dof of an order negative": (_with(_set("dof.order1", [[[-1, 0, 0]], [[0, 0, 0]]])), "t.exr: header dof.order1 = [[[-1, 0, 0]], [[0, 0, 0]]]: must be numbers >= 0 or null, " + PER_RGB),
    "inflation of total a string": (_with(_set("inflation.total", "x")), "t.exr: header inflation.total = 'x': must be numbers >= 0 or null, " + PER_RGB),
    "no meta": (_with(_drop("meta")), "t.exr: header has no meta"),
    "meta a list": (_with(_set("meta", [1])), "t.exr: header meta = [1]: must be an object"),
    "meta input without its sha256": (_with(_set("meta.inputs", [{"part": "base", "path": "a.exr", "component": "total"}])), "t.exr: header meta cannot be read (KeyError: 'sha256')"),
    "format 1 without single albedo": (_with(_drop("single_albedo"), base=format1_header), "t.exr: header has no single_albedo"),
    "format 1 single albedo negative": (_with(_set("single_albedo", [[[-1, 0, 0]], [[0, 0, 0]]]), base=format1_header), "t.exr: header single_albedo = [[[-1, 0, 0]], [[0, 0, 0]]]: must be numbers >= 0, " + PER_RGB),
    "format 1 single albedo error negative": (_with(_set("single_albedo_err", [[[-1, 0, 0]], [[0, 0, 0]]]), base=format1_header), "t.exr: header single_albedo_err = [[[-1, 0, 0]], [[0, 0, 0]]]: must be numbers >= 0 or null, " + PER_RGB),
    "format 1 without albedo": (_with(_drop("albedo"), base=format1_header), "t.exr: header has no albedo"),
    "format 1 without single albedo error": (_with(_drop("single_albedo_err"), base=format1_header), "t.exr: header has no single_albedo_err"),
    "format 1 albedo negative": (_with(_set("albedo", [[[-1, 0, 0]], [[0, 0, 0]]]), base=format1_header), "t.exr: header albedo = [[[-1, 0, 0]], [[0, 0, 0]]]: must be numbers >= 0, " + PER_RGB),
    "format 1 albedo error negative": (_with(_set("albedo_err", [[[-1, 0, 0]], [[0, 0, 0]]]), base=format1_header), "t.exr: header albedo_err = [[[-1, 0, 0]], [[0, 0, 0]]]: must be numbers >= 0 or null, " + PER_RGB),
    "format 1 without albedo error": (_with(_drop("albedo_err"), base=format1_header), "t.exr: header has no albedo_err"),
})


@pytest.mark.parametrize("case", sorted(HEADER_REFUSALS))
def test_a_bad_header_is_refused_with_its_whole_message(case):
    """One refusal per check and branch of check_header: the key, the value as shown (its
    repr, cut to 60 characters with "…"), and what is allowed, as docs/table-format.md's
    rules say it."""
    make, message = HEADER_REFUSALS[case]
    assert refused(InputError, lambda: validation.check_header(make(), WHERE)) == message


def test_a_meta_that_cannot_be_read_shows_its_exception_on_one_line_cut_with_an_ellipsis(
        monkeypatch):
    """The reason a header's meta cannot be read is the exception's message without
    quotes, escaped onto one line (a newline shown as \\n) and cut to 60 characters, the
    last one "…" where it was cut; a short one whole."""
    from microsim.tables.meta import TableMeta

    def raising(message):
        def from_json(_):
            raise ValueError(message)
        return from_json

    long = "a reason on\ntwo lines, " + "x" * 80
    monkeypatch.setattr(TableMeta, "from_json", staticmethod(raising(long)))
    shown = (r"a reason on\ntwo lines, " + "x" * 80)[:59] + "…"
    assert refused(InputError, lambda: validation.check_header(header(), WHERE)) == (
        f"t.exr: header meta cannot be read (ValueError: {shown})")
    monkeypatch.setattr(TableMeta, "from_json", staticmethod(raising("short")))
    assert refused(InputError, lambda: validation.check_header(header(), WHERE)) == (
        "t.exr: header meta cannot be read (ValueError: short)")


def _nudge(path: str, index: int, delta: float) -> Callable[[dict], None]:
    """An edit adding ``delta`` to item ``index`` of the list at the dotted ``path``."""
    def edit(info: dict) -> None:
        node = info
        for k in path.split("."):
            node = node[k]
        node[index] += delta
    return edit


HEADER_BOUNDARIES = {
    "theta_i at 90 degrees": _with(_set("axes.theta_i.values", [0.0, math.pi / 2])),
    "theta_i 1e-9 past 90 degrees": _with(_set("axes.theta_i.values",
                                               [0.0, math.pi / 2 + 1e-9])),
    "phi_i just below 2 pi": _with(
        _set("axes.phi_i.values", [0.0, math.nextafter(2 * math.pi, 0.0)]),
        base=lambda: header(isotropic=False)),
    "one theta_o and one phi_o bin": lambda: header(theta_bins=1, phi_bins=1),
    "65536 theta_o bins": lambda: header(theta_bins=65536),
    "a theta_o edge 0.5e-9 off": _with(_nudge("axes.theta_o.edges", 1, 0.5e-9)),
    "a phi_o edge 0.5e-9 off": _with(_nudge("axes.phi_o.edges", 4, -0.5e-9)),
    "folded": lambda: header(folded=True),
    "folded left out": _with(_drop("axes.phi_o.folded")),
    "wavelengths at 200 and 5000 nm": lambda: header(wavelengths=[200.0, 5000.0]),
    "one wavelength": lambda: header(wavelengths=[500.0]),
    "wavelengths 0.5 nm apart": lambda: header(wavelengths=[500.0, 500.5]),
    "wavelengths null": _with(_set("wavelengths", None)),
    "zero rays, one realisation, zero albedo": _with(
        _set("rays", [[0], [0]]), _set("realisations", [[1], [1]]),
        _set("albedo", [[[0, 0, 0]], [[0, 0, 0]]])),
    "realisations, error model, dof and inflation left out": _with(
        _drop("realisations"), _drop("error_model"), _drop("dof"), _drop("inflation")),
    "dof and inflation null": _with(_set("dof", None), _set("inflation", None)),
    "total alone": _with(_set("components", ["total"]), _set("orders", None),
                         _set("order_albedo", {}), _set("order_albedo_err", {}),
                         _set("dof", {"total": [[[1, 1, 1]], [[1, 1, 1]]]}),
                         _set("inflation", None)),
    "orders 1": _with(_set("components", ["total", "order1+"]), _set("orders", 1),
                      _set("order_albedo", {"order1+": [[[0, 0, 0]], [[0, 0, 0]]]}),
                      _set("order_albedo_err", {"order1+": [[[0, 0, 0]], [[0, 0, 0]]]}),
                      _set("dof", None), _set("inflation", None)),
    "a split that implies no orders": _with(
        _set("components", ["total", "order1", "order2"]), _set("orders", None),
        _drop("order_albedo.order3+"), _drop("order_albedo_err.order3+"),
        _set("dof", None), _set("inflation", None)),
    "format 1": format1_header,
}


@pytest.mark.parametrize("case", sorted(HEADER_BOUNDARIES))
def test_a_header_on_the_boundaries_of_its_rules_is_read(case):
    """The other side of each boundary the refusals above test: θi up to π/2 (+1e-9 rad),
    φi below 2π, 1 to 65536 bins per axis, edges within 1e-9 rad, wavelengths in
    [200, 5000] nm (one of them, or 0.5 nm apart), 0 rays, 1 realisation, albedo 0, the keys
    that may be left out or null, orders null or 1, format 1."""
    info = HEADER_BOUNDARIES[case]()
    checked = validation.check_header(copy.deepcopy(info), WHERE)
    assert checked["shape"] == tuple(info["layout"]["shape"])


def test_check_header_gives_what_the_header_says():
    """check_header's result, key by key, for an anisotropic spectral folded header and for
    the isotropic RGB one with the optional keys left out: the components, the bins the
    edges describe, the axes, the shape, the rays and realisations as integers, the
    channels, every per-component array (null read as NaN), the error model and meta."""
    from microsim.spectra.channels import Channels

    info = header(isotropic=False, wavelengths=[400.0, 500.0], folded=True)
    info["rays"] = [[10, 11], [20, 21]]
    info["albedo"][1][0] = [0.25, 0.75]
    info["order_albedo_err"]["order2"][0][1] = [0.5, None]
    info["dof"]["order3+"][1][1] = [None, 7.0]
    got = validation.check_header(copy.deepcopy(info), WHERE)
    assert got["components"] == tuple(COMPONENTS)
    bins = got["bins"]
    assert (bins.theta_bins, bins.phi_bins, bins.phi_period) == (2, 4, math.pi)
    np.testing.assert_array_equal(got["theta_i"], [0.0, 0.5])
    np.testing.assert_array_equal(got["phi_i"], [0.0, 3.0])
    assert got["isotropic"] is False and got["shape"] == (2, 2, 2, 4)
    assert got["rays"].dtype == np.int64 and got["rays"].tolist() == [[10, 11], [20, 21]]
    assert got["realisations"].dtype == np.int64
    assert got["realisations"].tolist() == [[2, 2], [3, 3]]
    assert got["channels"] == Channels((400.0, 500.0))
    expected = {"albedo": {c: info["albedo"] if c == "total" else info["order_albedo"][c]
                           for c in COMPONENTS},
                "albedo_err": {c: info["albedo_err"] if c == "total"
                               else info["order_albedo_err"][c] for c in COMPONENTS},
                "dof": info["dof"], "inflation": info["inflation"]}
    for key, arrays in expected.items():
        assert list(got[key]) == COMPONENTS, key
        for c in COMPONENTS:
            want = np.array(arrays[c], dtype=float)
            assert got[key][c].dtype == np.float64 and got[key][c].shape == (2, 2, 2)
            np.testing.assert_array_equal(got[key][c], want, err_msg=f"{key}.{c}")
    np.testing.assert_array_equal(got["lost_energy"], np.zeros((2, 2, 2)))
    assert got["error_model"] == "ensemble" and got["meta"].seed == 1

    info = header()
    for key in ("realisations", "error_model", "dof", "inflation"):
        del info[key]
    got = validation.check_header(info, WHERE)
    assert got["realisations"] is None and got["error_model"] == "rays"
    assert got["dof"] is None and got["inflation"] is None
    assert got["channels"] == Channels() and got["isotropic"] is True
    assert got["bins"].phi_period == 2 * math.pi
    assert validation.check_header(format1_header(), WHERE)["components"] == ("total",
                                                                              "single")


SH_REFUSALS = {
    "not an object": ([9], "t.exr: header sh = [9]: must be an object"),
    "no order": ({"coefficients": 9}, "t.exr: header has no sh.order"),
    "order negative": ({"order": -1, "coefficients": 0},
                       "t.exr: header sh.order = -1: must be an integer in [0, 4096]"),
    "order past 4096": ({"order": 4097, "coefficients": 4098 ** 2},
                        "t.exr: header sh.order = 4097: must be an integer in [0, 4096]"),
    "order a float": ({"order": 2.0, "coefficients": 9},
                      "t.exr: header sh.order = 2.0: must be an integer in [0, 4096]"),
    "order true": ({"order": True, "coefficients": 4},
                   "t.exr: header sh.order = True: must be an integer in [0, 4096]"),
    "order a string": ({"order": "2", "coefficients": 9},
                       "t.exr: header sh.order = '2': must be an integer in [0, 4096]"),
    "no coefficients": ({"order": 2}, "t.exr: header has no sh.coefficients"),
    "coefficients not (order + 1)^2": (
        {"order": 2, "coefficients": 10},
        "t.exr: header sh.coefficients = 10: must be 9 ((order + 1)^2 for order 2)"),
    "coefficients true": ({"order": 0, "coefficients": True},
                          "t.exr: header sh.coefficients = True: must be 1 ((order + 1)^2 for "
                          "order 0)"),
    "shape wrong": ({"order": 2, "coefficients": 9, "shape": [1, 2]},
                    "t.exr: header sh.shape = [1, 2]: must be [2, 1] (n_theta_i, n_phi_i)"),
}


@pytest.mark.parametrize("case", sorted(SH_REFUSALS))
def test_a_bad_harmonics_header_is_refused_with_its_whole_message(case):
    """check_sh_header (the ``microsim_sh`` attribute of the ``sh`` part) for a table of
    shape (2, 1, 8, 16): order an integer in [0, 4096], coefficients (order + 1)², shape
    the table's (n_theta_i, n_phi_i)."""
    sh, message = SH_REFUSALS[case]
    assert refused(InputError,
                   lambda: validation.check_sh_header(sh, WHERE, (2, 1, 8, 16))) == message


@pytest.mark.parametrize(("sh", "coefficients"), [
    ({"order": 0, "coefficients": 1}, 1),
    ({"order": 2, "coefficients": 9}, 9),
    ({"order": 2, "coefficients": 9, "shape": [2, 1]}, 9),
    ({"order": 4096, "coefficients": 4097 ** 2}, 4097 ** 2),
])
def test_a_harmonics_header_on_its_boundaries_is_read(sh, coefficients):
    """Orders 0 and 4096, the shape given or left out: the coefficients per row."""
    assert validation.check_sh_header(sh, WHERE, (2, 1, 8, 16)) == coefficients


def _pixels(names: tuple[str, ...] = ("R", "G", "B"), rows: int = 2, columns: int = 3
            ) -> dict[str, np.ndarray]:
    """Valid channels of the components total and order1: values 1, errors 0.1."""
    return {f"{c}{s}.{k}": np.full((rows, columns), 0.1 if s else 1.0, np.float32)
            for c in ("total", "order1") for s in ("", "_err") for k in names}


def _pixel(name: str, row: int, column: int, value: float, *more: tuple
           ) -> Callable[[dict], None]:
    """An edit setting pixel (row, column) of channel ``name`` to ``value`` (and the
    further (name, row, column, value) of ``more``)."""
    def edit(pixels: dict) -> None:
        for n, r, c, v in ((name, row, column, value), *more):
            pixels[n][r, c] = v
    return edit


VALUE = "must be finite and >= 0"
ERROR = "must be finite and >= 0, or NaN where the bin is empty (value 0)"
SH_ERROR = "must be finite and >= 0, or NaN where undefined"
PIXEL_REFUSALS = {
    "a value channel missing": (False, lambda p: p.pop("order1.G"),
                                "t.exr: channel order1.G is missing"),
    "an error channel missing": (False, lambda p: p.pop("total_err.B"),
                                 "t.exr: channel total_err.B is missing"),
    "a harmonics channel missing": (True, lambda p: p.pop("order1_err.R"),
                                    "t.exr: harmonics channel order1_err.R is missing"),
    "a channel of another shape": (
        False, lambda p: p.__setitem__("order1_err.G", np.zeros((3, 2), np.float32)),
        "t.exr: channel order1_err.G has shape (3, 2); the header's axes give (2, 3)"),
    "a harmonics channel of another shape": (
        True, lambda p: p.__setitem__("total.B", np.zeros(6, np.float32)),
        "t.exr: harmonics channel total.B has shape (6,); the header's axes give (2, 3)"),
    "a NaN value": (False, _pixel("total.G", 1, 2, np.nan),
                    "t.exr: channel total.G holds nan at row 1, column 2 (1 such pixels): "
                    + VALUE),
    "negative values": (False, _pixel("order1.R", 1, 0, -1.0, ("order1.R", 0, 2, -2.0)),
                        "t.exr: channel order1.R holds -2.0 at row 0, column 2 (2 such "
                        "pixels): " + VALUE),
    "an infinite value": (False, _pixel("total.B", 0, 1, np.inf),
                          "t.exr: channel total.B holds inf at row 0, column 1 (1 such "
                          "pixels): " + VALUE),
    "a NaN error of a full bin": (False, _pixel("total_err.R", 0, 0, np.nan),
                                  "t.exr: channel total_err.R holds nan at row 0, column 0 "
                                  "(1 such pixels): " + ERROR),
    "a tiny negative error": (False, _pixel("order1_err.B", 1, 1, -1e-30),
                                      "t.exr: channel order1_err.B holds -1.0000000031710769e-30"
                                      " at row 1, column 1 (1 such pixels): " + ERROR),
    "an infinite error": (False, _pixel("order1_err.G", 0, 0, np.inf),
                          "t.exr: channel order1_err.G holds inf at row 0, column 0 (1 such "
                          "pixels): " + ERROR),
    "an infinite coefficient": (True, _pixel("order1.G", 1, 2, -np.inf),
                                "t.exr: harmonics channel order1.G holds -inf at row 1, column "
                                "2 (1 such pixels): must be finite"),
    "a NaN coefficient": (True, _pixel("total.R", 0, 0, np.nan),
                          "t.exr: harmonics channel total.R holds nan at row 0, column 0 (1 "
                          "such pixels): must be finite"),
    "a negative coefficient error": (True, _pixel("total_err.G", 0, 1, -0.5),
                                     "t.exr: harmonics channel total_err.G holds -0.5 at row 0,"
                                     " column 1 (1 such pixels): " + SH_ERROR),
    "an infinite coefficient error": (True, _pixel("total_err.G", 0, 1, np.inf),
                                      "t.exr: harmonics channel total_err.G holds inf at row "
                                      "0, column 1 (1 such pixels): " + SH_ERROR),
}


@pytest.mark.parametrize("case", sorted(PIXEL_REFUSALS))
def test_bad_pixels_are_refused_with_their_whole_message(case):
    """check_pixels on 2 × 3 channels of the components total and order1: the first
    channel (component, then colour, value before error) that is missing, of another shape
    or holding a value that is not allowed, the first such pixel in row order with its
    row, column and value, how many there are, and what is allowed (bin values finite and
    >= 0, errors finite and >= 0 or NaN where the value is 0; harmonic coefficients finite,
    their errors finite and >= 0 or NaN)."""
    harmonics, edit, message = PIXEL_REFUSALS[case]
    pixels = _pixels()
    edit(pixels)
    assert refused(InputError, lambda: validation.check_pixels(
        pixels, ("total", "order1"), 2, 3, WHERE, harmonics=harmonics)) == message


@pytest.mark.parametrize(("harmonics", "edit"), [
    (False, _pixel("total.R", 0, 0, 0.0, ("total_err.R", 0, 0, np.nan))),
    (False, _pixel("order1.B", 1, 2, 0.0, ("order1_err.B", 1, 2, 0.0))),
    (False, _pixel("total.G", 1, 1, 3.0e38, ("total_err.G", 1, 1, 3.0e38))),
    (True, _pixel("total.R", 0, 0, -2.0, ("total_err.R", 0, 0, np.nan))),
    (True, _pixel("order1.G", 1, 2, 1.0, ("order1_err.G", 1, 2, np.nan))),
    (True, _pixel("order1.B", 0, 1, 0.0, ("order1_err.B", 0, 1, 0.0))),
])
def test_pixels_on_the_boundaries_of_their_rules_are_read(harmonics, edit):
    """A value 0 with a NaN or 0 error, the largest float32s; a negative coefficient, a
    coefficient's error NaN whatever its value, both 0."""
    pixels = _pixels()
    edit(pixels)
    validation.check_pixels(pixels, ("total", "order1"), 2, 3, WHERE, harmonics=harmonics)


def test_the_pixels_of_a_spectral_table_are_named_by_their_wavelength():
    pixels = _pixels(names=("400nm", "552p5nm"))
    validation.check_pixels(pixels, ("total", "order1"), 2, 3, WHERE,
                            names=("400nm", "552p5nm"))
    pixels["order1.552p5nm"][0, 0] = -1.0
    assert refused(InputError, lambda: validation.check_pixels(
        pixels, ("total", "order1"), 2, 3, WHERE, names=("400nm", "552p5nm"))) == (
        "t.exr: channel order1.552p5nm holds -1.0 at row 0, column 0 (1 such pixels): "
        + VALUE)


def test_a_value_is_shown_cut_to_sixty_characters():
    """``_shown``: the repr whole up to SHOWN = 60 characters; one more, and it is cut to
    59 characters and "…" (60 in all); the same in a refusal's message."""
    assert validation.SHOWN == 60
    text60 = "x" * 58  # its repr: 60 characters
    assert validation._shown(text60) == "'" + text60 + "'"
    assert validation._shown(text60 + "y") == "'" + "x" * 58 + "…"
    assert validation._shown(list(range(21))) == (
        "[0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, …")
    assert validation._shown([0.5]) == "[0.5]"
    assert refused(InputError, lambda: validation.check_header(
        _with(_set("error_model", text60 + "y"))(), WHERE)) == (
        "t.exr: header error_model = '" + "x" * 58 + "…: must be 'rays' or 'ensemble'")


def test_numbers_without_a_lower_bound_and_of_an_empty_shape():
    """``numbers`` with ``low=None`` takes any finite number (negative ones too) and, when
    it refuses, says "numbers" or "integers" with no bound; and its array has the shape
    asked for even where the nested lists do not show it: ``[]`` for (0, 3) is an empty
    (0, 3) array, not a (0,) one."""
    where = validation._Where(WHERE)
    got = validation.numbers(where, [-1.5, 2.0], "x", (2,), low=None)
    assert got.dtype == np.float64 and got.tolist() == [-1.5, 2.0]
    got = validation.numbers(where, [[-3], [None]], "x", (2, 1), low=None, nulls=True)
    assert got[0, 0] == -3.0 and np.isnan(got[1, 0])
    assert refused(InputError,
                   lambda: validation.numbers(where, [1, "2"], "x", (2,), low=None)) == (
        "t.exr: header x = [1, '2']: must be numbers, nested as [2]")
    assert refused(InputError, lambda: validation.numbers(where, [1.5], "n", (1,), low=None,
                                               integer=True)) == (
        "t.exr: header n = [1.5]: must be integers, nested as [1]")
    assert validation.numbers(where, [-2], "n", (1,), low=None, integer=True).tolist() == [-2]
    for shape in ((0, 3), (0,), (0, 2, 3)):
        got = validation.numbers(where, [], "x", shape)
        assert got.shape == shape and got.dtype == np.float64
    assert validation.numbers(where, [], "n", (0, 3), integer=True).shape == (0, 3)
