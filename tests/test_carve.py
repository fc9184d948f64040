"""Carved design spaces: the continuous-motion bound, dense-time collision checks, meshing."""

from __future__ import annotations

import functools

import numpy as np
import pytest
import trimesh
from fab_fixtures import example_loop
from scipy import ndimage
from scipy.spatial import cKDTree

from paraloop_core.algebra import dq, poly
from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import carve, meshing, sweep, voxelspace
from paraloop_core.linkage import loops
from paraloop_core.realization import motion_bound

RES = 40  # voxels along a design space: coarse but quick


def rel_mats(jf: np.ndarray, a: int, b: int, u: np.ndarray) -> np.ndarray:
    """Pose ``(T, 4, 4)`` of link b in link a's frame from the link poses (independent path)."""
    poses = loops.link_poses(jf, poly.param_to_t(u))
    return dq.to_matrix(dq.mul(dq.inv(poses[:, a]), poses[:, b]))


def colliding(target: voxelspace.VoxelSpace, src: voxelspace.VoxelSpace,
              mats: np.ndarray) -> int:
    """Number of (time, source voxel) hits: a source ball meets a target ball. Exact, with an
    EDT prefilter: dist(p, A) >= EDT(nearest grid point) - h_a."""
    reach = target.half_diagonal + src.half_diagonal
    pad = 4
    edt = ndimage.distance_transform_edt(~np.pad(target.occupancy, pad), sampling=target.pitch)
    tree = cKDTree(target.centers())
    pts = src.centers()
    to_grid = np.linalg.inv(target.frame)
    hits = 0
    for m in mats:  # dense times, one at a time (memory)
        p = pts @ m[:3, :3].T + m[:3, 3]
        g = (p @ to_grid[:3, :3].T + to_grid[:3, 3]) / target.pitch
        idx = np.rint(g).astype(int) + pad
        inside = np.all((idx >= 0) & (idx < edt.shape), axis=1)
        cand = np.zeros(len(p), bool)
        cand[inside] = edt[tuple(idx[inside].T)] - target.half_diagonal <= reach
        if cand.any():
            d, _ = tree.query(p[cand], distance_upper_bound=reach)
            hits += int(np.sum(d <= reach))
    return hits


@functools.lru_cache(maxsize=1)
def carved() -> carve.Carving:
    jf, pts, radius = example_loop()
    spaces = voxelspace.default_spaces(pts, 2.5 * radius, resolution=RES)
    return carve.carve(jf, pts, spaces, keep_radius=radius)


def test_motion_bound_dominates_sampled_speed():
    jf, pts, _ = example_loop()
    u = (np.arange(20000) + 0.5) / 20000
    rng = np.random.default_rng(0)
    for a, b in [(0, 3), (1, 2), (2, 5), (4, 0)]:
        center, radius = pts[2 * b], 0.4
        mb = motion_bound.motion_bound(jf, a, b, center)
        probe = center + radius * rng.normal(size=(16, 3)) / np.sqrt(3)
        probe = center + (probe - center) * np.minimum(
            1, radius / np.linalg.norm(probe - center, axis=1))[:, None]
        m = rel_mats(jf, a, b, u)
        x = np.einsum("tij,nj->tni", m[:, :3, :3], probe) + m[:, None, :3, 3]
        speed = np.linalg.norm(np.diff(x, axis=0), axis=-1).max(1) / (np.pi / len(u))
        # cells are finer where the motion turns fast: look the sample ends up in the edges
        cell = np.clip(np.searchsorted(mb.edges, np.pi * (u - 0.5), side="right") - 1, 0,
                       mb.omega.size - 1)
        rate = mb.rate(radius)
        assert np.all(speed <= np.maximum(rate[cell[:-1]], rate[cell[1:]]) * (1 + 1e-9))


