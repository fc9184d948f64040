"""Numpy kernels of the guide's renderer (:mod:`render`): a scanline z-buffer and feature edges.

Screen convention: pixel ``(x, y)`` with x to the right and y down; the centre of pixel
``(col, row)`` is ``(col + 0.5, row + 0.5)``. Depth is normalized to ``[0, 1]`` over the scene
(0 nearest the eye). A pixel is covered by a triangle when its centre lies inside it (rows: the
half-open rule ``y_min <= y < y_max``; columns: between the two edge crossings of the row).

The z-buffer is a flat ``(H * W,)`` ``int64`` array of keys ``(depth quantized to DEPTH_BITS)
<< FACE_BITS | face``, :data:`EMPTY` where nothing is drawn: one ``np.minimum.at`` keeps the
nearest fragment per pixel, ties going to the lower face index (deterministic).
"""

from __future__ import annotations

import functools

import numpy as np

FACE_BITS = 25
DEPTH_BITS = 37
FACE_MASK = (1 << FACE_BITS) - 1
EMPTY = np.iinfo(np.int64).max


def expand(counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(owner, offset)`` over ``counts.sum()`` slots: slot k belongs to ``owner[k]`` and is
    its ``offset[k]``-th (``0 .. counts[owner] - 1``)."""
    owner = np.repeat(np.arange(len(counts)), counts)
    start = np.cumsum(counts) - counts
    return owner, np.arange(len(owner)) - start[owner]


def quantize(depth: np.ndarray) -> np.ndarray:
    """Normalized depth ``[0, 1]`` -> integer depth of the keys."""
    return (np.clip(depth, 0.0, 1.0) * float((1 << DEPTH_BITS) - 1)).astype(np.int64)


def rasterize(xy: np.ndarray, depth: np.ndarray, shape: tuple[int, int],
              keys: np.ndarray | None = None, first_face: int = 0) -> np.ndarray:
    """Z-buffer keys ``(H * W,)`` of the triangles ``xy`` ``(F, 3, 2)`` (pixels) with vertex
    depths ``depth`` ``(F, 3)`` (normalized), face ``k`` keyed as ``first_face + k``; drawn into
    ``keys`` (modified) when given. Degenerate (zero-area) triangles draw nothing.

    Per triangle (vertices sorted by y: top, middle, bottom) each covered row's span lies
    between the long edge top-bottom and the short edge above or below the middle vertex; a
    fragment's key is its span's first key plus an integer step per pixel (exact)."""
    h, w = shape
    if keys is None:
        keys = np.full(h * w, EMPTY, np.int64)
    if len(xy) == 0:
        return keys
    order = np.argsort(xy[..., 1], axis=1)
    v = np.take_along_axis(np.concatenate([xy, depth[..., None]], -1), order[..., None], 1)
    (x0, y0, z0), (x1, y1, z1), (x2, y2, z2) = (v[:, k].T for k in range(3))
    r0 = np.clip(np.ceil(y0 - 0.5), 0, h).astype(np.int64)
    r1 = np.clip(np.ceil(y2 - 0.5), 0, h).astype(np.int64)
    # the depth plane z = z0 + a (x - x0) + b (y - y0) of each triangle
    det = (x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0)
    live = np.flatnonzero((np.abs(det) > 1e-12) & (r1 > r0))
    x0, y0, z0, x1, y1, z1, x2, y2, z2, det = (
        u[live] for u in (x0, y0, z0, x1, y1, z1, x2, y2, z2, det))
    a = ((z1 - z0) * (y2 - y0) - (z2 - z0) * (y1 - y0)) / det
    b = ((x1 - x0) * (z2 - z0) - (x2 - x0) * (z1 - z0)) / det
    with np.errstate(divide="ignore", invalid="ignore"):  # horizontal edges: never used
        s02, s01, s12 = (x2 - x0) / (y2 - y0), (x1 - x0) / (y1 - y0), (x2 - x1) / (y2 - y1)
    # one (triangle, row) pair per covered row, its span [c0, c1) of pixel centres
    n = r1[live] - r0[live]
    tri, off = expand(n)
    rep = functools.partial(np.repeat, repeats=n)
    yc = rep(r0[live]) + off + 0.5
    t0, tx0, ty0 = rep(y1), rep(x0), rep(y0)
    xl = tx0 + (yc - ty0) * rep(s02)
    with np.errstate(invalid="ignore"):
        xs = np.where(yc < t0, tx0 + (yc - ty0) * rep(s01), rep(x1) + (yc - t0) * rep(s12))
    c0 = np.clip(np.ceil(np.minimum(xl, xs) - 0.5), 0, w).astype(np.int64)
    c1 = np.clip(np.ceil(np.maximum(xl, xs) - 0.5), 0, w).astype(np.int64)
    span = np.flatnonzero(c1 > c0)
    tri, c0, yc = tri[span], c0[span], yc[span]
    zs = z0[tri] + a[tri] * (c0 + 0.5 - x0[tri]) + b[tri] * (yc - y0[tri])
    key0 = (quantize(zs) << FACE_BITS) | (live[tri] + first_face)
    step = np.round(a[tri] * float((1 << DEPTH_BITS) - 1)).astype(np.int64) << FACE_BITS
    # fragments
    m = c1[span] - c0
    _, off = expand(m)
    pix = np.repeat((yc - 0.5).astype(np.int64) * w + c0, m) + off
    np.minimum.at(keys, pix, np.repeat(key0, m) + off * np.repeat(step, m))
    return keys


def feature_edges(faces: np.ndarray, normals: np.ndarray, front: np.ndarray,
                  crease_cos: float) -> np.ndarray:
    """Vertex pairs ``(E, 2)`` of the edges to outline of a mesh ``faces`` ``(F, 3)`` with unit
    face ``normals`` ``(F, 3)`` and ``front`` ``(F,)`` (faces towards the eye): silhouettes
    (a front and a back face meet), creases between front faces (normals' cosine below
    ``crease_cos``) and open borders of front faces. An edge shared by more than two faces
    (non-manifold) is judged by consecutive face pairs."""
    e = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    owner = np.repeat(np.arange(len(faces)), 3)
    key = e[:, 0].astype(np.int64) * (int(faces.max(initial=0)) + 1) + e[:, 1]
    order = np.argsort(key, kind="stable")
    ks = key[order]
    same = np.flatnonzero(ks[1:] == ks[:-1])
    f, g = owner[order[same]], owner[order[same + 1]]
    paired = np.zeros(len(e), bool)
    paired[order[same]] = paired[order[same + 1]] = True
    sharp = (front[f] != front[g]) | (
        front[f] & front[g] & (np.einsum("ij,ij->i", normals[f], normals[g]) < crease_cos))
    border = ~paired & front[owner]
    return np.concatenate([e[order[same[sharp]]], e[border]])


def segment_samples(p0: np.ndarray, p1: np.ndarray, step: float
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Points along the segments ``p0 -> p1`` ``(S, k)`` (first two components: pixels) about
    ``step`` pixels apart, both ends included: ``(points (N, k), segment index (N,))``."""
    n = np.ceil(np.linalg.norm(p1[:, :2] - p0[:, :2], axis=1) / step).astype(np.int64) + 1
    seg, off = expand(n)
    t = (off / np.maximum(n[seg] - 1, 1))[:, None]
    return p0[seg] + t * (p1[seg] - p0[seg]), seg


def visible(points: np.ndarray, keys: np.ndarray, shape: tuple[int, int],
            tol: float) -> np.ndarray:
    """``(N,)`` whether the points ``(N, 3)`` (pixel x, y, normalized depth) are in front of
    the z-buffer ``keys`` within ``tol`` (normalized depth), at the farthest of the 3 x 3
    pixels about each (an edge on a silhouette or crease passes: a neighbour lies on the
    farther side). Points off the image are not visible."""
    h, w = shape
    col = np.floor(points[:, 0]).astype(np.int64)
    row = np.floor(points[:, 1]).astype(np.int64)
    inside = (col >= 0) & (col < w) & (row >= 0) & (row < h)
    far = np.full(len(points), -1, np.int64)
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            r, cc = np.clip(row + dr, 0, h - 1), np.clip(col + dc, 0, w - 1)
            far = np.maximum(far, keys[r * w + cc] >> FACE_BITS)
    return inside & (quantize(points[:, 2] - tol) <= far)


def disk_offsets(radius: float) -> np.ndarray:
    """Integer pixel offsets ``(K, 2)`` (dx, dy) within ``radius`` (at least the centre)."""
    r = int(np.ceil(radius))
    d = np.stack(np.meshgrid(np.arange(-r, r + 1), np.arange(-r, r + 1)), -1).reshape(-1, 2)
    return d[np.hypot(d[:, 0], d[:, 1]) <= max(radius, 0.5)]


def stamp(points: np.ndarray, radius: float, shape: tuple[int, int]) -> np.ndarray:
    """Flat pixel indices covered by disks of ``radius`` about ``points`` ``(N, 2)`` (pixels),
    clipped to the image, each once."""
    h, w = shape
    d = disk_offsets(radius)
    col = (np.floor(points[:, 0]).astype(np.int64)[:, None] + d[:, 0]).ravel()
    row = (np.floor(points[:, 1]).astype(np.int64)[:, None] + d[:, 1]).ravel()
    ok = (col >= 0) & (col < w) & (row >= 0) & (row < h)
    return np.unique(row[ok] * w + col[ok])
