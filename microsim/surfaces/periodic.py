"""Making geometry periodic: cut what crosses a tile side, bring the rest back inside."""

from __future__ import annotations

import numpy as np


def _edge_point(p: np.ndarray, q: np.ndarray, dp: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """Where the segment p→q crosses the plane, from signed distances dp ≥ 0 > dq."""
    t = dp / (dp - dq)
    return p + t[:, None] * (q - p)


def clip_triangles(tri: np.ndarray, material: np.ndarray, normal: np.ndarray,
                   offset: float) -> tuple[np.ndarray, np.ndarray]:
    """Keep the part of each triangle where normal · x ≥ offset (Sutherland & Hodgman 1974,
    one plane), preserving the winding.

    A triangle with one vertex inside becomes one triangle, with two inside a quad split in
    two; wholly inside it is kept, wholly outside dropped.

    Parameters
    ----------
    tri : (m, 3, 3) float
        Triangle soup.
    material : (m,) int
    normal : (3,) float
    offset : float

    Returns
    -------
    tri : (k, 3, 3) float
    material : (k,) int
    """
    d = tri @ normal - offset
    inside = d >= 0
    count = inside.sum(axis=1)
    out_t, out_m = [tri[count == 3]], [material[count == 3]]
    for n_in in (1, 2):
        sel = np.flatnonzero(count == n_in)
        if not sel.size:
            continue
        # roll each triangle so vertex A is the odd one out (inside for 1, outside for 2)
        odd = inside[sel] if n_in == 1 else ~inside[sel]
        k = np.argmax(odd, axis=1)
        order = (k[:, None] + np.arange(3)) % 3
        t = np.take_along_axis(tri[sel], order[:, :, None], axis=1)
        dd = np.take_along_axis(d[sel], order, axis=1)
        a, b, c = t[:, 0], t[:, 1], t[:, 2]
        if n_in == 1:  # A inside: (A, AB*, AC*)
            ab = _edge_point(a, b, dd[:, 0], dd[:, 1])
            ac = _edge_point(a, c, dd[:, 0], dd[:, 2])
            out_t.append(np.stack([a, ab, ac], axis=1))
            out_m.append(material[sel])
        else:  # A outside: the quad (B, C, CA*, AB*) as two triangles
            ca = _edge_point(c, a, dd[:, 2], dd[:, 0])
            ab = _edge_point(b, a, dd[:, 1], dd[:, 0])
            out_t += [np.stack([b, c, ca], axis=1), np.stack([b, ca, ab], axis=1)]
            out_m += [material[sel], material[sel]]
    return np.concatenate(out_t), np.concatenate(out_m)


def wrap_into_box(vertices: np.ndarray, faces: np.ndarray, material: np.ndarray,
                  period: tuple[float, float], groups: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The periodic tile of geometry that may stick out of [0, Lx] × [0, Ly].

    The tile is the union over shifts (i Lx, j Ly), i, j ∈ {−1, 0, 1}, of the shifted
    geometry clipped to the box, so a piece that leaves one side re-enters at the opposite
    one. Groups (e.g. one fibre each) lying wholly inside the box are kept as they are;
    only groups whose bounding box crosses a side are cut (``clip_triangles`` against the
    four sides). Slivers the cuts leave (area below 1e-12 of the largest face) are dropped.

    Parameters
    ----------
    vertices : (n, 3) float
    faces : (m, 3) int
    material : (m,) int
    period : (Lx, Ly)
    groups : (m,) int
        Connected object of each face; objects no larger than the period.

    Returns
    -------
    vertices, faces, material
        The periodic geometry, every vertex within the box (cut pieces become separate
        triangles).
    """
    lx, ly = period
    tri = vertices[faces]
    lo = np.full((groups.max() + 1, 2), np.inf)
    hi = np.full((groups.max() + 1, 2), -np.inf)
    np.minimum.at(lo, groups, tri[:, :, :2].min(axis=1))
    np.maximum.at(hi, groups, tri[:, :, :2].max(axis=1))
    crossing = ((lo < 0) | (hi > [lx, ly])).any(axis=1)[groups]
    pieces, piece_m = [], []
    sides = [((1.0, 0.0, 0.0), 0.0), ((-1.0, 0.0, 0.0), -lx),
             ((0.0, 1.0, 0.0), 0.0), ((0.0, -1.0, 0.0), -ly)]
    for i in (-1, 0, 1):
        for j in (-1, 0, 1):
            t, m = tri[crossing] + [i * lx, j * ly, 0.0], material[crossing]
            for normal, offset in sides:
                if not len(t):
                    break
                t, m = clip_triangles(t, m, np.array(normal), offset)
            pieces.append(t)
            piece_m.append(m)
    soup = np.concatenate(pieces) if pieces else np.zeros((0, 3, 3))
    soup[:, :, 0] = np.clip(soup[:, :, 0], 0.0, lx)
    soup[:, :, 1] = np.clip(soup[:, :, 1], 0.0, ly)
    n = len(vertices)
    vertices = np.concatenate([vertices, soup.reshape(-1, 3)])
    faces = np.concatenate([faces[~crossing], n + np.arange(3 * len(soup)).reshape(-1, 3)])
    material = np.concatenate([material[~crossing], *piece_m]).astype(np.int32)
    t = vertices[faces]
    area = 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)
    keep = area > 1e-12 * area.max()
    faces, material = faces[keep], material[keep]
    used, faces = np.unique(faces, return_inverse=True)  # drop vertices no face uses
    return vertices[used], faces.reshape(-1, 3).astype(np.int64), material