def test_displacement_bounds_cover_the_motion_between_samples():
    jf, pts, _ = example_loop()
    a, b, radius = 1, 4, 0.5
    center = pts[2 * b]
    mb = motion_bound.motion_bound(jf, a, b, center)
    u = np.sort(np.random.default_rng(1).random(40))
    delta = motion_bound.displacement_bounds(mb, radius, u)
    dense = (np.arange(8000) + 0.25) / 8000
    nearest = np.argmin(np.abs((dense[:, None] - u[None, :] + 0.5) % 1.0 - 0.5), axis=1)
    probe = center + np.array([[radius, 0, 0], [0, -radius, 0], [0, 0, radius], [0, 0, 0]])
    xs = np.einsum("tij,nj->tni", (m := rel_mats(jf, a, b, dense))[:, :3, :3], probe) + \
        m[:, None, :3, 3]
    ms = rel_mats(jf, a, b, u)
    x0 = np.einsum("tij,nj->tni", ms[:, :3, :3], probe) + ms[:, None, :3, 3]
    moved = np.linalg.norm(xs - x0[nearest], axis=-1).max(1)
    assert np.all(moved <= delta[nearest] + 1e-12)
    # adaptive samples: every time is within integrated bound 0.05 of some sample
    us = motion_bound.adaptive_params(mb, radius, 0.05)
    edges, cum = mb.cumulative(radius)
    lam = np.interp(np.pi * (dense - 0.5), edges, cum)
    lam_s = np.interp(np.pi * (us - 0.5), edges, cum)
    gap = np.abs(lam[:, None] - lam_s[None, :])
    gap = np.minimum(gap, cum[-1] - gap)  # cyclic
    assert gap.min(axis=1).max() <= 0.05 + 1e-12


def test_carved_spaces_are_collision_free_at_dense_times():
    jf, _, _ = example_loop()
    cv = carved()
    jf0, pts, radius = example_loop()
    spaces = voxelspace.default_spaces(pts, 2.5 * radius, resolution=RES)
    before = [sp.occupancy.sum() for sp in spaces]
    after = [sp.occupancy.sum() for sp in cv.spaces]
    assert all(0 < n1 < n0 for n0, n1 in zip(before, after, strict=True))  # really carved
    assert cv.report["max_motion_margin"] > 0
    u = (np.arange(600) + 0.318) / 600  # not the carving samples
    for a in range(6):
        for b in range(6):
            if a != b:
                assert colliding(cv.spaces[a], cv.spaces[b], rel_mats(jf, a, b, u)) == 0, (a, b)


def test_naive_sampled_sweep_misses_what_the_dilated_sweep_catches():
    """Carving link a by link b's sweep at 12 uniform samples, dilated only by the voxel sizes,
    leaves voxels that collide at times between the samples; the motion-bound dilation not."""
    jf, pts, radius = example_loop()
    a, b = 2, 5
    spaces = voxelspace.default_spaces(pts, 2.5 * radius, resolution=RES)
    target, src = spaces[a], spaces[b]
    keep = np.zeros_like(target.occupancy)
    grid_pts = np.argwhere(src.occupancy) * src.pitch
    u12 = np.arange(12) / 12
    mats = np.linalg.inv(target.frame) @ sweep.relative_mats(jf, a, b, u12) @ src.frame
    naive = sweep.splat_remove(target, keep, [(grid_pts, mats)],
                               src.half_diagonal + 2 * target.half_diagonal)
    delta = target.pitch
    jobs, n = sweep.sweep_jobs(jf, a, b, target, grid_pts, grid_pts, src.frame, delta)
    safe = sweep.splat_remove(target, keep, jobs, delta + src.half_diagonal
                              + 2 * target.half_diagonal)
    dense = rel_mats(jf, a, b, (np.arange(2000) + 0.5) / 2000)
    assert n > 12
    assert colliding(target.with_occupancy(naive), src, dense) > 0
    assert colliding(target.with_occupancy(safe), src, dense) == 0


