"""Link design spaces carved as in paper Sec. 5.2, with a rigorous continuous-motion bound.

The spaces are voxel spaces of :mod:`voxelspace` (frames, units and the *region* that all
guarantees below are about); this module holds the joint zones and the carving itself: clip at
the joint zones, wire cutting by the other bars, the sweeps of fixed solids and the pairwise
swept differences, each a removal by :mod:`sweep`.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from paraloop_core.errors import FabricationError
from paraloop_core.fabrication.progress import Progress
from paraloop_core.fabrication.sweep import solid_jobs, splat_remove, sweep_jobs
from paraloop_core.fabrication.voxelspace import VoxelSpace, check_points, point_segment_distance
from paraloop_core.linkage import loops


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


#: Default carving order: (target, source) pairs, the base link carved first.
DEFAULT_ORDER = tuple((a, b) for a in range(6) for b in range(a + 1, 6))


@dataclass(frozen=True)
class Carving:
    """Carved spaces (one per link), the joint zones used and a JSON-ready ``report``."""

    spaces: tuple[VoxelSpace, ...]
    zones: tuple[JointZone, ...]
    report: dict


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
    pts = check_points(points)
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
    if len(pairs) != 15:  # a pair left out would not be carved: no collision-freedom claim
        raise FabricationError(f"order must list all 15 pairs of the six links once, got "
                               f"{len(pairs)}", "bad-parameters")
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
                new, nt = sweep_jobs(jf, a, b, sp, seg, seg[:0], np.eye(4), delta * sp.pitch)
                jobs += new
                ops.append({"kind": "wire", "target": a, "source": b, "samples": nt})
        keep = prot[(a, a)] | prot[(a, (a - 1) % 6)]
        reach = delta * sp.pitch + sigma / 2 + extra + 2 * sp.half_diagonal
        cur[a] = sp.with_occupancy(splat_remove(sp, keep, jobs, reach))
        done += 1
    for f, solid in fixed:
        tick(f"carving the other links by the sweep of link {f}'s fixed solid")
        for a in (x for x in range(6) if x != f):
            jobs, nt, reach = solid_jobs(jf, a, f, cur[a], solid, delta)
            cur[a] = cur[a].with_occupancy(
                splat_remove(cur[a], np.zeros_like(cur[a].occupancy), jobs, reach))
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
            new, nt, r = solid_jobs(jf, a, b, cur[a], cur[b].with_occupancy(src), delta)
            jobs += new
            reach = max(reach, r)
            ops.append({"kind": "pair", "target": a, "source": b, "samples": nt,
                        "motion_margin": delta * cur[a].pitch})
        if jobs:
            cur[a] = cur[a].with_occupancy(splat_remove(cur[a], keep, jobs, reach))
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
