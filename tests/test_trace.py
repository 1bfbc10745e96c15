"""The periodic tracer: hits, the wrap at the tile's sides, and self-hit-free offsets."""

from __future__ import annotations

import numpy as np
import pytest
from tilefixtures import bump_tile, cosine_directions, flat_tile, random_tile, vgroove_tile

from microsim.bench import bare_scene
from microsim.measurement.masking import sample_faces
from microsim.measurement.scene import BACKFACE, ESCAPED, HIT, LEAKED, TRAPPED, PeriodicScene


def test_flat_tile_hits_below_every_start_point() -> None:
    rng = np.random.default_rng(1)
    with PeriodicScene(flat_tile()) as scene:
        n = 1000
        start = np.c_[rng.random((n, 2)) * 3 - 1, np.full(n, scene.z_top)]
        d = np.tile([0.6, 0.0, -0.8], (n, 1))
        hits = scene.closest_hit(start, d)
    assert np.all(hits.status == HIT)
    # travel to z = 0 moves x by 0.75 z_top, then wrap into [0, 1)
    expected = np.mod(start[:, :2] + d[:, :2] * (scene.z_top / 0.8), 1.0)
    gap = np.abs(hits.point[:, :2] - expected)
    gap = np.minimum(gap, 1.0 - gap)  # a point at 1 - 1e-17 is the point at 0
    assert gap.max() < 1e-12
    assert np.abs(hits.point[:, 2]).max() < 1e-15


def steep_vgroove_tile():
    return vgroove_tile(70.0, grooves=32)


@pytest.mark.parametrize("make", [flat_tile, random_tile, steep_vgroove_tile],
                         ids=["flat", "rough", "vgroove70"])
def test_secondary_rays_never_rehit_their_face(make) -> None:
    """Rays leaving a face (cosine-distributed, so grazing ones too) must never report
    that face again. On smooth tiles none may end in a back face or leak either; at the
    140 deg concave edges of 70 deg V-grooves an origin within ~eps of the edge can start
    behind the neighbour face: that band is eps / face length ~ 2e-5 of the points, so at
    most 1e-4 of the rays may end so (5x the band, for noise in the count)."""
    tile = make()
    normals, areas = tile.face_normals_areas()
    rng = np.random.default_rng(2)
    n = 100_000
    faces, points = sample_faces(tile, areas, n, rng)
    d = cosine_directions(normals[faces], rng.random((n, 2)))
    with PeriodicScene(tile) as scene:
        hits = scene.closest_hit(scene.offset(points, normals[faces], d), d)
    # Embree's own answer for the same rays without the offset is their own face for some
    # of them: the check can fail
    raw = bare_scene(tile.vertices, tile.faces).run(points.astype(np.float32),
                                                    d.astype(np.float32))
    assert np.count_nonzero((hits.status == HIT) & (hits.face == faces)) == 0
    lost = np.count_nonzero(np.isin(hits.status, (BACKFACE, LEAKED, TRAPPED)))
    assert lost <= (1e-4 * n if make is steep_vgroove_tile else 0)
    if make is flat_tile:
        assert np.all(hits.status == ESCAPED)
    assert np.count_nonzero(raw == faces) > 0


def test_grazing_ray_wraps_across_many_tiles_to_the_bump() -> None:
    """A ray at 89.9 deg along +x over a flat tile with one pyramid (height 0.05, base
    [0.4, 0.6]^2) passes over the apex for several periods, then hits the pyramid's -x
    face; the hit point follows from the ray's line: z descends cot(89.9 deg) per unit x
    and the face is z = 0.05 (x - 0.4) / 0.1 within each period."""
    height, theta = 0.05, np.radians(89.9)
    slope = 1 / np.tan(theta)
    z0 = height + 12.5 * slope  # passes above 12 apexes first
    x0 = 0.7
    start = np.array([[x0, 0.5, z0]])
    d = np.array([[np.sin(theta), 0.0, -np.cos(theta)]])
    # independent solution: first period k whose face the line meets within x in [0.4, 0.5]
    for k in range(1, 100):
        # z0 - (X - x0) slope = height (X - k - 0.4) / 0.1 with X the unwrapped x
        big_x = (z0 + x0 * slope + height * (k + 0.4) / 0.1) / (slope + height / 0.1)
        if big_x - k <= 0.5:
            break
    expected = np.array([big_x - k, 0.5, z0 - (big_x - x0) * slope])
    with PeriodicScene(bump_tile(height)) as scene:
        hits = scene.closest_hit(start, d)
        assert scene.segments == k + 1  # one query per period entered
    assert k >= 10
    assert hits.status[0] == HIT and hits.face[0] == 16
    assert np.abs(hits.point[0] - expected).max() < 1e-9