def test_meshes_are_watertight_and_inside_the_voxel_region():
    jf, pts, radius = example_loop()
    for sp in voxelspace.default_spaces(pts, 3 * radius, resolution=RES)[1:3]:
        occ = sp.occupancy.copy()
        occ[: occ.shape[0] // 3, : occ.shape[1] // 2] = False  # a notch, not just a capsule
        sp = sp.with_occupancy(occ)
        v, f = meshing.space_mesh(sp)
        mesh = trimesh.Trimesh(v, f, process=True)
        assert mesh.is_watertight and mesh.volume > 0
        d, _ = cKDTree(sp.centers()).query(v)
        assert d.max() <= sp.half_diagonal + 1e-9


def test_marching_tetrahedra_sphere():
    g = np.stack(np.meshgrid(*[np.arange(24.0)] * 3, indexing="ij"), -1) - 11.5
    v, f = meshing.marching_tetrahedra(7.3 - np.linalg.norm(g, axis=-1))
    mesh = trimesh.Trimesh(v, f)
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.volume == pytest.approx(4 / 3 * np.pi * 7.3**3, rel=0.03)


def test_user_mesh_space_and_per_link_radii():
    box = trimesh.creation.box(extents=[1.0, 0.5, 0.25])
    sp = voxelspace.mesh_space(box.vertices, box.faces, 0.05)
    c = sp.centers()
    assert len(c) > 100 and np.all(np.abs(c) <= [0.5, 0.25, 0.125] + np.array(0.05))
    assert sp.occupancy.sum() * 0.05**3 == pytest.approx(box.volume, rel=0.35)
    _, pts, radius = example_loop()
    spaces = voxelspace.default_spaces(pts, [radius * (1 + i) for i in range(6)], resolution=16)
    assert spaces[5].occupancy.shape[1] > spaces[0].occupancy.shape[1]
    with pytest.raises(FabricationError):
        voxelspace.default_spaces(pts, [radius] * 5)


def test_bad_inputs_refused():
    jf, pts, radius = example_loop()
    with pytest.raises(FabricationError):
        voxelspace.capsule_space(pts[0], pts[1], 0.0)
    spaces = voxelspace.default_spaces(pts, 2 * radius, resolution=16)
    empty = spaces[3].with_occupancy(np.zeros_like(spaces[3].occupancy))
    with pytest.raises(FabricationError) as err:
        carve.carve(jf, pts, spaces[:3] + [empty] + spaces[4:], keep_radius=radius)
    assert err.value.reason == "empty-space"
    with pytest.raises(FabricationError) as err:
        carve.carve(jf, pts, spaces, keep_radius=radius, order=[(0, 0)])
    assert err.value.reason == "bad-parameters"
    with pytest.raises(FabricationError, match="all 15 pairs"):  # an uncarved pair
        carve.carve(jf, pts, spaces, keep_radius=radius, order=carve.DEFAULT_ORDER[1:])
    with pytest.raises(FabricationError) as err:
        meshing.space_mesh(spaces[1].with_occupancy(np.pad(np.ones((2, 2, 2), bool), 1)))
    assert err.value.reason == "empty-space"


def test_an_emptied_space_stays_empty_without_error():
    _, pts, radius = example_loop()
    sp = voxelspace.capsule_space(pts[0], pts[1], radius, resolution=16)
    empty = sp.with_occupancy(np.zeros_like(sp.occupancy))
    jobs = [(sp.centers(), np.eye(4)[None])]
    assert not sweep.splat_remove(empty, empty.occupancy, jobs, radius).any()


def test_coarsened_space_covers_the_fine_region():
    """Each fine voxel's ball lies in an occupied coarse voxel's ball (the sweep of the coarse
    source removes at least what the fine one would)."""
    rng = np.random.default_rng(5)
    rot = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    frame = np.eye(4)
    frame[:3, :3], frame[:3, 3] = rot, rng.normal(size=3)
    fine = voxelspace.VoxelSpace(rng.random((9, 7, 5)) < 0.2, 0.3, frame)
    for stride in (1, 2, 3):
        coarse = fine.coarsened(stride)
        assert coarse.pitch == pytest.approx(0.3 * stride)
        assert coarse.half_diagonal == pytest.approx(stride * fine.half_diagonal)
        d = np.linalg.norm(fine.centers()[:, None] - coarse.centers()[None], axis=-1)
        assert np.all(d.min(axis=1) + fine.half_diagonal <= coarse.half_diagonal + 1e-12)
        assert coarse.occupancy.sum() <= fine.occupancy.sum()


def test_auto_resolution_puts_voxels_across_the_thinnest_space():
    from paraloop_core.fabrication.voxelspace import AUTO_VOXELS_PER_RADIUS, auto_resolution

    pts = np.zeros((12, 3))
    pts[1::2, 0] = 1.0  # six bars of length 1 along x (base link twice as thick by default)
    for radius, want in ((0.05, 128), (0.03, 160), (0.02, 256), (0.005, 256)):
        res = auto_resolution(pts, radius)
        assert res == want
        if res < 256:  # enough voxels across the thinnest (radius) capsule
            assert res * radius / (1.0 + 2 * radius) >= AUTO_VOXELS_PER_RADIUS
    assert auto_resolution(pts, [0.2] * 5 + [0.03]) == 160  # six radii: the thinnest decides
    with pytest.raises(FabricationError):
        auto_resolution(pts, 0.0)
