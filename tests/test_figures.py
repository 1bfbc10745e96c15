"""Every figure a command draws, at 1, 4 and 18 incidences (of isotropic and anisotropic
tables), passes the figure lint (tests/figurelint.py: no text clipped or on another text
or panel, aspect within 3:1), and says what it shows (luminance, the component, the rays,
backscatter and forward). measure ndf, demo and bench draw no per-incidence panels (demo's
are its recipe's 4); view's 3D screenshots are pyvista's, checked for their font sizes."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from figurelint import figure_layout_faults
from tablefixtures import changed

SURFACES = Path(__file__).resolve().parent.parent / "surfaces"
INCIDENCES = (1, 4, 18)
GOLD = "eta=[0.143,0.374,1.442],k=[3.983,2.385,1.603]"


@pytest.fixture
def figures(monkeypatch):
    """The lint faults and the texts of every figure closed while the test runs, in
    order (the figures' modules close each figure after writing it). Files are written
    empty: rasterising them would double the test's time, and the lint draws the figure
    itself."""
    import matplotlib.figure
    import matplotlib.pyplot as plt

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig",
                        lambda self, fname, **kw: Path(fname).write_bytes(b""))

    drawn: list[dict] = []
    close = plt.close

    def inspect(fig=None):
        texts = [t.get_text() for t in fig.findobj(lambda a: hasattr(a, "get_text"))
                 if t.get_text()]
        drawn.append({"faults": figure_layout_faults(fig), "texts": texts,
                      "size": tuple(fig.get_size_inches()),
                      "axes_lines": [line for ax in fig.axes for line in ax.get_lines()]})
        close(fig)

    monkeypatch.setattr(plt, "close", inspect)
    return drawn


def synthetic_table(n: int, path: Path) -> Path:
    """A gold Beckmann table (α = 0.3) of ``n`` incidences over 0–87°, 8 × 16 bins, 5%
    noise, with harmonics to order 4 projected from its bins and rays that differ between
    directions (as an adaptive run's do), written to ``path``."""
    import microsim
    from microsim.analytic.registry import parse_model_spec
    from microsim.comparison.metrics import model_table
    from microsim.tables import sh
    from microsim.tables.binning import HemisphereBins

    _, _, model = parse_model_spec(f"beckmann:alpha=0.3,{GOLD}")
    theta = np.radians(np.linspace(0.0, 87.0, n) if n > 1 else [30.0])
    bins = HemisphereBins(8, 16)
    table = model_table(model, theta, bins, 0.05, np.random.default_rng(n))
    table = replace(table, rays=np.arange(1, n + 1)[:, None] * 200_000)
    t, p = np.meshgrid(bins.theta_centers, bins.phi_centers, indexing="ij")
    weights = bins.projected_solid_angle.ravel()
    y = sh.basis(4, np.cos(t).ravel(), p.ravel()) * weights[:, None]  # (bins, 25)
    table = changed(table, sh=lambda e: np.einsum(
        "bk,aqbc->aqkc", y, e.values.reshape(*e.values.shape[:2], -1, 3)))
    table = changed(table, sh_err=lambda e: 0.05 * np.abs(e.sh))
    microsim.write_table(table, path)
    return path


NM5 = (400.0, 475.0, 550.0, 625.0, 700.0)
"""The wavelengths of the spectral synthetic table, nm."""


def spectral_synthetic_table(n: int, path: Path) -> Path:
    """``synthetic_table`` of a spectral gold table: Beckmann α = 0.3 with the Fresnel of
    the shipped gold indices at five wavelengths (400-700 nm), one channel each."""
    import microsim
    from microsim.analytic.registry import parse_model_spec
    from microsim.comparison.metrics import model_table
    from microsim.spectra import measured
    from microsim.spectra.channels import Channels
    from microsim.tables import sh
    from microsim.tables.binning import HemisphereBins

    eta, k = (np.round(x.at(NM5), 4).tolist() for x in measured.conductor("Au"))
    _, _, model = parse_model_spec(f"beckmann:alpha=0.3,eta={eta},k={k}".replace(" ", ""))
    theta = np.radians(np.linspace(0.0, 87.0, n) if n > 1 else [30.0])
    bins = HemisphereBins(8, 16)
    table = model_table(model, theta, bins, 0.05, np.random.default_rng(n),
                        channels=Channels(NM5))
    table = replace(table, rays=np.arange(1, n + 1)[:, None] * 200_000)
    t, p = np.meshgrid(bins.theta_centers, bins.phi_centers, indexing="ij")
    weights = bins.projected_solid_angle.ravel()
    y = sh.basis(4, np.cos(t).ravel(), p.ravel()) * weights[:, None]  # (bins, 25)
    table = changed(table, sh=lambda e: np.einsum(
        "bk,aqbc->aqkc", y, e.values.reshape(*e.values.shape[:2], -1, len(NM5))))
    table = changed(table, sh_err=lambda e: 0.05 * np.abs(e.sh))
    microsim.write_table(table, path)
    return path


def assert_clean(drawn: list[dict], count: int) -> None:
    assert len(drawn) == count, len(drawn)
    for figure in drawn:
        assert not figure["faults"], figure["faults"]


@pytest.mark.parametrize("n", INCIDENCES)
def test_compare_figures(cli, tmp_path, figures, n):
    """compare --out: plane of incidence, half-difference, z-maps, albedo. Titles name
    the component, luminance, the range of rays, both sides of θo and keep a hyphenated
    model name whole."""
    table = synthetic_table(n, tmp_path / "t.exr")
    code, _, err = cli("compare", str(table), "--model", "oren-nayar", "--out",
                       str(tmp_path / "out"))
    assert code == 0, err
    assert_clean(figures, 4)
    plane = " ".join(figures[0]["texts"])
    assert "luminance" in plane and "all orders" in plane and "oren-nayar" in plane
    assert "backscatter" in plane and "forward" in plane and "colour of the table" in plane
    if n > 1:
        assert f"200,000 to {200_000 * n:,} rays per direction" in plane
    assert all("oren-\n" not in t for f in figures for t in f["texts"])


@pytest.mark.parametrize(("theta", "phi"), [(1, 1), (2, 2), (3, 6)])
def test_anisotropic_compare_figures(cli, tmp_path, figures, theta, phi):
    """compare --out of an anisotropic table (Beckmann αx = 0.2, αy = 0.4) at 1, 4 and
    18 incidences (θi × φi): a panel per incidence in the plane of incidence and z-maps,
    and the albedo (no half-difference view: it needs an isotropic table)."""
    import microsim
    from microsim.analytic.registry import parse_model_spec
    from microsim.comparison.metrics import model_table
    from microsim.tables.binning import HemisphereBins

    spec = "beckmann:alpha_x=0.2,alpha_y=0.4"
    _, _, model = parse_model_spec(spec)
    table = model_table(model, np.radians(np.linspace(0.0, 80.0, theta)),
                        HemisphereBins(8, 16), 0.05, np.random.default_rng(theta),
                        phi_i=np.radians(np.arange(phi) * 360.0 / phi))
    microsim.write_table(table, tmp_path / "t.exr")
    code, _, err = cli("compare", str(tmp_path / "t.exr"), "--model", spec, "--out",
                       str(tmp_path / "out"), "--json")
    assert code == 0, err
    assert_clean(figures, 3)


@pytest.mark.parametrize("n", INCIDENCES)
def test_fit_and_sh_figures(cli, tmp_path, figures, n):
    """fit --plot (the plane of incidence against the fit) and sh --plot."""
    table = synthetic_table(n, tmp_path / "t.exr")
    code, _, err = cli("fit", str(table), "--model", "ggx", "--plot",
                       str(tmp_path / "f.png"), "--json")
    assert code == 0, err
    code, _, err = cli("sh", str(table), "--plot", str(tmp_path / "s.png"), "--json")
    assert code == 0, err
    assert_clean(figures, 2)
    assert "fit: ggx" in figures[0]["texts"]


@pytest.mark.parametrize("n", INCIDENCES)
def test_spectral_figures(cli, tmp_path, figures, n):
    """A spectral table's figures (compare --out and sh --plot; fit --plot draws
    compare's plane of incidence) pass the lint too and say what they show: luminance as
    CIE Y under D65, the strip's sRGB of the spectrum, the albedo per wavelength beside
    the luminance against θi."""
    table = spectral_synthetic_table(n, tmp_path / "t.exr")
    code, _, err = cli("compare", str(table), "--model", "beckmann", "--out",
                       str(tmp_path / "out"))
    assert code == 0, err
    code, _, err = cli("sh", str(table), "--plot", str(tmp_path / "s.png"), "--json")
    assert code == 0, err
    assert_clean(figures, 5)
    texts = [" ".join(f["texts"]) for f in figures]
    assert all("luminance (CIE Y, D65)" in t for t in texts), texts
    strips = [texts[k] for k in (0, 1, 3)]      # plane, half-difference, albedo
    assert all("sRGB of its spectrum under D65" in t for t in strips), strips
    assert "albedo per wavelength" in texts[3] and "wavelength (nm)" in texts[3]
    assert "Rec. 709" not in " ".join(texts)


def test_measure_and_demo_figures(cli, tmp_path, figures):
    """measure ndf --plot (no incidences) and demo --plot (the demo's own four)."""
    code, _, err = cli("measure", "ndf", str(SURFACES / "gaussian-0.3.toml"), "--set",
                       "surface.resolution=32", "--realisations", "1", "--plot",
                       str(tmp_path / "n.png"), "--json")
    assert code == 0, err
    code, _, err = cli("demo", "--rays", "2000", "-o", str(tmp_path / "d.exr"), "--plot",
                       str(tmp_path / "d.png"), "--json")
    assert code == 0, err
    assert_clean(figures, 2)


def test_bench_figures(tmp_path, figures):
    """bench's two figures, from rows shaped like its sweep's."""
    from microsim.bench import Row, plot

    rows = [Row(case=case, rays=rays, tile_resolution=res, table_bins=512, wall_s=t,
                segments=2 * rays, segments_per_s=1e6, error=0.1 / np.sqrt(t),
                stderr=0.08 / np.sqrt(t), bare_rays_per_s=2e6)
            for case in ("ts", "ms", "g1") for res in (64, 128)
            for t, rays in ((1.0, 1000), (4.0, 4000))]
    plot(rows, tmp_path)
    assert_clean(figures, 2)


@pytest.mark.parametrize(("tables", "model"), [(1, False), (1, True), (4, False),
                                               (4, True), (18, False), (18, True)])
def test_render_grids(tmp_path, figures, tables, model):
    """render's grid (a panel per table, or table | model | difference rows), from
    synthetic images, with the titles the command gives."""
    from microsim.render import figure

    rng = np.random.default_rng(0)
    image = rng.uniform(0, 1, (48, 64, 3))          # the default 320 x 240's shape
    diff = rng.normal(0, 0.1, (48, 64))
    rows = [figure.Row(f"table-{k}", [("table", image), ("beckmann (roughconductor)", image),
                                      ("median |Δ| 12.3% (noise 4.5%)", diff)]
                       if model else [(f"table-{k}", image)]) for k in range(tables)]
    figure.write_grid(rows, tmp_path / "g.png")
    assert_clean(figures, 1)


def test_render_live_grid(tmp_path, figures):
    """render --live's grid (table | live | difference, one row, its own colour-bar
    label), from synthetic images, with the titles the command gives."""
    from microsim.render import figure

    rng = np.random.default_rng(0)
    image = rng.uniform(0, 1, (48, 64, 3))
    row = figure.Row("gaussian-0.3-gold", [
        ("table", image), ("live (128 realisations)", image),
        ("mean luminance +12.3% ± 4.5%", rng.normal(0, 0.1, (48, 64)))])
    figure.write_grid([row], tmp_path / "g.png", difference="(live − table) / table")
    assert_clean(figures, 1)
    assert "(live − table) / table" in figures[0]["texts"]


def test_the_lint_finds_what_it_is_for():
    """A figure with clipped, overlapping and off-panel texts, and one 4:1 figure, are
    each reported; a clean one is not."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(6, 3), layout="constrained")
    assert figure_layout_faults(fig) == []
    plt.close(fig)
    fig, (a, b) = plt.subplots(1, 2, figsize=(6, 3))      # no layout engine to save it
    a.set_title("a title far too long for its panel that runs over the next one " * 2)
    a.text(1.6, 0.5, "on b", transform=a.transAxes)
    faults = figure_layout_faults(fig)
    assert any("'on b' lies on another panel" in f for f in faults)
    assert any("clipped" in f for f in faults)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(4, 3), layout="constrained")
    ax.set_xticks(np.arange(0, 1.01, 0.02))
    assert any("overlaps" in f for f in figure_layout_faults(fig))
    plt.close(fig)
    fig = plt.figure(figsize=(8, 2))
    assert any("aspect" in f for f in figure_layout_faults(fig))
    plt.close(fig)


def test_lobe_view_shows_the_model_inside_the_lobe(tmp_path, monkeypatch):
    """view's lobe with a model: the simulated lobe is drawn see-through and the model's
    wireframe opaque after it, so a model lobe inside the simulated one shows (an opaque
    lobe hid it); the screenshot is written. (Pixels cannot tell: seen through the lobe
    the black lines take its colour.)"""
    import pyvista as pv

    from microsim.analytic.registry import parse_model_spec
    from microsim.comparison.metrics import model_table
    from microsim.tables.binning import HemisphereBins
    from microsim.view import LOBE_OPACITY, show_lobe

    _, _, model = parse_model_spec("beckmann:alpha=0.4")
    table = model_table(model, np.radians([0.0, 30.0]), HemisphereBins(16, 32))
    calls = []
    add_mesh = pv.Plotter.add_mesh

    def record(self, mesh, **kw):
        calls.append(kw)
        return add_mesh(self, mesh, **kw)

    monkeypatch.setattr(pv.Plotter, "add_mesh", record)
    show_lobe(table, np.radians(30.0), model, tmp_path / "l.png", n=16)
    assert (tmp_path / "l.png").stat().st_size > 0
    lobe = next(k for k, c in enumerate(calls) if c.get("scalars"))
    wire = next(k for k, c in enumerate(calls) if c.get("style") == "wireframe")
    assert calls[lobe]["opacity"] == LOBE_OPACITY < 0.7 and wire > lobe
    assert calls[wire].get("opacity", 1.0) == 1.0


def test_the_ray_view_labels_are_readable(cli, tmp_path, monkeypatch):
    """view RECIPE --rays (the tile with ray paths): its axis titles and tick labels are
    drawn at 14 pt and its corner text at 12 pt (they were 10 pt, tiny beside the tile in
    a screenshot; the figure lint reads matplotlib figures, not these 3D views)."""
    import pyvista as pv

    calls = {}
    for name in ("show_bounds", "add_text"):
        method = getattr(pv.Plotter, name)

        def record(self, *args, _name=name, _method=method, **kw):
            calls.setdefault(_name, []).append(kw.get("font_size"))
            return _method(self, *args, **kw)

        monkeypatch.setattr(pv.Plotter, name, record)
    code, _, err = cli("view", str(SURFACES / "gaussian-0.3.toml"), "--set",
                       "surface.resolution=32", "--rays", "5", "--tiles", "1",
                       "--screenshot", str(tmp_path / "v.png"))
    assert code == 0, err
    assert calls["show_bounds"] == [14] and calls["add_text"] and \
        min(calls["add_text"]) >= 12, calls


def test_the_half_difference_band_is_the_last_theta_o_ring(tmp_path, figures):
    """The bright band of the half-difference view at θd > 80° across all θh is the
    table's last θo ring, not the surface: a noiseless table of the model's own bin
    averages (gold Beckmann α = 0.3, 32 × 64 bins, incidences to 87° as a simulated gold
    table has) is 10⁴ times the model at θh = 60°, θd = 87° (both directions in the last
    ring, whose bins hold the grazing mirror peak), yet within 10% of it at θh = 10°,
    θd = 40°. The figure marks the ring's edge with a dashed line and says so."""
    from microsim.analytic.registry import parse_model_spec
    from microsim.comparison.metrics import model_table
    from microsim.geometry import half_difference
    from microsim.plots import half_difference_slices
    from microsim.plots.layout import luminance
    from microsim.tables.binning import HemisphereBins

    _, _, model = parse_model_spec(f"beckmann:alpha=0.3,{GOLD}")
    theta = np.radians([0, 15, 30, 45, 60, 70, 80, 87])
    table = model_table(model, theta, HemisphereBins(32, 64))
    th, td = np.radians([60.0, 10.0]), np.radians([87.0, 40.0])
    wi, wo = half_difference(th, td, np.pi / 2)
    ratio = luminance(table.eval(wi, wo)) / luminance(model.eval(wi, wo))
    assert ratio[0] > 1e4 and abs(ratio[1] - 1) < 0.1, ratio
    half_difference_slices(table, model, tmp_path / "h.png")
    edge = np.degrees(table.bins.theta_edges[-2])
    lines = [line.get_ydata()[0] for line in figures[0]["axes_lines"]]
    assert lines == pytest.approx([edge] * 3)
    assert any(f"θd = {edge:.1f}°" in t for t in figures[0]["texts"])


def test_titles_wrap_at_spaces_only():
    """A title that must wrap inside a hyphenated model name breaks before it, not at its
    hyphen ("oren-/nayar" before)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from microsim.plots.layout import wrapped

    fig = plt.figure(figsize=(2.0, 2.0))      # 24 characters a line at 10 pt
    title = "a velvet table, oren-nayar fit"              # "…, oren-" fits a line
    lines = wrapped(title, fig, 10).splitlines()
    plt.close(fig)
    assert len(lines) > 1 and not any(line.endswith("-") for line in lines), lines
    assert any("oren-nayar" in line for line in lines)
