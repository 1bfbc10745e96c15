"""The compiled transport kernel: its random numbers, its scalar physics against the
analytic module, its binning against the table's, and results that depend on neither the
threads nor the chunks."""

from __future__ import annotations

import numpy as np
import pytest
from tilefixtures import random_tile, sections

from microsim.analytic.fresnel import fresnel_conductor, fresnel_dielectric
from microsim.kernel import rng, tally
from microsim.materials import optics
from microsim.measurement.goniometer import measure_directions
from microsim.measurement.scene import PeriodicScene
from microsim.measurement.simulation import assemble_table
from microsim.tables.binning import HemisphereBins


@pytest.mark.parametrize("key", [(0, 0), (123456789, 987654321), (2**64 - 1, 2**63 + 5)])
@pytest.mark.parametrize("counter", [(1, 0, 0, 0), (5, 7, 9, 11), (2**64 - 2, 1, 2**40, 3)])
def test_philox_is_numpys_philox(key, counter) -> None:
    """Philox4x64-10 (Salmon et al. 2011) against numpy's own implementation: numpy's
    generator first increments its counter, so its first four words are ours at c + 1."""
    key = np.array(key, np.uint64)
    ours = rng.philox(*(np.uint64(c) for c in counter), key[0], key[1])
    before = np.array(counter, np.uint64)
    before[0] -= np.uint64(1)  # c0 > 0 in every case above, so no borrow
    theirs = np.random.Philox(key=key, counter=before).random_raw(4)
    assert [int(x) for x in ours] == [int(x) for x in theirs]


def test_uniforms_are_numpys_doubles_and_in_the_unit_interval() -> None:
    key = np.array([3, 4], np.uint64)
    ours = np.array([rng.uniforms(key, ray, 2, 1) for ray in range(1, 2001)])
    assert ours.min() >= 0.0 and ours.max() < 1.0
    # numpy turns a 64-bit word into a double the same way (top 53 bits)
    gen = np.random.Generator(np.random.Philox(key=key, counter=np.array([0, 2, 1, 0],
                                                                         np.uint64)))
    np.testing.assert_array_equal(ours[0], gen.random(4))
    # 8000 uniforms: mean within 5 standard errors of 1/2 (sd of a uniform: 1/√12)
    assert abs(ours.mean() - 0.5) < 5 / np.sqrt(12 * ours.size)


def test_kernel_fresnel_equals_the_analytic_module() -> None:
    """The kernel's scalar Fresnel factors are the analytic module's (which the analytic
    tests check against mpmath) to round-off, TIR and grazing included."""
    cos = np.concatenate([[0.0, 1e-12, 1.0], np.linspace(0.0, 1.0, 301)])
    for eta in (1.5, 1 / 1.5, 1.0001, 4.0):
        got = np.array([optics.fresnel_dielectric(c, eta) for c in cos])
        np.testing.assert_allclose(got, fresnel_dielectric(cos, eta), rtol=1e-13, atol=1e-15)
    for eta, k in ((0.2, 3.9), (1.1, 2.14), (1.5, 0.0), (3.0, 100.0)):
        got = np.array([optics.fresnel_conductor(c, eta, k) for c in cos])
        np.testing.assert_allclose(got, fresnel_conductor(cos, eta, k), rtol=1e-13,
                                   atol=1e-15)


@pytest.mark.parametrize("phi_period", [2 * np.pi, np.pi])
def test_kernel_bins_are_the_tables_bins(phi_period) -> None:
    """The compiled binning puts every direction where ``HemisphereBins.index`` does,
    below the horizon included."""
    bins = HemisphereBins(7, 12, phi_period)
    g = np.random.default_rng(3)
    wo = g.standard_normal((20_000, 3))
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    wo[:10, 2] = 0.0
    for phi_ref in (0.0, 1.3):
        want = bins.index(wo, phi_ref)
        got = [tally.bin_of(*w, phi_ref, 7, 12, bins.folded) for w in wo]
        np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("spectral", [False, True])