def test_horizontal_ray_is_trapped_not_endless() -> None:
    with PeriodicScene(flat_tile()) as scene:
        start = np.array([[0.3, 0.3, scene.eps]])
        hits = scene.closest_hit(start, np.array([[0.8, 0.6, 0.0]]))
    assert hits.status[0] == TRAPPED


def test_threads_and_chunks_do_not_change_hits() -> None:
    tile = random_tile(seed=3)
    rng = np.random.default_rng(4)
    n = 20_000
    start = np.c_[rng.random((n, 2)), np.full(n, 1.0)]
    d = -cosine_directions(np.tile([0.0, 0.0, 1.0], (n, 1)), rng.random((n, 2)))
    with PeriodicScene(tile, threads=1) as one, PeriodicScene(tile, threads=2,
                                                             chunk=832) as two:
        start[:, 2] = one.z_top
        a, b = one.closest_hit(start, d), two.closest_hit(start, d)
    assert np.array_equal(a.status, b.status) and np.array_equal(a.face, b.face)
    assert np.array_equal(a.point, b.point)


def test_a_chunk_holds_whole_energy_blocks() -> None:
    """A chunk of rays that would split a block of the absorbed and transmitted sums (whose
    additions in ray order make them independent of the chunking) is refused."""
    with pytest.raises(ValueError, match="chunk 777: a positive multiple of 64 rays"):
        PeriodicScene(flat_tile(), chunk=777)


def test_kernel_queries_find_what_bare_embreex_finds() -> None:
    """The kernel's own Embree queries (``microsim.kernel.embree``) against
    ``embreex``'s ``EmbreeScene.run`` on the same float32 rays: steep rays from the top of
    a rough tile, aimed inside the box so no side is reached, hit the same faces."""
    tile = random_tile(seed=5)
    rng = np.random.default_rng(6)
    n = 20_000
    with PeriodicScene(tile) as scene:
        assert scene._scene.version >= 40000  # Embree 4
        start = np.c_[0.2 + 0.6 * rng.random((n, 2)), np.full(n, scene.z_top)]
        d = -cosine_directions(np.tile([0.0, 0.0, 1.0], (n, 1)), 0.01 * rng.random((n, 2)))
        # float32 rays, as Embree sees them in both
        start, d = start.astype(np.float32).astype(float), d.astype(np.float32).astype(float)
        hits = scene.closest_hit(start, d)
    bare = bare_scene(tile.vertices, tile.faces).run(start.astype(np.float32),
                                                     d.astype(np.float32))
    assert np.all(hits.status == HIT)
    assert np.array_equal(hits.face, bare)


