"""Link design spaces carved as in paper Sec. 5.2, with a rigorous continuous-motion bound.

Frames and units: every link's geometry lives in its **home frame** (the base frame at
``t = inf``, where all link poses are the identity), in design units. A voxel space stores its
centres as ``frame @ [pitch * (i, j, k), 1]``; its *region* is the union of closed balls of
radius ``h = sqrt(3)/2 pitch`` (the voxel half-diagonal) about the occupied centres. That region
contains every voxel cube and the meshes of :mod:`meshing`, and all guarantees below are about it.

The continuous-motion bound of the sweeps is :mod:`motion_bound`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from . import dq, loops, poly
from .errors import FabricationError
from .motion_bound import adaptive_params, motion_bound

Progress = Callable[[float, str], None]
_CHUNK_POINTS = 3_000_000  # points transformed per numpy call (memory only: ~36 MB float32)


@dataclass(frozen=True)
class VoxelSpace:
    """Occupancy ``(nx, ny, nz)`` bool; voxel ``(i,j,k)`` has its centre at
    ``frame @ [pitch*(i,j,k), 1]`` in the link's home frame (design units)."""

    occupancy: np.ndarray
    pitch: float
    frame: np.ndarray

    @property
    def half_diagonal(self) -> float:
        return float(np.sqrt(3.0) / 2.0 * self.pitch)

    def centers(self, mask: np.ndarray | None = None) -> np.ndarray:
        """Home-frame centres ``(N, 3)`` of the voxels in ``mask`` (default: occupied)."""
        idx = np.argwhere(self.occupancy if mask is None else mask) * self.pitch
        return idx @ self.frame[:3, :3].T + self.frame[:3, 3]

    def with_occupancy(self, occ: np.ndarray) -> VoxelSpace:
        return VoxelSpace(occ, self.pitch, self.frame)