def test_tables_do_not_depend_on_threads_or_chunks(spectral: bool) -> None:
    """A rough tile of three materials (Lambertian, a conductor and a dielectric whose
    refracted part leaves: absorbing and transmitting), harmonics on: one thread with a
    chunk of 32768 rays (each batch traced, then added) and two threads with chunks of
    832 (13 energy blocks, ``microsim.kernel.slots.ENERGY_BLOCK``; the next batch traced
    while one is added, ``goniometer.DEPTH``) give the same table, bit for bit, its
    absorbed, transmitted and lost energy included; in RGB and at 16 wavelengths (gold's
    measured spectra: the harmonics through principal components,
    ``microsim.tables.principal``)."""
    tile = random_tile(32, 0.5, seed=2)
    tile.material = np.arange(len(tile.faces), dtype=np.int64) % 3
    tile.parts = ("a", "b", "c")
    materials = {"a": {"kind": "lambertian", "albedo": 0.7 if spectral else [0.9, 0.6, 0.3]},
                 "b": {"kind": "conductor", "data": "Au"} if spectral else {
                     "kind": "conductor", "eta": [0.2, 0.92, 1.1], "k": [3.9, 2.45, 2.14]},
                 "c": {"kind": "dielectric", "eta": 1.5}}
    sim = {"theta_i": [0.0, 70.0], "phi_i": [0.0], "rays": 70_000, "bounces": 8, "seed": 5}
    table = {"theta_bins": 6, "phi_bins": 12, "sh_order": 4,
             **({"wavelengths": list(range(400, 720, 20))} if spectral else {})}
    made = []
    for threads, chunk in ((1, 32768), (2, 832)):
        with PeriodicScene(tile, threads, chunk) as scene:
            part = measure_directions(tile, *sections(materials, sim, table), scene=scene)
        made.append(assemble_table([part], *sections(materials, sim, table)))
    one, two = made
    assert_identical_tables(one, two)
    record = one.meta.directions[1]
    assert min(record.absorbed) > 0.01 and min(record.transmitted) > 0.01


def assert_identical_tables(one, two) -> None:  # noqa: ANN001 (two BRDFTable)
    """Every component's values, errors, harmonics and their errors, and every
    direction's record (its energies and fates among them), the same bit for bit."""
    for c in one.components:
        assert np.array_equal(one[c].values, two[c].values)
        assert np.array_equal(one[c].errors, two[c].errors, equal_nan=True)
        assert np.array_equal(one[c].sh, two[c].sh)
        assert np.array_equal(one[c].sh_err, two[c].sh_err, equal_nan=True)
    assert np.array_equal(one.lost_energy, two.lost_energy)
    assert one.meta.directions == two.meta.directions


