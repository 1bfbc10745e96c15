"""Exports: npz, MERL .binary (read back by an independent reader written from the
published layout) and RGL .bsdf (loaded and evaluated by Mitsuba 3 itself)."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest

import microsim
from microsim.analytic.brdf import TorranceSparrow
from microsim.analytic.fresnel import ConductorFresnel
from microsim.analytic.ndf import Beckmann
from microsim.comparison.metrics import model_table
from microsim.tables.binning import HemisphereBins
from microsim.tables.export import rgl_through_mitsuba
from microsim.tables.exr import write_table
from microsim.tables.meta import TableMeta

THETA_I = np.radians([0.0, 20.0, 40.0, 60.0, 75.0])


@pytest.fixture(scope="module")
def table_path(tmp_path_factory):
    """A smooth table: a conductor Beckmann α = 0.45 lobe averaged over 32 × 64 bins."""
    model = TorranceSparrow(Beckmann(0.45), fresnel=ConductorFresnel(np.array([0.2, 0.9, 1.1]),
                                                     np.array([3.9, 2.4, 2.1])))
    table = model_table(model, THETA_I, HemisphereBins(32, 64), meta=TableMeta.from_json({"surface": {"kind": "test"}}))
    path = tmp_path_factory.mktemp("export") / "t.exr"
    write_table(table, path)
    return path


def test_npz(cli, table_path, tmp_path):
    out = tmp_path / "t.npz"
    assert cli("export", str(table_path), "--format", "npz", "-o", str(out))[0] == 0
    data = np.load(out)
    table = microsim.read_table(table_path)
    np.testing.assert_array_equal(data["total"], table["total"].values)
    np.testing.assert_array_equal(data["theta_o_edges"], table.bins.theta_edges)
    assert json.loads(str(data["meta"]))["surface"]["kind"] == "test"


def merl_read(path):
    """A MERL reader from the published layout (Matusik et al. 2003, BRDFRead.cpp):
    three int32 dims, then R, G, B float64 planes, values times 1/1500, 1.15/1500,
    1.66/1500."""
    raw = path.read_bytes()
    dims = struct.unpack("<3i", raw[:12])
    data = np.frombuffer(raw[12:], "<f8").reshape(3, *dims)
    return dims, data * np.array([1.0, 1.15, 1.66])[:, None, None, None] / 1500.0


def cell_directions(i, j, k):
    """(ωi, ωo) of MERL cells, by explicit rotation matrices: the difference vector at
    (θd, φd) about the half vector, the half vector tilted by θh about y (φh = 0)."""
    th = (i / 90.0) ** 2 * np.pi / 2
    td, pd = j / 90.0 * np.pi / 2, k / 180.0 * np.pi
    d = np.stack([np.sin(td) * np.cos(pd), np.sin(td) * np.sin(pd), np.cos(td)], -1)
    rot = np.zeros((len(th), 3, 3))
    rot[:, 0, 0] = rot[:, 2, 2] = np.cos(th)
    rot[:, 0, 2], rot[:, 2, 0], rot[:, 1, 1] = np.sin(th), -np.sin(th), 1.0
    wi = np.einsum("nij,nj->ni", rot, d)
    wo = np.einsum("nij,nj->ni", rot, d * [-1, -1, 1])
    return wi, wo


def test_merl_against_table_eval(cli, table_path, tmp_path):
    """500 random cells: the reader's value equals read_table().eval at the cell's
    directions to float64 round-off; cells below the horizon hold −1 in every channel."""
    out = tmp_path / "t.binary"
    assert cli("export", str(table_path), "--format", "merl", "-o", str(out))[0] == 0
    dims, data = merl_read(out)
    assert dims == (90, 90, 180) and out.stat().st_size == 12 + 3 * 8 * 90 * 90 * 180
    rng = np.random.default_rng(4)
    i, j, k = (rng.integers(0, n, 500) for n in dims)
    wi, wo = cell_directions(i, j, k)
    stored = data[:, i, j, k].T
    above = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    expected = microsim.read_table(table_path).eval(wi[above], wo[above])
    np.testing.assert_allclose(stored[above], expected, rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(stored[~above] * 1500 / [1.0, 1.15, 1.66], -1.0)
    assert above.sum() > 100 and (~above).sum() > 10


def test_rgl_round_trip_through_mitsuba(cli, table_path, tmp_path):
    """Mitsuba 3's `measured` plugin loads the file; its eval (which includes cos θo)
    matches read_table().eval · cos θo within 5% at 50 random direction pairs in the lobe
    (f_r cos θo ≥ 10% of its value in the mirror direction); the two interpolate different
    grids (bins in (sin²θo, φo) here, a 64² half-vector grid there)."""
    pytest.importorskip("mitsuba")
    out = tmp_path / "t.bsdf"
    assert cli("export", str(table_path), "--format", "rgl", "-o", str(out),
               "--resolution", "64")[0] == 0
    ref, got = rgl_through_mitsuba(microsim.read_table(table_path), out, 50,
                                   np.random.default_rng(7))
    rel = np.abs(got / ref - 1)
    assert np.median(rel) < 0.05 and rel.max() < 0.05


@pytest.mark.parametrize(("argv", "needle"), [
    (["--format", "merl", "-o", "x.bsdf"], "must end in .binary"),
    (["--format", "tiff", "-o", "x.tiff"], "--format"),
    (["--format", "rgl", "-o", "x.bsdf", "--resolution", "1"], "--resolution"),
])
def test_bad_export_flags(cli, table_path, argv, needle):
    code, _, err = cli("export", str(table_path), *argv)
    assert code == 2 and err.startswith("error: ") and needle in err
