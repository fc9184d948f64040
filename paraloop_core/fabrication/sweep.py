"""Swept removal for carving: the sweep of a moving source of one link (bar sample points or a
voxel solid), sampled in time with the continuous-motion bound of :mod:`motion_bound`, splatted
into a target link's voxel grid (:mod:`voxelspace`) to remove every voxel it can reach.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from scipy import ndimage

from paraloop_core.algebra import dq, poly
from paraloop_core.fabrication.voxelspace import VoxelSpace
from paraloop_core.linkage import loops
from paraloop_core.realization.motion_bound import sound_params

#: Source voxels per axis swept as one block: the sweep of a solid costs (boundary points) x
#: (time samples), so stride 2 is 4x faster; the removal reach grows by one source
#: half-diagonal (0.87 voxel), a slightly more conservative carving.
SOURCE_STRIDE = 2
_CHUNK_POINTS = 1_000_000  # points transformed per numpy call (memory: ~12 MB float32 each)


def splat_remove(target: VoxelSpace, keep: np.ndarray,
                 jobs: Sequence[tuple[np.ndarray, np.ndarray]], reach: float) -> np.ndarray:
    """Occupancy of ``target`` minus voxels (outside ``keep``) whose centre lies within
    ``reach`` of a point ``mats[t] @ src`` for a job ``(src (N, 3), mats (T, 4, 4))`` mapping
    source points into target grid coordinates (``pitch * index``)."""
    # float32 transforms (index units <= ~1e3, rounding <= 1e-4 voxel) are absorbed by this:
    reach = reach + 1e-3 * target.pitch
    pad = int(np.ceil((reach + target.half_diagonal) / target.pitch)) + 1
    shape = np.array(target.occupancy.shape) + 2 * pad
    marked = np.zeros(int(np.prod(shape)), bool)
    # Fold 1/pitch and the padding into the matrices; +0.5 then truncation rounds to the
    # nearest centre (values in (-1, 0) truncate into the padding, harmlessly far away).
    to_idx = np.diag([1 / target.pitch] * 3 + [1.0])
    to_idx[:3, 3] = pad + 0.5
    lim = shape.astype(np.uint32)
    chunks = []
    for src, mats in jobs:
        # rows (x, y, z) of the matrices, transposed: one batched BLAS product per chunk
        m32 = np.ascontiguousarray((to_idx @ mats)[:, :3, :].transpose(0, 2, 1), np.float32)
        src32 = np.concatenate([np.asarray(src, np.float32).reshape(-1, 3),
                                np.ones((len(src), 1), np.float32)], axis=1)
        step = max(1, _CHUNK_POINTS // max(len(src), 1))
        chunks += [(src32, m32[t0:t0 + step]) for t0 in range(0, len(m32), step)]

    def mark(chunk: tuple[np.ndarray, np.ndarray]) -> None:
        p = chunk[0] @ chunk[1]  # (t, n, 3) homogeneous transform
        i = p.reshape(-1, 3).astype(np.int32).view(np.uint32)  # negatives wrap: rejected
        ok = (i[:, 0] < lim[0]) & (i[:, 1] < lim[1]) & (i[:, 2] < lim[2])
        i = i[ok].astype(np.int64)
        marked[(i[:, 0] * shape[1] + i[:, 1]) * shape[2] + i[:, 2]] = True  # idempotent

    # numpy releases the GIL in these array operations: the chunks run on every core
    with ThreadPoolExecutor(max_workers=min(len(chunks), os.cpu_count() or 1) or 1) as pool:
        list(pool.map(mark, chunks))
    marked = marked.reshape(shape)
    # Only the box around the occupied voxels needs distances.
    occ_idx = np.argwhere(target.occupancy)
    if not len(occ_idx):  # nothing left to remove (reported as empty-space by the caller)
        return target.occupancy
    box = tuple(slice(lo, hi) for lo, hi in
                zip(occ_idx.min(0), occ_idx.max(0) + 2 * pad + 1, strict=True))
    sub = marked[box]
    if not sub.any():
        return target.occupancy
    near = np.zeros(shape, bool)
    near[box] = ndimage.distance_transform_edt(~sub, sampling=target.pitch) <= reach
    sl = tuple(slice(pad, pad + n) for n in target.occupancy.shape)
    return target.occupancy & ~(near[sl] & ~keep)


def relative_mats(joint_factors: np.ndarray, a: int, b: int, u: np.ndarray) -> np.ndarray:
    """Matrices ``(T, 4, 4)``: pose of link b in link a's home frame at parameters u."""
    c = loops.relative_motion(joint_factors, a, b)
    return dq.to_matrix(poly.evaluate_pose(c, poly.param_to_t(u)))


def sweep_jobs(jf: np.ndarray, a: int, b: int, target: VoxelSpace, boundary: np.ndarray,
               interior: np.ndarray, frame_b: np.ndarray, delta: float) -> tuple[list, int]:
    """Splat jobs for the sweep of a source of link b in link a's grid: its ``boundary`` points
    at adaptive samples (every time within moved distance ``delta`` of a sample) and its
    ``interior`` points at one time (a solid's sweep is its pose at one time plus the sweep of
    its boundary). Points in b's grid coordinates, mapped home by ``frame_b``."""
    home = boundary @ frame_b[:3, :3].T + frame_b[:3, 3]
    center = 0.5 * (home.min(0) + home.max(0))
    radius = float(np.max(np.linalg.norm(home - center, axis=1)))
    u = sound_params(jf, a, b, center, radius, delta)
    # target.frame maps pitch * index -> home, so its inverse gives grid coordinates.
    mats = np.linalg.inv(target.frame) @ relative_mats(jf, a, b, u) @ frame_b
    return [(boundary, mats), (interior, mats[:1])], len(u)


def solid_jobs(jf: np.ndarray, a: int, b: int, target: VoxelSpace, src: VoxelSpace,
               delta: float) -> tuple[list, int, float]:
    """Splat jobs of the sweep of the region of ``src`` (a solid of link b) in link a's grid,
    their sample count and the removal reach (design units): time margin + source ball +
    rounding to a target centre + target ball. The source is swept as blocks of
    :data:`SOURCE_STRIDE` voxels per axis (:meth:`VoxelSpace.coarsened`, a superset)."""
    src = src.coarsened(SOURCE_STRIDE)
    occ = src.occupancy
    bnd = occ & ~ndimage.binary_erosion(occ, np.ones((3, 3, 3), bool))
    jobs, nt = sweep_jobs(jf, a, b, target, np.argwhere(bnd) * src.pitch,
                          np.argwhere(occ) * src.pitch, src.frame, delta * target.pitch)
    return jobs, nt, delta * target.pitch + src.half_diagonal + 2 * target.half_diagonal