def test_kinds_the_transport_reflects_inline_are_perfect_mirrors() -> None:
    """The transport reflects inline, keeping the weight, at a part whose kind says it is
    a perfect mirror (``Material.mirror``): that kind's own event must agree exactly."""
    from microsim.kernel.packing import FacetMaterials
    from microsim.materials import KINDS

    rng = np.random.default_rng(2)
    n = rng.normal(size=(500, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    d = rng.normal(size=(500, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d *= -np.sign(np.einsum("ij,ij->i", d, n))[:, None]  # towards the front of the face
    mirrors = [kind for kind in KINDS if kind.mirror]
    assert [kind.kind for kind in mirrors] == ["mirror"]
    for kind in mirrors:
        facets = FacetMaterials(np.zeros(500, np.int64), ("base",), {"base": kind()})
        out, factor, transmitted = facets.scatter(np.arange(500), d, n,
                                                  np.random.SeedSequence(0))
        np.testing.assert_array_equal(out, [optics.reflect(*a, *b) for a, b in zip(d, n,
                                                                               strict=True)])
        assert np.all(factor == 1.0) and not transmitted.any()


def test_the_beam_is_the_points_drawn_in_cell_order() -> None:
    """``beam_origins`` only reorders: the points drawn, scaled to the tile and at the
    height given, in the order numpy's stable sort gives by the place of their cell on the
    path through the grid (rows rising, x forwards on even rows and backwards on odd).
    The points of several runs are sorted together, and each run's rows hold the beam
    its points alone make, in that order."""
    from microsim.kernel.beam import beam_origins

    u = np.random.default_rng(4).random((5000, 2))
    period, cells = np.array([2.0, 3.0]), 8
    cx, cy = (u * cells).astype(int).T
    step = cy * cells + np.where(cy % 2 == 0, cx, cells - 1 - cx)
    order = np.argsort(step, kind="stable")
    starts = np.array([0, 1200, 1201, 5000])
    out, rows, run = beam_origins(u, starts, period, 0.25, cells)
    assert np.array_equal(out[:, :2], (u * period)[order])
    assert np.all(out[:, 2] == 0.25)
    assert np.array_equal(run, np.searchsorted(starts, order, side="right") - 1)
    for r in range(3):
        points = u[starts[r]:starts[r + 1]]
        alone, own, _ = beam_origins(points, np.array([0, len(points)]), period, 0.25,
                                     cells)
        assert np.array_equal(own, np.arange(len(own)))
        in_rows = np.empty_like(out)
        in_rows[rows] = out
        assert np.array_equal(in_rows[starts[r]:starts[r + 1]], alone)


@pytest.mark.parametrize("divided", [False, True], ids=["absorbing", "dividing"])
@pytest.mark.parametrize("spectral", [False, True], ids=["rgb", "spectral"])
def test_batches_traced_in_one_beam_give_the_tables_they_give_alone(
        spectral: bool, divided: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    """A realisation's batches are traced together, in beams of up to
    ``goniometer.BEAM`` rays (``microsim.kernel.beam.Runs``), each batch in its own rows
    and with its own random numbers: the table is the one that tracing each batch alone
    (``BEAM`` = 1) gives, bit for bit in every bin, harmonic and energy. Three
    incidences of 3000 rays on a rough tile of three materials: Lambertian, a conductor
    and a third that absorbs only (a rougher conductor: one beam), or that divides a
    path's weight (``FacetMaterials.divides_weight``: a dielectric that transmits 1 − F,
    or at 16 wavelengths one that refracts with BK7's dispersion, so that paths follow
    their hero channel), whose batches are then traced each in its own beam."""
    from microsim.measurement import goniometer

    tile = random_tile(32, 0.5, seed=2)
    tile.material = np.arange(len(tile.faces), dtype=np.int64) % 3
    tile.parts = ("a", "b", "c")
    third = ({"kind": "dielectric", "data": "BK7", "refract": True} if spectral else
             {"kind": "dielectric", "eta": 1.5}) if divided else {
                 "kind": "conductor", "data": "Cu"} if spectral else {
                     "kind": "conductor", "eta": [0.27, 0.68, 1.22], "k": [3.6, 2.6, 2.3]}
    materials = {"a": {"kind": "lambertian", "albedo": 0.7 if spectral else [0.9, 0.6, 0.3]},
                 "b": {"kind": "conductor", "data": "Au"} if spectral else {
                     "kind": "conductor", "eta": [0.2, 0.92, 1.1], "k": [3.9, 2.45, 2.14]},
                 "c": third}
    sim = {"theta_i": [0.0, 40.0, 75.0], "phi_i": [0.0], "rays": 3000, "bounces": 8,
           "seed": 5}
    table = {"theta_bins": 6, "phi_bins": 12, "sh_order": 4,
             **({"wavelengths": list(range(400, 720, 20))} if spectral else {})}
    beams, made = [], []
    beams_of = goniometer._beams

    def counted(batches, limit):  # noqa: ANN001, ANN202 (as ``_beams``)
        for beam in beams_of(batches, limit):
            beams.append(len(beam))
            yield beam

    monkeypatch.setattr(goniometer, "_beams", counted)
    for beam in (goniometer.BEAM, 1):
        monkeypatch.setattr(goniometer, "BEAM", beam)
        part = measure_directions(tile, *sections(materials, sim, table), threads=2)
        made.append(assemble_table([part], *sections(materials, sim, table)))
    assert beams == ([1] * 6 if divided else [3, 1, 1, 1])
    together, alone = made
    assert_identical_tables(together, alone)
    record = together.meta.directions[2]
    assert min(record.absorbed) > 0.01
    assert (min(record.transmitted) > 0.01) == divided


@pytest.mark.parametrize("with_tangents", [False, True])
def test_face_table_holds_each_faces_columns(with_tangents) -> None:
    """The compiled face table against its columns set by numpy; an old table of as many
    faces is overwritten in place, one of another size replaced."""
    from microsim.kernel import slots as ks

    rng = np.random.default_rng(2)
    m = 1000
    normals, plane = rng.normal(size=(m, 3)), rng.normal(size=m)
    part = rng.integers(0, 3, m).astype(np.int32)
    tangents = rng.normal(size=(m, 3)) if with_tangents else None
    want = np.zeros((m, ks.FACE_FLOATS))
    want[:, ks.F_NX:ks.F_NZ + 1], want[:, ks.F_C], want[:, ks.F_PART] = normals, plane, part
    if with_tangents:
        want[:, ks.F_TX:ks.F_TZ + 1] = tangents
    old = np.full((m, ks.FACE_FLOATS), np.nan)
    got = ks.face_table(normals, plane, part, tangents, old)
    assert got is old and np.array_equal(got, want)
    assert np.array_equal(ks.face_table(normals, plane, part, tangents, old[:-1]), want)
