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
from test_robustness import GAUSSIAN, SMALL, one_error_line

import microsim
from microsim.errors import InputError

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
        v, e = table.values[c], table.errors[c]
        assert np.all(np.isfinite(v) & (v >= 0))
        assert np.all(np.isfinite(e) & (e >= 0) | np.isnan(e) & (v == 0))
        assert np.all(np.isfinite(table.albedo_of[c]) & (table.albedo_of[c] >= 0))
        if table.sh is not None:
            s, se = table.sh[c], table.sh_err[c]
            assert np.all(np.isfinite(s))
            assert np.all(np.isfinite(se) & (se >= 0) | np.isnan(se))
    rng = np.random.default_rng(0)
    wi = rng.normal(size=(64, 3))
    wo = rng.normal(size=(64, 3))
    wi[:, 2], wo[:, 2] = np.abs(wi[:, 2]), np.abs(wo[:, 2])
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    assert np.all(np.isfinite(table.eval(wi, wo)))
    if table.sh is not None:
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
    table.values["order1"][0, 0, 0, 0, 0] = np.nan
    with pytest.raises(InputError, match="not written: channel order1.R holds nan"):
        microsim.write_table(table, tmp_path / "nan.exr")
    assert not (tmp_path / "nan.exr").exists()
    table = microsim.read_table(table_file)
    table.albedo_of["total"][1, 0, 2] = np.inf
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