def _bar_frame(p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Rotation ``(3, 3)`` with first column along ``p1 - p0`` (any, if degenerate)."""
    e = p1 - p0
    e = e / n if (n := np.linalg.norm(e)) > 0 else np.array([1.0, 0, 0])
    f = np.cross(e, [1.0, 0, 0] if abs(e[0]) < 0.9 else [0, 1.0, 0])
    f /= np.linalg.norm(f)
    return np.stack([e, f, np.cross(e, f)], axis=1)


def point_segment_distance(x: np.ndarray, p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Distance ``(...)`` of points ``(..., 3)`` to the segment ``[p0, p1]``."""
    d = p1 - p0
    t = np.clip((x - p0) @ d / max(float(d @ d), 1e-300), 0.0, 1.0)
    return np.linalg.norm(x - p0 - t[..., None] * d, axis=-1)


def capsule_space(p0: np.ndarray, p1: np.ndarray, radius: float,
                  resolution: int = 128) -> VoxelSpace:
    """Cylinder of ``radius`` about the bar ``[p0, p1]`` with hemispherical ends (the default
    potential design space), on a bar-aligned grid with ``resolution`` voxels along its longest
    side."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    if not (radius > 0 and np.isfinite(radius)) or resolution < 8:
        raise FabricationError("design-space radius must be > 0 and resolution >= 8",
                               "bad-parameters")
    length = float(np.linalg.norm(p1 - p0))
    pitch = (length + 2 * radius) / resolution
    rot = _bar_frame(p0, p1)
    dims = np.ceil(np.array([length + 2 * radius, 2 * radius, 2 * radius]) / pitch).astype(int) + 1
    frame = np.eye(4)
    frame[:3, :3] = rot
    frame[:3, 3] = p0 - rot @ np.full(3, radius)
    grid = np.stack(np.meshgrid(*[np.arange(d) for d in dims], indexing="ij"), -1) * pitch
    home = grid @ rot.T + frame[:3, 3]
    occ = point_segment_distance(home, p0, p1) <= radius
    return VoxelSpace(occ, pitch, frame)


def mesh_space(vertices: np.ndarray, faces: np.ndarray, pitch: float) -> VoxelSpace:
    """A user mesh (home frame of its link, design units) as a filled voxel space."""
    import trimesh

    mesh = trimesh.Trimesh(np.asarray(vertices, float), np.asarray(faces), process=True)
    if not mesh.is_watertight or not pitch > 0:
        raise FabricationError("a user design space must be a watertight mesh and pitch > 0",
                               "bad-parameters")
    vox = mesh.voxelized(pitch).fill()
    frame = np.asarray(vox.transform, float) @ np.diag([1 / pitch] * 3 + [1.0])
    return VoxelSpace(np.asarray(vox.matrix, bool), pitch, frame)


@dataclass(frozen=True)
class JointZone:
    """Cylinder of ``radius`` about axis A_i from ``E_i`` along unit ``w`` (towards
    ``S_{i+1}``), axial ``s`` in ``[-radius, length + radius]``, split at ``s = length/2``: the
    lower half belongs to link i, the upper half to link i+1 (both are solids of revolution
    about the shared axis, so their separation survives the joint's rotation)."""

    origin: np.ndarray
    w: np.ndarray
    length: float
    radius: float

    def coords(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Axial ``s`` and radial ``rho`` ``(...)`` of points ``(..., 3)``."""
        d = x - self.origin
        s = d @ self.w
        return s, np.linalg.norm(d - s[..., None] * self.w, axis=-1)

    def half_distance(self, x: np.ndarray, upper: bool) -> np.ndarray:
        """Distance ``(...)`` from points to the lower (link i) or upper (link i+1) half."""
        s, rho = self.coords(x)
        lo, hi = (self.length / 2, self.length + self.radius) if upper else \
            (-self.radius, self.length / 2)
        ds = np.maximum(np.maximum(lo - s, s - hi), 0.0)
        return np.hypot(ds, np.maximum(rho - self.radius, 0.0))

    def inside_half(self, x: np.ndarray, upper: bool, margin: float) -> np.ndarray:
        """Mask: the ball of radius ``margin`` about each point lies in the half."""
        s, rho = self.coords(x)
        lo, hi = (self.length / 2, self.length + self.radius) if upper else \
            (-self.radius, self.length / 2)
        return (rho <= self.radius - margin) & (s >= lo + margin) & (s <= hi - margin)


def _index_box(sp: VoxelSpace, points: np.ndarray, margin: float) -> tuple[slice, ...]:
    """Index box of ``sp`` holding every voxel centre within ``margin`` of the convex hull of
    ``points`` ``(n, 3)`` (home frame): their grid-frame bounding box, padded."""
    g = np.linalg.solve(sp.frame[:3, :3], (points - sp.frame[:3, 3]).T).T / sp.pitch
    lo = np.maximum(np.floor(g.min(0) - margin / sp.pitch), 0).astype(int)
    hi = np.minimum(np.ceil(g.max(0) + margin / sp.pitch) + 1, sp.occupancy.shape).astype(int)
    return tuple(slice(a, max(a, b)) for a, b in zip(lo, hi, strict=True))


def _zone_mask(sp: VoxelSpace, zone: JointZone, upper: bool, inside: bool) -> np.ndarray:
    """Grid mask of occupied voxels whose ball (radius h) meets (``inside=False``) or lies
    inside (``inside=True``) the lower/upper half of ``zone``."""
    h = sp.half_diagonal
    ends = zone.origin + np.outer([-zone.radius, zone.length + zone.radius], zone.w)
    box = _index_box(sp, ends, zone.radius + h)
    mask = np.zeros_like(sp.occupancy)
    sub = np.zeros_like(sp.occupancy)
    sub[box] = sp.occupancy[box]
    c = sp.centers(sub)
    hit = zone.inside_half(c, upper, h) if inside else zone.half_distance(c, upper) <= h
    mask[tuple(np.argwhere(sub)[hit].T)] = True
    return mask


def joint_zones(joint_factors: np.ndarray, points: np.ndarray, radius: float) -> list[JointZone]:
    """The six joint zones (``points`` ``(12, 3)`` offset polyline, ``radius`` design units)."""
    axes = loops.factor_axes(np.asarray(joint_factors, float))
    out = []
    for i in range(6):
        e, s = points[2 * i + 1], points[(2 * i + 2) % 12]
        length = float(np.linalg.norm(s - e))
        w = (s - e) / length if length > 1e-12 * (1 + np.abs(e).max()) else axes[i, :3]
        out.append(JointZone(e, w, length if length > 1e-12 else 0.0, float(radius)))
    return out


def _shared_joint(a: int, b: int) -> tuple[int, bool] | None:
    """Joint index shared by links a, b and whether a holds the upper half; None if not adjacent."""
    if b == (a + 1) % 6:
        return a, False
    if a == (b + 1) % 6:
        return b, True
    return None


def _splat_remove(target: VoxelSpace, keep: np.ndarray,
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
    for src, mats in jobs:
        m32 = (to_idx @ mats).astype(np.float32)
        src32 = np.asarray(src, np.float32)
        step = max(1, _CHUNK_POINTS // max(len(src), 1))
        for t0 in range(0, len(m32), step):  # chunks for memory only
            m = m32[t0:t0 + step]
            p = np.einsum("tij,nj->tni", m[:, :3, :3], src32) + m[:, None, :3, 3]
            i = p.reshape(-1, 3).astype(np.int32).view(np.uint32)  # negatives wrap: rejected
            ok = (i[:, 0] < lim[0]) & (i[:, 1] < lim[1]) & (i[:, 2] < lim[2])
            i = i[ok].astype(np.int64)
            marked[(i[:, 0] * shape[1] + i[:, 1]) * shape[2] + i[:, 2]] = True
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


def _relative_mats(joint_factors: np.ndarray, a: int, b: int, u: np.ndarray) -> np.ndarray:
    """Matrices ``(T, 4, 4)``: pose of link b in link a's home frame at parameters u."""
    c = loops.relative_motion(joint_factors, a, b)
    return dq.to_matrix(poly.evaluate_pose(c, poly.param_to_t(u)))


def _sweep_jobs(jf: np.ndarray, a: int, b: int, target: VoxelSpace, boundary: np.ndarray,
                interior: np.ndarray, frame_b: np.ndarray, delta: float) -> tuple[list, int]:
    """Splat jobs for the sweep of a source of link b in link a's grid: its ``boundary`` points
    at adaptive samples (every time within moved distance ``delta`` of a sample) and its
    ``interior`` points at one time (a solid's sweep is its pose at one time plus the sweep of
    its boundary). Points in b's grid coordinates, mapped home by ``frame_b``."""
    home = boundary @ frame_b[:3, :3].T + frame_b[:3, 3]
    center = 0.5 * (home.min(0) + home.max(0))
    radius = float(np.max(np.linalg.norm(home - center, axis=1)))
    u = adaptive_params(motion_bound(jf, a, b, center), radius, delta)
    # target.frame maps pitch * index -> home, so its inverse gives grid coordinates.
    mats = np.linalg.inv(target.frame) @ _relative_mats(jf, a, b, u) @ frame_b
    return [(boundary, mats), (interior, mats[:1])], len(u)


def _solid_jobs(jf: np.ndarray, a: int, b: int, target: VoxelSpace, src: VoxelSpace,
                delta: float) -> tuple[list, int, float]:
    """Splat jobs of the sweep of the region of ``src`` (a solid of link b) in link a's grid,
    their sample count and the removal reach (design units): time margin + source ball +
    rounding to a target centre + target ball."""
    occ = src.occupancy
    bnd = occ & ~ndimage.binary_erosion(occ, np.ones((3, 3, 3), bool))
    jobs, nt = _sweep_jobs(jf, a, b, target, np.argwhere(bnd) * src.pitch,
                           np.argwhere(occ) * src.pitch, src.frame, delta * target.pitch)
    return jobs, nt, delta * target.pitch + src.half_diagonal + 2 * target.half_diagonal


#: Default carving order: (target, source) pairs, the base link carved first.
DEFAULT_ORDER = tuple((a, b) for a in range(6) for b in range(a + 1, 6))


@dataclass(frozen=True)
class Carving:
    """Carved spaces (one per link), the joint zones used and a JSON-ready ``report``."""

    spaces: tuple[VoxelSpace, ...]
    zones: tuple[JointZone, ...]
    report: dict


def default_spaces(points: np.ndarray, radius: float | Sequence[float],
                   base_radius: float | None = None, resolution: int = 128) -> list[VoxelSpace]:
    """Capsules about the six bars (``points`` ``(12, 3)``, design units) of ``radius`` (one
    value, or six, e.g. a realization's design-space radii); with one value the base link's
    gets ``base_radius`` (default ``2 radius``: large, for grounding)."""
    pts = _check_points(points)
    if np.ndim(radius) == 0:
        radii = [base_radius if base_radius is not None else 2.0 * radius] + [radius] * 5
    else:
        radii = [float(r) for r in radius]
        if len(radii) != 6:
            raise FabricationError("give one design-space radius or six", "bad-parameters")
    return [capsule_space(pts[2 * i], pts[2 * i + 1], radii[i], resolution) for i in range(6)]


def _check_points(points: np.ndarray) -> np.ndarray:
    pts = np.asarray(points, float)
    if pts.shape != (12, 3) or not np.all(np.isfinite(pts)):
        raise FabricationError(f"points must be a finite (12, 3) polyline, got {pts.shape}",
                               "bad-parameters")
    return pts


def _clip_to_zones(spaces: list[VoxelSpace], zones: Sequence[JointZone]) -> list[VoxelSpace]:
    """Remove from each link the voxels whose ball meets its neighbour's half of a joint zone."""
    return [sp.with_occupancy(sp.occupancy & ~_zone_mask(sp, zones[a], True, False)
                              & ~_zone_mask(sp, zones[(a - 1) % 6], False, False))
            for a, sp in enumerate(spaces)]


def carve(joint_factors: np.ndarray, points: np.ndarray, spaces: Sequence[VoxelSpace], *,
          keep_radius: float, joint_radius: float | None = None,
          order: Sequence[tuple[int, int]] = DEFAULT_ORDER, delta: float = 1.0,
          bars: Sequence[np.ndarray | None] | None = None,
          fixed: Sequence[tuple[int, VoxelSpace]] = (),
          progress: Progress | None = None) -> Carving:
    """Sec. 5.2: clip the spaces at the joint zones, wire-cut each by the other moving bars,
    carve every link by the sweep of the ``fixed`` solids of the others, then carve target a by
    the sweep of source b for each ``(a, b)`` in ``order``.

    ``bars``: per link, None (its bar ``S_i E_i``) or segments ``(n, 2, 3)`` replacing it (the
    end link ``S_3 L``, ``R E_3``). ``fixed``: ``(link, solid)`` pairs, regions rigidly attached
    to a link and never carved (an end-effector P), removed with their sweep from every other
    link before the pairwise differences, so no order can carve them.

    ``keep_radius`` (design units): bar radius to keep clear in the wire cut (the bar survives
    the later differences). ``joint_radius`` (default ``1.25 keep_radius``) sizes the joint
    zones. ``delta``: time-sampling margin in voxels of the target. The carved regions are
    pairwise collision-free for the continuous motion (module docstring); joint-zone halves are
    solids of revolution about the shared axis and never meet."""
    jf = np.asarray(joint_factors, float)
    pts = _check_points(points)
    if jf.shape != (6, 8) or len(spaces) != 6:
        raise FabricationError("need joint factors (6, 8) and six design spaces",
                               "bad-parameters")
    if not (keep_radius > 0 and delta > 0) or (joint_radius is not None and joint_radius <= 0):
        raise FabricationError("keep_radius, joint_radius and delta must be > 0",
                               "bad-parameters")
    pairs = [tuple(int(x) for x in p) for p in order]
    bad = any(not (0 <= a < 6 and 0 <= b < 6) or a == b for a, b in pairs)
    if bad or len({frozenset(p) for p in pairs}) != len(pairs):
        raise FabricationError(f"order must list distinct pairs of links 0..5, got {pairs}",
                               "bad-parameters")
    for i, sp in enumerate(spaces):
        if not sp.occupancy.any():
            raise FabricationError(f"design space of link {i} is empty", "empty-space")
    segs = [pts[[2 * i, 2 * i + 1]][None] if bars is None or bars[i] is None
            else np.asarray(bars[i], float).reshape(-1, 2, 3) for i in range(6)]
    zones = joint_zones(jf, pts, joint_radius or 1.25 * keep_radius)
    cur = _clip_to_zones(list(spaces), zones)
    prot = {(a, j): _zone_mask(cur[a], zones[j], up, True)
            for a in range(6) for j, up in ((a, False), ((a - 1) % 6, True))}
    groups = _pair_groups(pairs)
    n_ops, done, ops = 6 + len(fixed) + len(groups), 0, []
    t_start = time.perf_counter()

    def tick(msg: str) -> None:
        if progress is not None:
            progress(done / n_ops, msg)

    # Wire cutting only helps bars survive (spaces stay pairwise safe without it): bar b keeps
    # keep_radius plus the largest pair-difference reach clear of every other space.
    h_max = max(sp.half_diagonal for sp in cur)
    extra = keep_radius + delta * max(sp.pitch for sp in cur) + 3 * h_max
    for a in range(6):
        tick(f"wire-cutting link {a} by the other bars")
        sp, jobs = cur[a], []
        sigma = sp.pitch / 2
        for b in [x for x in range(6) if x != a]:
            seg = np.concatenate([p0 + np.linspace(0, 1, int(np.linalg.norm(p1 - p0) / sigma)
                                                   + 2)[:, None] * (p1 - p0) for p0, p1 in segs[b]])
            if (sj := _shared_joint(a, b)) is not None:  # inside b's own half: never meets a
                seg = seg[~zones[sj[0]].inside_half(seg, not sj[1], sigma)]
            if len(seg):
                new, nt = _sweep_jobs(jf, a, b, sp, seg, seg[:0], np.eye(4), delta * sp.pitch)
                jobs += new
                ops.append({"kind": "wire", "target": a, "source": b, "samples": nt})
        keep = prot[(a, a)] | prot[(a, (a - 1) % 6)]
        reach = delta * sp.pitch + sigma / 2 + extra + 2 * sp.half_diagonal
        cur[a] = sp.with_occupancy(_splat_remove(sp, keep, jobs, reach))
        done += 1
    for f, solid in fixed:
        tick(f"carving the other links by the sweep of link {f}'s fixed solid")
        for a in (x for x in range(6) if x != f):
            jobs, nt, reach = _solid_jobs(jf, a, f, cur[a], solid, delta)
            cur[a] = cur[a].with_occupancy(
                _splat_remove(cur[a], np.zeros_like(cur[a].occupancy), jobs, reach))
            ops.append({"kind": "fixed", "target": a, "source": f, "samples": nt,
                        "motion_margin": delta * cur[a].pitch})
        done += 1
    for a, joint, sources in groups:
        tick(f"carving link {a} by the sweep of links {sources}")
        keep = np.zeros_like(cur[a].occupancy) if joint is None else prot[(a, joint)]
        jobs, reach = [], 0.0
        for b in sources:
            src = cur[b].occupancy if joint is None else cur[b].occupancy & ~prot[(b, joint)]
            if not src.any():
                continue
            new, nt, r = _solid_jobs(jf, a, b, cur[a], cur[b].with_occupancy(src), delta)
            jobs += new
            reach = max(reach, r)
            ops.append({"kind": "pair", "target": a, "source": b, "samples": nt,
                        "motion_margin": delta * cur[a].pitch})
        if jobs:
            cur[a] = cur[a].with_occupancy(_splat_remove(cur[a], keep, jobs, reach))
        done += 1
    tick("checking bars")
    for i, sp in enumerate(cur):
        if not sp.occupancy.any():
            raise FabricationError(f"carving emptied the design space of link {i}; "
                                   "enlarge it or change the order", "empty-space")
    report = {
        "seconds": time.perf_counter() - t_start,
        "continuous_bound": "sweeps sampled at adaptive parameters so that every point moves "
                            "at most motion_margin between a time and its nearest sample "
                            "(Bernstein bound of the rational motion); removal reach = "
                            "motion_margin + source ball + 2 target half-diagonals",
        "max_motion_margin": delta * max(sp.pitch for sp in cur),
        "voxels": [int(sp.occupancy.sum()) for sp in cur],
        "pitch": [sp.pitch for sp in cur],
        "bar_kept": [_bar_kept(sp, segs[i], keep_radius, zones, i) for i, sp in enumerate(cur)],
        "operations": ops,
    }
    if progress is not None:
        progress(1.0, "carving done")
    return Carving(tuple(cur), tuple(zones), report)


def _pair_groups(pairs: Sequence[tuple[int, int]]) -> list[tuple[int, int | None, list[int]]]:
    """Consecutive pairs with the same target and the same shared joint (None: not adjacent)
    carved in one pass: ``(target, joint, sources)``. Sources are unchanged within a run."""
    out: list[tuple[int, int | None, list[int]]] = []
    for a, b in pairs:
        sj = _shared_joint(a, b)
        joint = None if sj is None else sj[0]
        if out and out[-1][0] == a and out[-1][1] == joint and joint is None:
            out[-1][2].append(b)
        else:
            out.append((a, joint, [b]))
    return out


def _bar_kept(sp: VoxelSpace, segs: np.ndarray, keep_radius: float,
              zones: Sequence[JointZone], i: int) -> float:
    """Fraction of the grid centres within ``keep_radius`` of the bars ``segs`` ``(n, 2, 3)``
    (outside the neighbours' joint-zone halves) that are still occupied."""
    box = np.zeros_like(sp.occupancy)
    box[_index_box(sp, segs.reshape(-1, 3), keep_radius)] = True
    core = np.zeros_like(box)
    c = sp.centers(box)
    core[box] = np.min([point_segment_distance(c, p0, p1) for p0, p1 in segs], 0) <= keep_radius
    near = sp.with_occupancy(core)
    core &= ~(_zone_mask(near, zones[i], True, False)
              | _zone_mask(near, zones[(i - 1) % 6], False, False))
    return float(np.mean(sp.occupancy[core])) if core.any() else 1.0
