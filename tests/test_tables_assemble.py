"""Tables assembled from hand-made per-bin sums: one run's rays, realisations, an ensemble's
running sums (added, taken, absorbed) and the merge of two tables, every field against the
estimator's formulas written out (``microsim.tables.estimator``'s module docstring)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from refusals import refused

from microsim.spectra.channels import RGB, Channels
from microsim.tables import sh
from microsim.tables.assemble import (
    EnsembleSums,
    from_ensemble,
    from_realisations,
    from_sums,
    merge,
)
from microsim.tables.binning import HemisphereBins
from microsim.tables.estimator import estimate
from microsim.tables.meta import TableMeta

BINS = HemisphereBins(1, 2)
"""Two outgoing bins, split by azimuth: [0, π) and [π, 2π), each of projected solid angle
½ · 1 · π = π/2 (``HemisphereBins``'s docstring)."""
OMEGA = math.pi / 2
TWO = Channels((450.0, 550.0))
COMPONENTS = ("total", "order1")
RTOL = 1e-12
"""Relative tolerance of the estimates: the code sums deviations from a shift (the first
realisation's estimate) where the formulas below sum the estimates themselves, so the two
agree to rounding only."""
SH_RTOL = 1e-9
"""The harmonics' errors: the code gets Σ w² Y_k² from the order-2L sums Σ w² Y_K through
the product coefficients (``sh.second_moments``), here summed ray by ray; the two agree
to rounding."""


def make_sums(rays: np.ndarray, channels: int, order: int | None, seed: int) -> dict:
    """Per-bin sums of made-up rays for every realisation and direction of ``rays``
    (K, a, b): max(n − 1, 1) of a direction's n rays exit, each into a random azimuth
    (bin 0 below π, bin 1 above), cos θo in [0.1, 0.9], with a random weight per channel
    and escape order 1 or 2; the lost weight is random. With ``order`` L the harmonic
    sums Σ w Y_k (order L), Σ w² Y_K (order 2L) and, summed directly, Σ w² Y_k²."""
    rng = np.random.default_rng(seed)
    k, a, b = rays.shape
    size = BINS.size
    out = {"s1": {c: np.zeros((k, a, b, size, channels)) for c in COMPONENTS},
           "s2": {c: np.zeros((k, a, b, size, channels)) for c in COMPONENTS},
           "lost": np.zeros((k, a, b, channels))}
    if order is not None:
        for key, n in (("sh1", sh.size(order)), ("sh2", sh.size(2 * order)),
                       ("shq", sh.size(order))):
            out[key] = {c: np.zeros((k, a, b, n, channels)) for c in COMPONENTS}
    for r, l, j in np.ndindex(k, a, b):
        n = int(rays[r, l, j])
        if n == 0:
            continue
        out["lost"][r, l, j] = rng.uniform(0.0, 0.5, channels)
        for _ in range(max(n - 1, 1)):
            phi = rng.uniform(0.0, 2 * math.pi)
            cos_theta = rng.uniform(0.1, 0.9)
            w = rng.uniform(0.2, 1.0, channels)
            escape = int(rng.integers(1, 3))
            where = (r, l, j, 0 if phi < math.pi else 1)
            for c in COMPONENTS:
                if c == "order1" and escape != 1:
                    continue
                out["s1"][c][where] += w
                out["s2"][c][where] += w * w
                if order is not None:
                    y = sh.basis(order, np.array([cos_theta]), np.array([phi]))[0]
                    y2 = sh.basis(2 * order, np.array([cos_theta]), np.array([phi]))[0]
                    out["sh1"][c][r, l, j] += y[:, None] * w
                    out["sh2"][c][r, l, j] += y2[:, None] * w * w
                    out["shq"][c][r, l, j] += (y * y)[:, None] * w * w
    return out


def moments(s1: np.ndarray, s2: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """m = Σx/n and v = (Σx² − n m²)/(n (n − 1)) (at least 0), NaN where Σx² = 0 or
    n < 2."""
    m = s1 / n
    if n < 2:
        return m, np.full(m.shape, np.nan)
    v = np.maximum(s2 - n * m * m, 0.0) / (n * (n - 1))
    return m, np.where(s2 > 0, v, np.nan)


def batch_means(ms: list, vs: list, ns: list) -> tuple:
    """Mean, error, ray error and degrees of freedom of K realisations' estimates: one
    realisation's error is its ray error √v with n − 1 degrees of freedom; for K ≥ 2
    s² = Σ (m − μ̂)² / (K (K − 1)) floored at u = Σ v / K² (NaN where no v is known),
    with K − 1."""
    k = len(ms)
    mean = sum(ms) / k
    if k == 1:
        return mean, np.sqrt(vs[0]), np.sqrt(vs[0]), ns[0] - 1.0
    spread = sum((m - mean) ** 2 for m in ms) / (k * (k - 1))
    v = np.stack(vs)
    u = np.where(np.isnan(v).all(axis=0), np.nan, np.nansum(v, axis=0) / k**2)
    return mean, np.sqrt(np.where(np.isnan(u), np.nan, np.maximum(spread, u))), np.sqrt(u), \
        k - 1.0


def reference(rays: np.ndarray, data: dict, harmonics: bool = True) -> dict:
    """Every field of the table of ``data`` (``make_sums``) with at most two
    realisations a direction (batch means: the moderated estimator needs three)."""
    k, a, b = rays.shape
    c_count = data["lost"].shape[-1]
    shape = (a, b) + BINS.shape + (c_count,)
    exp = {f: {} for f in ("values", "errors", "ray_errors", "dof", "inflation", "albedo",
                           "albedo_err", "sh", "sh_err", "realisation_albedo")}
    count = (rays > 0).sum(axis=0)
    for c in COMPONENTS:
        values = np.zeros((a, b, BINS.size, c_count))
        errors, ray_errors, sh_values, sh_errors = (np.zeros_like(values) for _ in range(4))
        if harmonics:
            sh_values = np.zeros((a, b) + data["sh1"][c].shape[-2:])
            sh_errors = np.zeros_like(sh_values)
        dof, albedo, albedo_err = (np.zeros((a, b, c_count)) for _ in range(3))
        per = np.full((count.max(), a, b, c_count), np.nan)
        for l, j in np.ndindex(a, b):
            present = [r for r in range(k) if rays[r, l, j] > 0]
            ns = [int(rays[r, l, j]) for r in present]
            bins = [moments(data["s1"][c][r, l, j], data["s2"][c][r, l, j], n)
                    for r, n in zip(present, ns, strict=True)]
            mean, err, ray_err, d = batch_means(*zip(*bins, strict=True), ns)
            values[l, j], errors[l, j], ray_errors[l, j], dof[l, j] = (
                mean / OMEGA, err / OMEGA, ray_err / OMEGA, d)
            whole = [moments(data["s1"][c][r, l, j].sum(axis=0),
                             data["s2"][c][r, l, j].sum(axis=0), n)
                     for r, n in zip(present, ns, strict=True)]
            albedo[l, j], albedo_err[l, j] = batch_means(*zip(*whole, strict=True), ns)[:2]
            per[:len(present), l, j] = [m for m, _ in whole]
            if harmonics:
                coefficients = [moments(data["sh1"][c][r, l, j], data["shq"][c][r, l, j], n)
                                for r, n in zip(present, ns, strict=True)]
                sh_values[l, j], sh_errors[l, j] = batch_means(
                    *zip(*coefficients, strict=True), ns)[:2]
        exp["values"][c], exp["errors"][c] = values.reshape(shape), errors.reshape(shape)
        exp["ray_errors"][c], exp["dof"][c] = ray_errors.reshape(shape), dof
        exp["inflation"][c] = np.full((a, b, c_count), np.nan)
        exp["albedo"][c], exp["albedo_err"][c] = albedo, albedo_err
        exp["sh"][c], exp["sh_err"][c] = sh_values, sh_errors
        exp["realisation_albedo"][c] = per
    lost = np.zeros((a, b, c_count))
    for r, l, j in np.ndindex(k, a, b):
        if rays[r, l, j]:
            lost[l, j] += data["lost"][r, l, j] / rays[r, l, j] / count[l, j]
    exp.update(lost_energy=lost, realisations=count, rays=rays.sum(axis=0),
               error_model="ensemble" if count.max() > 1 else "rays")
    if not harmonics:
        exp["sh"] = exp["sh_err"] = None
    return exp


def assert_fields(t, exp: dict, components: tuple[str, ...] = COMPONENTS) -> None:
    """Every estimated field of table ``t`` equals ``exp`` (NaN where it is NaN)."""
    assert t.components == components
    assert list(t.estimates) == list(components)
    for field, tolerance in (("values", RTOL), ("errors", RTOL), ("ray_errors", RTOL),
                             ("dof", 0), ("inflation", 0), ("albedo", RTOL),
                             ("albedo_err", RTOL), ("sh", RTOL), ("sh_err", SH_RTOL),
                             ("realisation_albedo", RTOL)):
        expected = exp[field]
        for c in components:
            if expected is None:
                assert getattr(t[c], field) is None, field
                continue
            np.testing.assert_allclose(getattr(t[c], field), expected[c], rtol=tolerance,
                                       atol=0, err_msg=f"{field} {c}")
    np.testing.assert_allclose(t.lost_energy, exp["lost_energy"], rtol=RTOL, atol=0)
    assert t.rays.dtype == np.int64 and np.array_equal(t.rays, exp["rays"])
    assert t.realisations.dtype == np.int64
    assert np.array_equal(t.realisations, exp["realisations"])
    assert t.error_model == exp["error_model"]


def assert_raw(t, rays: np.ndarray, data: dict, harmonics: bool = True,
               components: tuple[str, ...] = COMPONENTS) -> None:
    """The table keeps the raw per-realisation sums it was made of, as floats."""
    assert t.realisation_rays.dtype == np.int64
    assert np.array_equal(t.realisation_rays, rays)
    assert t.lost.dtype == float and np.array_equal(t.lost, data["lost"])
    for field, key in (("sums", "s1"), ("sums_sq", "s2"), ("sh_sums", "sh1"),
                       ("sh_sums_sq", "sh2")):
        for c in components:
            if key.startswith("sh") and not harmonics:
                assert getattr(t[c], field) is None
                continue
            assert getattr(t[c], field).dtype == float, field
            assert np.array_equal(getattr(t[c], field), data[key][c]), field


RAYS = np.array([[[4, 0], [5, 0]],
                 [[6, 3], [7, 1]]])
"""Two realisations over 2 × 2 incident directions: the first traces only the first
azimuth; the last direction has a single ray."""
THETA_I, PHI_I = np.array([0.2, 0.6]), np.array([0.0, math.pi])


def realisations_table(rays=RAYS, seed=3, order=1, channels=TWO, meta=None,
                       isotropic=False, theta_i=THETA_I, phi_i=PHI_I):
    """The table of ``make_sums``' sums, with the data made."""
    data = make_sums(rays, channels.count, order, seed)
    harmonics = {} if order is None else {"sh_sums": data["sh1"], "sh_sums_sq": data["sh2"]}
    t = from_realisations(BINS, theta_i, phi_i, isotropic, rays, data["s1"], data["s2"],
                          data["lost"], meta or TableMeta(seed=seed), channels=channels,
                          **harmonics)
    return t, data


def test_a_table_of_realisations_is_the_mean_of_their_estimates_with_batch_means():
    """Realisations that trace only some directions, a one-ray direction, two spectral
    channels and harmonics of order 1: every bin's f_r, error and ray error, the albedo,
    the harmonics and their errors, the degrees of freedom (K − 1 for two realisations,
    n − 1 for one), the lost energy (mean over the direction's realisations of lost / n),
    each direction's realisations and the error model, against the formulas written out;
    the table keeps the raw sums, the axes, the meta and the channels."""
    t, data = realisations_table(meta=TableMeta(seed=11))
    assert_fields(t, reference(RAYS, data))
    assert_raw(t, RAYS, data)
    assert t.bins is BINS and t.channels == TWO and t.meta == TableMeta(seed=11)
    assert np.array_equal(t.theta_i, THETA_I) and np.array_equal(t.phi_i, PHI_I)
    assert t.isotropic is False and t.sh_order == 1
    # the one-ray direction: an estimate without an error, of 0 degrees of freedom
    assert np.isnan(t["total"].errors[1, 1]).all() and (t["total"].dof[1, 1] == 0).all()


def test_one_run_is_the_table_of_one_realisation():
    """``from_sums`` of one run's sums (no realisation axis) is the one-realisation table:
    errors the ray errors √v of n − 1 degrees of freedom, harmonics included, the error
    model ``rays``, and the sums kept with a realisation axis of one."""
    rays = np.array([[[5, 3], [4, 2]]])
    data = make_sums(rays, TWO.count, 1, seed=8)
    t = from_sums(BINS, THETA_I, PHI_I, False, rays[0],
                  {c: v[0] for c, v in data["s1"].items()},
                  {c: v[0] for c, v in data["s2"].items()}, data["lost"][0],
                  TableMeta(seed=8), sh_sums={c: v[0] for c, v in data["sh1"].items()},
                  sh_sums_sq={c: v[0] for c, v in data["sh2"].items()}, channels=TWO)
    exp = reference(rays, data)
    assert exp["error_model"] == "rays"
    assert_fields(t, exp)
    assert_raw(t, rays, data)
    for c in COMPONENTS:
        np.testing.assert_array_equal(t[c].ray_errors, t[c].errors)
    assert t.channels == TWO and t.meta == TableMeta(seed=8)


def test_integer_sums_and_counts_are_kept_as_floats_and_int64():
    """A total-only table of integer counts (unit weights: Σw = Σw² = hits) given as int32
    rays, integer sums and integer lost weight: the raw sums and the lost weight are kept as
    floats and the rays as int64, and the estimate is that of the same sums as floats."""
    rays = np.array([[[4]], [[6]]], np.int32)
    s1 = np.array([[[[[3], [1]]]], [[[[2], [3]]]]])      # (K, a, b, m, C = 1)
    lost = np.array([[[1]], [[0]]])
    one = Channels((550.0,))
    t = from_realisations(BINS, [0.1], [0.0], True, rays, {"total": s1}, {"total": s1},
                          lost, TableMeta(), channels=one)
    assert t.components == ("total",)
    assert t.realisation_rays.dtype == np.int64 and np.array_equal(t.realisation_rays, rays)
    assert t.lost.dtype == float and np.array_equal(t.lost, lost)
    for field in ("sums", "sums_sq"):
        assert getattr(t["total"], field).dtype == float
        assert np.array_equal(getattr(t["total"], field), s1)
    m = s1[:, 0, 0, :, 0] / rays[:, 0, 0, None]                 # (K, m)
    v = (s1[:, 0, 0, :, 0] - rays[:, 0, 0, None] * m * m) / (
        rays[:, 0, 0, None] * (rays[:, 0, 0, None] - 1))
    mean = m.mean(axis=0)
    err = np.sqrt(np.maximum(((m - mean) ** 2).sum(axis=0) / 2, v.sum(axis=0) / 4))
    np.testing.assert_allclose(t["total"].values[0, 0, 0, :, 0], mean / OMEGA, rtol=RTOL)
    np.testing.assert_allclose(t["total"].errors[0, 0, 0, :, 0], err / OMEGA, rtol=RTOL)
    np.testing.assert_allclose(t.lost_energy[0, 0], [(1 / 4 + 0 / 6) / 2], rtol=RTOL)
    assert t.error_model == "ensemble" and t.realisations.tolist() == [[2]]


def test_harmonics_need_both_sums():
    """Harmonic sums without their order-2L sums (or the reverse) make a table without
    harmonics, the bins as with none."""
    data = make_sums(RAYS, TWO.count, 1, seed=3)
    exp = reference(RAYS, data, harmonics=False)
    for given in ({"sh_sums": data["sh1"]}, {"sh_sums_sq": data["sh2"]}):
        t = from_realisations(BINS, THETA_I, PHI_I, False, RAYS, data["s1"], data["s2"],
                              data["lost"], TableMeta(), channels=TWO, **given)
        assert_fields(t, exp)
        assert t["total"].sh_sums is None and t["total"].sh_sums_sq is None


def test_realisations_refuse_bad_counts_and_shapes_with_their_messages():
    """Counts of the wrong shape, negative counts and an untraced direction are refused
    with the documented message; so are harmonic sums of the wrong order-2L shape."""
    def table(rays, theta_i=(0.1,), phi_i=(0.0,), **harmonics):
        rays = np.asarray(rays)
        s = {c: np.ones(rays.shape + (BINS.size, 3)) for c in COMPONENTS}
        return from_realisations(BINS, list(theta_i), list(phi_i), True, rays, s, s,
                                 np.zeros(rays.shape + (3,)), TableMeta(), **harmonics)

    assert refused(ValueError, table, [[[5], [5]]]) == (
        "rays must be (K, n_theta_i, n_phi_i) = (K, 1, 1) counts >= 0, each direction "
        "traced, got shape (1, 2, 1)")
    assert refused(ValueError, table, [[[5]], [[-1]]]) == (
        "rays must be (K, n_theta_i, n_phi_i) = (K, 1, 1) counts >= 0, each direction "
        "traced, got shape (2, 1, 1)")
    assert refused(ValueError, table, [[[3, 0]]], phi_i=(0.0, 1.0)) == (
        "rays must be (K, n_theta_i, n_phi_i) = (K, 1, 2) counts >= 0, each direction "
        "traced, got shape (1, 1, 2)")
    good = {c: np.ones((1, 1, 1, 4, 3)) for c in COMPONENTS}
    for bad in ({c: np.ones((1, 1, 1, 8, 3)) for c in COMPONENTS},
                {"total": np.ones((1, 1, 1, 9, 3)), "order1": np.ones((1, 1, 1, 8, 3))}):
        assert refused(ValueError, table, [[[5]]], sh_sums=good, sh_sums_sq=bad) == (
            "sh_sums['total'] and sh_sums_sq['total'] must have shapes (K, a, b, (L+1)^2, "
            "C) and (K, a, b, (2L+1)^2, C)" if bad["total"].shape[-2] != 9 else
            "sh_sums['order1'] and sh_sums_sq['order1'] must have shapes (K, a, b, "
            "(L+1)^2, C) and (K, a, b, (2L+1)^2, C)")


def test_one_ray_directions_and_absent_realisations_are_accepted():
    """A direction of a single ray (traced by one realisation, absent from the other) is a
    table: its value Σw / Ω, its error undefined (n < 2), its degrees of freedom 0."""
    rays = np.array([[[0]], [[1]]])
    data = make_sums(rays, 3, None, seed=4)
    t = from_realisations(BINS, [0.1], [0.0], True, rays, data["s1"], data["s2"],
                          data["lost"], TableMeta())
    exp = reference(rays, data, harmonics=False)
    assert_fields(t, exp)
    assert t.channels == RGB and exp["error_model"] == "rays"
    assert np.isnan(t["total"].errors).all() and (t["total"].dof == 0).all()


def three_realisations() -> tuple[np.ndarray, dict, np.ndarray]:
    """Three realisations of 100 rays over one polar angle and two azimuths, four bins,
    one channel, unit-weight hits: the total's bins 0 and 1 hold most of the light
    (bins 2 and 3 below a tenth of the peak), the second azimuth's weights are a
    hundredth of the first's, and the single-scattering row holds a few hits a bin,
    even over its bins but under a tenth of the total's peak in bins 0 and 1."""
    total = np.array([[40, 20, 3, 1], [44, 18, 2, 2], [37, 23, 4, 1]], float)
    single = np.array([[3, 1, 1, 1], [4, 2, 1, 2], [3, 1, 2, 1]], float)
    weight = np.array([1.0, 0.01])
    s1 = {"total": np.zeros((3, 1, 2, 4, 1)), "order1": np.zeros((3, 1, 2, 4, 1))}
    s2 = {c: np.zeros_like(v) for c, v in s1.items()}
    for j, w in enumerate(weight):
        for c, hits in (("total", total), ("order1", single)):
            s1[c][:, 0, j, :, 0] = hits * w
            s2[c][:, 0, j, :, 0] = hits * w * w
    return np.full((3, 1, 2), 100), {"s1": s1, "s2": s2}, weight


def test_three_realisations_moderate_the_bins_over_each_incidences_lobe():
    """With three realisations the bins' errors are moderated over the lobe bins of each
    incidence and component (f_r at least a tenth of that row's peak, mean over the
    channels): the estimate of ``microsim.tables.estimator.estimate`` with that pool,
    which here is bins 0 and 1 of the total and all four single-scattering bins, in both
    azimuths; the albedo is batch means of the three realisations."""
    rays, data, _ = three_realisations()
    bins = HemisphereBins(2, 2)
    omega = math.pi / 4
    one = Channels((550.0,))
    t = from_realisations(bins, [0.3], [0.0, math.pi], False, rays, data["s1"], data["s2"],
                          np.zeros((3, 1, 2, 1)), TableMeta(), channels=one)
    s1 = np.stack([data["s1"][c] for c in COMPONENTS], axis=3)       # (K, a, b, rows, m, C)
    s2 = np.stack([data["s2"][c] for c in COMPONENTS], axis=3)
    f = (s1 / 100).mean(axis=0).mean(axis=-1)                        # (a, b, rows, m)
    pool = np.zeros(f.shape, bool)
    for j, row in np.ndindex(2, 2):
        peak = f[0, j, row].max()
        pool[0, j, row] = f[0, j, row] >= 0.1 * peak
    assert pool[0, :, 0].tolist() == [[True, True, False, False]] * 2
    assert pool[0, :, 1].all()
    e = estimate(s1, s2, np.broadcast_to(rays[..., None], (3, 1, 2, 2)),
                 pool[..., None])
    assert np.isfinite(e.inflation).all()
    for row, c in enumerate(COMPONENTS):
        np.testing.assert_allclose(t[c].values, e.mean[:, :, row].reshape(1, 2, 2, 2, 1)
                                   / omega, rtol=RTOL)
        np.testing.assert_allclose(t[c].errors, e.stderr[:, :, row].reshape(1, 2, 2, 2, 1)
                                   / omega, rtol=RTOL)
        np.testing.assert_allclose(t[c].ray_errors, e.ray_stderr[:, :, row].reshape(
            1, 2, 2, 2, 1) / omega, rtol=RTOL)
        np.testing.assert_allclose(t[c].dof, e.dof[:, :, row], rtol=RTOL)
        np.testing.assert_allclose(t[c].inflation, e.inflation[:, :, row], rtol=RTOL)
        m = s1[:, :, :, row].sum(axis=-2) / 100                      # (K, a, b, C)
        v = (s2[:, :, :, row].sum(axis=-2) - 100 * m * m) / (100 * 99)
        mean = m.mean(axis=0)
        err = np.sqrt(np.maximum(((m - mean) ** 2).sum(axis=0) / 6, v.sum(axis=0) / 9))
        np.testing.assert_allclose(t[c].albedo, mean, rtol=RTOL)
        np.testing.assert_allclose(t[c].albedo_err, err, rtol=RTOL)
        np.testing.assert_allclose(t[c].realisation_albedo, m, rtol=RTOL)
    assert t.error_model == "ensemble" and (t.realisations == 3).all()


def add_all(s: EnsembleSums, rays: np.ndarray, data: dict, directions) -> None:
    """Add to ``s`` every realisation of ``directions`` (in index order)."""
    directions = list(directions)
    for r in range(len(rays)):
        for l, j in directions:
            if rays[r, l, j]:
                def rows(key, r=r, l=l, j=j):
                    return np.stack([data[key][c][r, l, j] for c in COMPONENTS])
                s.add((l, j), r, int(rays[r, l, j]), rows("s1"), rows("s2"),
                      data["lost"][r, l, j], rows("sh1"), rows("sh2"))


def test_ensemble_sums_have_the_documented_shapes_counts_and_degrees_of_freedom():
    """``EnsembleSums``' attributes: the bins', the albedo's and the harmonics' estimates of
    shapes (a, b, rows, m, C), (a, b, rows, 1, C) and (a, b, rows, (L+1)², C), the rays
    (int64) and the lost weight per ray summed over the realisations, each direction's
    realisations' rays and albedos in the order added; a direction of one realisation has
    its rays − 1 degrees of freedom in every estimate; without an order no harmonics."""
    data = make_sums(RAYS, TWO.count, 1, seed=3)
    s = EnsembleSums((2, 2), COMPONENTS, BINS.size, 1, TWO.count)
    add_all(s, RAYS, data, np.ndindex(2, 2))
    assert s.bins.shape == (2, 2, 2, 2, 2) and s.albedo.shape == (2, 2, 2, 1, 2)
    assert s.sh.shape == (2, 2, 2, 4, 2)
    assert s.rays.dtype == np.int64 and s.rays.tolist() == [[10, 3], [12, 1]]
    lost = data["lost"][0] / np.maximum(RAYS[0], 1)[..., None] + data["lost"][1] / RAYS[
        1][..., None]
    np.testing.assert_allclose(s.lost, lost, rtol=RTOL)
    assert s.realisation_rays == {(0, 0): [4, 6], (0, 1): [3], (1, 0): [5, 7], (1, 1): [1]}
    exp = reference(RAYS, data)
    for (l, j), albedos in s.realisation_albedo.items():
        for i, albedo in enumerate(albedos):
            np.testing.assert_allclose(albedo, [exp["realisation_albedo"][c][i, l, j]
                                                for c in COMPONENTS], rtol=RTOL)
    for x in (s.bins, s.albedo, s.sh):
        assert (x.estimate().dof[0, 1] == 2).all()        # one realisation of 3 rays
    plain = EnsembleSums((1, 1), ("total",), 2)
    assert plain.sh is None and plain.sh_order == 0
    plain.add((0, 0), 0, 4, np.ones((1, 2, 3)), np.ones((1, 2, 3)), np.zeros(3))
    assert not from_ensemble(BINS, [0.1], [0.0], True, plain, TableMeta()).has_sh


def test_sums_taken_for_some_polar_angles_are_those_angles_tables():
    """The sums taken for the second polar angle make that angle's table (every field,
    harmonics included, and each realisation's albedo), are copies that keep the order
    of the harmonics, and list their directions' realisations re-indexed; taking every
    angle in order gives the sums themselves; sums without harmonics are taken too."""
    data = make_sums(RAYS, TWO.count, 1, seed=3)
    s = EnsembleSums((2, 2), COMPONENTS, BINS.size, 1, TWO.count)
    add_all(s, RAYS, data, np.ndindex(2, 2))
    assert s.take([0, 1]) is s and s.take(range(2)) is s
    part = s.take([1])
    assert part is not s and part.sh_order == 1 and part.components == COMPONENTS
    assert part.realisation_rays == {(0, 0): [5, 7], (0, 1): [1]}
    assert list(part.realisation_albedo) == [(0, 0), (0, 1)]
    assert part.rays.tolist() == [[12, 1]]
    t = from_ensemble(BINS, THETA_I[1:], PHI_I, False, part, TableMeta(), channels=TWO)
    exp = reference(RAYS[:, 1:], {k: ({c: x[:, 1:] for c, x in v.items()}
                                      if isinstance(v, dict) else v[:, 1:])
                                  for k, v in data.items()})
    assert_fields(t, exp)
    plain = EnsembleSums((2, 1), ("total",), 2)
    for l in range(2):
        plain.add((l, 0), 0, 4 + l, np.full((1, 2, 3), l + 1.0), np.full((1, 2, 3), l + 1.0),
                  np.zeros(3))
    one = plain.take([1])
    assert one.sh is None and one.rays.tolist() == [[5]]
    t = from_ensemble(BINS, [0.5], [0.0], True, one, TableMeta())
    np.testing.assert_allclose(t["total"].values, np.full((1, 1, 1, 2, 3), 2 / 5 / OMEGA),
                               rtol=RTOL)


def test_sums_of_disjoint_directions_absorb_into_the_whole_table():
    """Sums of the first polar angle absorbing those of the second make the whole table
    (every field as for one set of sums; the counts, the lost weight and the realisations'
    lists of both); a direction with realisations in both is refused."""
    data = make_sums(RAYS, TWO.count, 1, seed=3)
    first = EnsembleSums((2, 2), COMPONENTS, BINS.size, 1, TWO.count)
    second = EnsembleSums((2, 2), COMPONENTS, BINS.size, 1, TWO.count)
    add_all(first, RAYS, data, [(0, 0), (0, 1)])
    add_all(second, RAYS, data, [(1, 0), (1, 1)])
    first.absorb(second)
    assert first.rays.tolist() == [[10, 3], [12, 1]]
    assert first.realisation_rays == {(0, 0): [4, 6], (0, 1): [3], (1, 0): [5, 7],
                                      (1, 1): [1]}
    t = from_ensemble(BINS, THETA_I, PHI_I, False, first, TableMeta(), channels=TWO)
    assert_fields(t, reference(RAYS, data))
    again = EnsembleSums((2, 2), COMPONENTS, BINS.size, 1, TWO.count)
    add_all(again, RAYS, data, [(1, 1)])
    assert refused(ValueError, first.absorb, again) == (
        "the same incident direction was measured twice")
    plain, other = (EnsembleSums((2, 1), ("total",), 2) for _ in range(2))
    plain.add((0, 0), 0, 4, np.full((1, 2, 3), 1.0), np.full((1, 2, 3), 1.0), np.ones(3))
    other.add((1, 0), 0, 5, np.full((1, 2, 3), 2.0), np.full((1, 2, 3), 2.0), np.ones(3))
    plain.absorb(other)
    assert plain.sh is None and plain.rays.tolist() == [[4], [5]]
    np.testing.assert_allclose(plain.lost, [[[1 / 4] * 3], [[1 / 5] * 3]], rtol=RTOL)


def test_the_ensemble_table_refuses_untraced_directions_and_other_channels():
    """A direction without rays (or sums of other directions) and sums of other channels
    than the table's are refused with messages naming them."""
    s = EnsembleSums((1, 2), ("total",), 2)
    s.add((0, 0), 0, 5, np.ones((1, 2, 3)), np.ones((1, 2, 3)), np.zeros(3))
    assert refused(ValueError, from_ensemble, BINS, [0.1], [0.0, 1.0], False, s, TableMeta()) == (
        "every one of the (1, 2) incident directions needs rays, got [[5, 0]]")
    assert refused(ValueError, from_ensemble, BINS, [0.1, 0.2], [0.0], False, s, TableMeta()) == (
        "every one of the (2, 1) incident directions needs rays, got [[5, 0]]")
    s.add((0, 1), 0, 1, np.ones((1, 2, 3)), np.ones((1, 2, 3)), np.zeros(3))
    assert refused(ValueError, from_ensemble, BINS, [0.1], [0.0, 1.0], False, s, TableMeta(),
                   channels=TWO) == "the sums have 3 channels, the table 2"


MERGE_RAYS = (np.array([[[4], [0]], [[6], [3]]]), np.array([[[2], [5]], [[3], [1]]]))
"""Two tables of the same two realisations over two polar angles (isotropic), the first
with a realisation absent from one angle."""


def merge_tables(order=1):
    """The two tables of ``MERGE_RAYS`` and their data."""
    out = []
    for seed, rays in zip((5, 6), MERGE_RAYS, strict=True):
        out.append(realisations_table(rays, seed, order, TWO, TableMeta(seed=seed), True,
                                      THETA_I, [0.0]))
    return out


def test_tables_of_independent_rays_merge_into_the_table_of_their_pooled_sums():
    """Merging pools each realisation's rays and sums: the merged table is the table of the
    summed counts and sums (every field, harmonics included), with the first table's axes,
    meta and channels."""
    (a, da), (b, db) = merge_tables()
    t = merge(a, b)
    rays = MERGE_RAYS[0] + MERGE_RAYS[1]
    data = {k: ({c: da[k][c] + db[k][c] for c in COMPONENTS} if isinstance(da[k], dict)
                else da[k] + db[k]) for k in da}
    assert_fields(t, reference(rays, data))
    assert_raw(t, rays, data)
    assert t.isotropic is True and t.meta == TableMeta(seed=5) and t.channels == TWO
    assert np.array_equal(t.theta_i, THETA_I) and np.array_equal(t.phi_i, [0.0])
    assert t.bins is BINS


def test_harmonics_merge_only_when_both_tables_hold_them():
    """A table with (order-0) harmonic sums merged with one without them: no harmonic sums
    in the merged table, the bins those of the pooled sums."""
    (a, da), _ = merge_tables(order=0)
    (_, _), (b, db) = merge_tables(order=None)
    t = merge(a, b)
    rays = MERGE_RAYS[0] + MERGE_RAYS[1]
    data = {k: ({c: da[k][c] + db[k][c] for c in COMPONENTS} if isinstance(da[k], dict)
                else da[k] + db[k]) for k in ("s1", "s2", "lost")}
    assert_fields(t, reference(rays, data, harmonics=False))
    assert t["total"].sh_sums is None and t["total"].sh_sums_sq is None


def test_tables_of_other_set_ups_do_not_merge_and_say_why():
    """Tables without raw sums, of other bins, isotropy, polar angles, azimuths or
    realisations, of other components or channels are refused, each with its message."""
    (a, _), (b, _) = merge_tables(order=None)
    read = replace(b, estimates={c: replace(e, sums=None) for c, e in b.estimates.items()})
    for x, y in ((a, read), (read, a)):
        assert refused(ValueError, merge, x, y) == (
            "only tables holding raw sums (fresh estimates) merge")

    def changed(**attributes):
        return replace(b, **attributes)

    for other in (changed(bins=HemisphereBins(2, 1)), changed(isotropic=False),
                  changed(theta_i=THETA_I + 0.1), changed(phi_i=np.array([0.5])),
                  changed(realisation_rays=MERGE_RAYS[1][:1])):
        assert refused(ValueError, merge, a, other) == (
            "tables with different axes or realisations do not merge")
    total = {"total": np.ones((2, 2, 1, 2, 2))}
    only = from_realisations(BINS, THETA_I, [0.0], True, MERGE_RAYS[1], total, total,
                             np.zeros((2, 2, 1, 2)), TableMeta(), channels=TWO)
    assert refused(ValueError, merge, a, only) == ("tables with different components do not merge: "
                                       "('total', 'order1') and ('total',)")
    assert refused(ValueError, merge, a, changed(channels=Channels((450.0, 600.0)))) == (
        "tables of different channels do not merge: 450nm, 550nm and 450nm, 600nm")
    assert refused(ValueError, merge, changed(channels=RGB), a) == (
        "tables of different channels do not merge: R, G, B and 450nm, 550nm")