def incoherent_rays(scene: PeriodicScene, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Rays from the top of the slab, cosine-distributed about −z, anywhere over the box."""
    rng = np.random.default_rng(seed)
    start = np.c_[rng.random((n, 2)), np.full(n, scene.z_top)]
    return start, -cosine_directions(np.tile([0.0, 0.0, 1.0], (n, 1)), rng.random((n, 2)))


def test_every_scene_shares_the_process_embree_device() -> None:
    """Scenes made on several threads at once come from one device, made once."""
    from concurrent.futures import ThreadPoolExecutor

    from microsim.kernel.embree import Scene, device

    tile = random_tile(n=16, seed=1)
    with ThreadPoolExecutor(4) as pool:
        scenes = list(pool.map(lambda _: Scene(tile.vertices, tile.faces), range(8)))
    assert {s._device for s in scenes} == {device()}
    for s in scenes:
        s.close()
    assert device() == scenes[0]._device


def hits_and_own_device(seed: int) -> tuple[np.ndarray, bool]:
    """Faces hit by fixed rays in a new scene of a random tile, and whether the process's
    Embree device was made by this process (run in a forked child too)."""
    import os

    from microsim.kernel import embree

    with PeriodicScene(random_tile(n=32, seed=seed), threads=1) as scene:
        start, d = incoherent_rays(scene, 2000, 1)
        return scene.closest_hit(start, d).face, embree._DEVICE[0] == os.getpid()


def test_a_forked_process_makes_its_own_device() -> None:
    """A child forked after the parent made its device (whose build threads the child does
    not have) makes its own, and traces as the parent does."""
    import multiprocessing

    want, own = hits_and_own_device(3)
    with multiprocessing.get_context("fork").Pool(1) as pool:
        got, child_own = pool.apply_async(hits_and_own_device, (3,)).get(timeout=120)
    assert own and child_own and np.array_equal(got, want)


def test_an_updated_scene_finds_what_a_new_one_finds() -> None:
    """``PeriodicScene.update`` to another realisation of the same grid (the same faces
    array: the BVH is refitted) finds the closest hits a new scene of it finds, except
    float32 ties: a ray through a shared edge may get either face, the hit points then
    agree to float32 precision. A tile of other faces is rebuilt: the same hits exactly."""
    from microsim.recipe import resolve
    from microsim.surfaces import build_tile

    surface = resolve({"surface": {"kind": "gaussian", "alpha": 0.4, "resolution": 64,
                                   "correlation_length": 1 / 16}}).surface
    a, b = (build_tile(surface.with_seed(seed)) for seed in (1, 2))
    assert a.faces is b.faces
    n = 200_000
    with PeriodicScene(a, threads=2) as reused:
        before = reused._scene
        reused.update(b)
        assert reused._scene is before and reused.tile is b
        start, d = incoherent_rays(reused, n, 7)
        got = reused.closest_hit(start, d)
        with PeriodicScene(b, threads=2) as new:
            want = new.closest_hit(start, d)
            assert reused.eps == new.eps and np.array_equal(reused.box, new.box)
            assert np.array_equal(reused._faces, new._faces)
        assert np.array_equal(got.status, want.status)
        tie = got.face != want.face
        assert tie.sum() <= 1e-4 * n  # measured: about 1e-6 of first hits
        assert np.allclose(got.point[tie], want.point[tie], rtol=0, atol=1e-6)
        assert np.array_equal(got.point[~tie], want.point[~tie])
        other = random_tile(n=32, seed=2)
        reused.update(other)
        assert reused._scene is not before and before.handle == 0
        start, d = incoherent_rays(reused, 20_000, 8)
        got = reused.closest_hit(start, d)
        with PeriodicScene(other) as new:
            want = new.closest_hit(start, d)
        assert np.array_equal(got.face, want.face) and np.array_equal(got.point, want.point)


def test_embree_scene_update_refuses_other_vertices_and_closed_scenes() -> None:
    from microsim.kernel.embree import Scene

    tile = random_tile(n=8, seed=1)
    scene = Scene(tile.vertices, tile.faces)
    with pytest.raises(ValueError, match="vertices"):
        scene.update(tile.vertices[:-1])
    scene.close()
    with pytest.raises(RuntimeError, match="closed"):
        scene.update(tile.vertices)


def test_scenes_closed_release_their_memory() -> None:
    """Making and closing 200 scenes (8 MB of Embree memory each, were it kept) or updating
    one 200 times leaves the process no larger than a few scenes."""
    import psutil

    tile = random_tile(n=256, seed=1)
    process = psutil.Process()
    for _ in range(5):  # the device, the compiled code and numpy's pools warm up
        PeriodicScene(tile, threads=1).close()
    before = process.memory_info().rss
    for _ in range(200):
        PeriodicScene(tile, threads=1).close()
    with PeriodicScene(tile, threads=1) as scene:
        for _ in range(200):
            scene.update(tile)
    assert process.memory_info().rss - before < 40e6


def test_paths_are_the_escaping_rays_of_the_raw_outcomes() -> None:
    """``trace_paths`` summarises the outcomes in place: its directions, weights and orders
    are views of the outcomes' columns, those of the rays that escaped as traced and zero
    for the others, whose weights are counted as lost (ended at the bounce limit here) or
    transmitted; to the transmitted the energy blocks add what the glass's events sent
    on, and the absorbed is every path's 1 − its final weight less that. Against the raw
    outcomes of the same rays and key (``PeriodicScene.run``), bit for bit (the sums to
    1e-12)."""
    from microsim.kernel.packing import FacetMaterials
    from microsim.kernel.slots import O_FATE, O_ORDER, O_W, S_DX, S_DZ, TRANSMITTED
    from microsim.materials import material_from_json
    from microsim.measurement.paths import trace_paths

    tile = random_tile(seed=3)
    tile.material = np.arange(len(tile.faces), dtype=np.int64) % 2
    tile.parts = ("glass", "paint")
    facets = FacetMaterials(tile.material, tile.parts, {
        "glass": material_from_json({"kind": "dielectric", "eta": 1.5}),  # F on, 1 − F sent
        "paint": material_from_json({"kind": "lambertian", "albedo": 0.5})})
    with PeriodicScene(tile, threads=2) as scene:
        start, d = incoherent_rays(scene, 5000, 2)
        raw = scene.run(start, d, facets, 2, np.random.SeedSequence(7))
        paths = trace_paths(scene, facets, start, d, 2, np.random.SeedSequence(7))
    fate = raw.ints[:, O_FATE]
    out = fate == ESCAPED
    assert 0 < out.sum() < len(fate)                 # some end at the bounce limit
    weight = raw.floats[:, O_W:]
    assert np.array_equal(paths.direction, np.where(out[:, None],
                                                    raw.floats[:, S_DX:S_DZ + 1], 0.0))
    assert np.array_equal(paths.weight, np.where(out[:, None], weight, 0.0))
    assert np.array_equal(paths.order, np.where(out, raw.ints[:, O_ORDER], 0))
    diverted, sent = raw.energy.sum(axis=(0, 1))
    ended = ~out & (fate != TRANSMITTED)
    np.testing.assert_allclose(paths.lost, weight[ended].sum(axis=0), rtol=1e-12)
    assert paths.lost.min() > 0
    np.testing.assert_allclose(paths.transmitted, sent + weight[fate == TRANSMITTED].sum(
        axis=0), rtol=1e-12)
    np.testing.assert_allclose(paths.absorbed, (1.0 - weight).sum(axis=0) - diverted,
                               rtol=1e-12)
    assert paths.transmitted.min() > 0 and paths.absorbed.min() > 0


def test_memory_freed_is_kept_for_the_next_batch() -> None:
    """``keep_pages``: an array of a beam's size (24 MiB) freed and allocated again is
    served from memory the process kept, already backed: its second touch takes under a
    tenth of the first's page faults. Without it (the same in a process that does not
    call it) glibc returns the block to the system when it is freed (its first
    allocation is a mapping of its own) and the next touch faults about every page
    anew. Each in a fresh process, whose allocator nothing else has used yet."""
    import subprocess
    import sys

    code = """
import resource, sys
import numpy as np
from microsim.pages import keep_pages
if sys.argv[1] == "keep":
    keep_pages()
def touch():
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    block = np.empty(3 << 20)
    block[::512] = 1.0
    del block
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before
print(touch(), touch())
"""
    faults = {}
    for arm in ("keep", "default"):
        out = subprocess.run([sys.executable, "-c", code, arm], capture_output=True,
                             text=True, check=True)
        faults[arm] = [int(x) for x in out.stdout.split()]
    first, again = faults["keep"]
    assert first > 3000 and again < first / 10, faults      # 6144 pages of 4 KiB
    first, again = faults["default"]
    assert again > first / 2, faults
