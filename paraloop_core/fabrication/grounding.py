"""Loop grounding (paper Sec. 5.2, Fig. 10): a column from one link to the ground.

Any link g may be the grounded one (it then stands still and the others move relative to it;
the paper grounds the base link 0). The column extends one of its two axes (``A_{g-1}`` from
``S_g`` or ``A_g`` from ``E_g``) from the joint point, away from the neighbouring link, down to
the ground plane ``z = ground_z`` (default: the lowest point of the linkage swept about link g
minus a margin), and stands on a round foot. It is coaxial with the joint it extends, so
against the adjacent link's hub (a solid of revolution about the same axis on the far side of
the bosses' split) it is clear for every joint angle by construction; the moving links' bars
and the other hubs (as capsules) are checked over the cycle at ``samples`` parameters with the
continuous bound of :mod:`motion_bound`: a certified distance is ``min over samples (distance -
displacement bound)``, positive means collision-free. Every (link, axis) that points down is
tried and the largest certified clearance wins. All lengths in design units, the home
configuration (where every link frame is the base frame), z up.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from paraloop_core.algebra import dq, poly
from paraloop_core.errors import FabricationError
from paraloop_core.linkage import loops
from paraloop_core.realization.clearance import segment_distance
from paraloop_core.realization.motion_bound import sound_displacement_bounds, try_motion_bound


@dataclass(frozen=True)
class Grounding:
    """Column of the grounded ``link``: ``top`` -> ``bottom`` (on the ground plane) of
    ``radius`` along axis ``axis``;
    foot of ``foot_radius`` x ``foot_height`` on ``z = ground_z``; ``clearance``: certified
    minimum distance to the moving links over the continuous cycle, ``sampled_clearance`` the
    minimum at the samples (design units)."""

    link: int
    axis: int
    top: np.ndarray
    bottom: np.ndarray
    radius: float
    ground_z: float
    foot_radius: float
    foot_height: float
    clearance: float
    sampled_clearance: float


def link_capsules(points: np.ndarray, bar_radius: float, hub_radius: float,
                  hub_extent: float, end_link: Sequence[tuple] | None = None,
                  splits: Sequence[float] | None = None,
                  ) -> list[list[tuple[np.ndarray, np.ndarray, float, int]]]:
    """Skeleton capsules per link (home frame): the bar and the two hubs along the pins, each
    hub from the bosses' split (fraction ``splits[i]`` of pin i from ``E_i``, default the
    midpoint; ``parts.Zone.split``) to ``hub_extent`` beyond the joint point; tagged with the
    joint (-1 for the bar). ``points`` ``(12, 3)``; ``end_link``: capsules ``(p0, p1,
    radius)`` replacing link 3's bar (bars ``S_3 L``, ``R E_3`` and the end-effector P)."""
    out: list[list[tuple[np.ndarray, np.ndarray, float, int]]] = [[] for _ in range(6)]
    for i in range(6):
        if i == 3 and end_link is not None:
            out[i] += [(p0, p1, r, -1) for p0, p1, r in end_link]
        else:
            out[i].append((points[2 * i], points[2 * i + 1], bar_radius, -1))
        e, s = points[2 * i + 1], points[(2 * i + 2) % 12]
        d = s - e
        w = d / n if (n := np.linalg.norm(d)) > 0 else np.zeros(3)
        mid = e + (0.5 if splits is None else splits[i]) * d
        out[i].append((e - hub_extent * w, mid, hub_radius, i))
        out[(i + 1) % 6].append((mid, s + hub_extent * w, hub_radius, i))
    return out


def _poses_about(jf: np.ndarray, link: int, u: np.ndarray) -> np.ndarray:
    """``(T, 6, 4, 4)``: every link's pose in the frame of ``link`` at parameters ``u``."""
    poses = dq.to_matrix(loops.link_poses(jf, poly.param_to_t(u)))
    return np.linalg.inv(poses[:, link, None]) @ poses


def _column_gaps(jf: np.ndarray, caps: list, top: np.ndarray, bottom: np.ndarray, r: float,
                 link: int, axis: int, u: np.ndarray, poses: np.ndarray) -> tuple[float, float]:
    """(certified, sampled) distance between the column capsule of ``link`` and the others;
    ``poses`` (:func:`_poses_about`) at ``u``."""
    best_c, best_s = np.inf, np.inf
    for j in range(6):
        if j == link:
            continue
        sel = [c for c in caps[j] if c[3] != axis]  # the coaxial hub is clear by construction
        seg = np.array([[c[0], c[1]] for c in sel])  # (n, 2, 3)
        rad = np.array([c[2] for c in sel])
        moved = np.einsum("tij,nkj->tnki", poses[:, j, :3, :3], seg) + \
            poses[:, j, None, None, :3, 3]
        dist = segment_distance(top, bottom, moved[..., 0, :], moved[..., 1, :]) - rad - r
        gap = dist.min(axis=1)
        center = 0.5 * (seg.reshape(-1, 3).min(0) + seg.reshape(-1, 3).max(0))
        reach = float(np.max(np.linalg.norm(seg.reshape(-1, 3) - center, axis=1)))
        delta = sound_displacement_bounds(jf, link, j, center, reach, u,
                                          try_motion_bound(jf, link, j, center))
        best_c = min(best_c, float(np.min(gap - delta)))
        best_s = min(best_s, float(gap.min()))
    return best_c, best_s


def ground_column(joint_factors: np.ndarray, points: np.ndarray, *, bar_radius: float,
                  hub_radius: float, hub_extent: float, column_radius: float | None = None,
                  link: int | None = None, axis: int | None = None,
                  ground_z: float | None = None, margin: float | None = None,
                  samples: int = 720, end_link: Sequence[tuple] | None = None,
                  splits: Sequence[float] | None = None, pin_heads: bool = False) -> Grounding:
    """Grounding column (module docstring) of ``link`` along ``axis`` (each default: every one
    that works, the largest certified clearance wins; an axis must be one of the link's two).
    ``end_link`` and ``splits`` as in :func:`link_capsules` (so the ground lies below the
    end-effector too). ``pin_heads`` (print-in-place): the head of joint g-1's pin sits beyond
    link g's boss on ``A_{g-1}``, so only ``A_g`` is free.

    Raises :class:`FabricationError` (``bad-parameters``) for bad sizes and (``grounding``)
    when no axis points down to the ground or every column collides with a moving link.
    """
    jf = np.asarray(joint_factors, float)
    pts = np.asarray(points, float)
    r = 0.8 * hub_radius if column_radius is None else column_radius
    links = range(6) if link is None else [link]
    if not all(np.isfinite(v) and v > 0 for v in (bar_radius, hub_radius, r)) or \
            hub_extent < 0 or samples < 8 or link not in (None, *range(6)) or \
            axis not in (None, *range(6)):
        raise FabricationError("grounding needs radii > 0, hub_extent >= 0, samples >= 8, a "
                               "link and an axis in 0..5", "bad-parameters")
    sides = (0,) if pin_heads else (0, 1)
    candidates = [(g, (g - k) % 6) for g in links for k in sides if axis in (None, (g - k) % 6)]
    if not candidates:
        raise FabricationError(f"no grounding on axis A_{axis} for link {link}: link g turns "
                               "about A_{g-1} and A_g (print-in-place: A_g only)",
                               "bad-parameters")
    foot_h = r
    margin = foot_h + 2.0 * r if margin is None else margin
    caps = link_capsules(pts, bar_radius, hub_radius, hub_extent, end_link, splits)
    u = np.arange(samples) / samples
    tried, best = [], None
    for g in sorted({g for g, _ in candidates}):
        poses = _poses_about(jf, g, u)  # (T, 6, 4, 4)
        gz = _ground_below(jf, caps, g, u, poses) - margin if ground_z is None else ground_z
        for ax in [a for h, a in candidates if h == g]:
            # link g holds E_g on A_g (neighbour S_{g+1}) and S_g on A_{g-1} (neighbour E_{g-1})
            top = pts[2 * g + 1] if ax == g else pts[2 * g]
            away = top - (pts[(2 * g + 2) % 12] if ax == g else pts[(2 * g - 1) % 12])
            if np.linalg.norm(away) < 1e-12:
                away = loops.factor_axes(jf)[ax, :3]
                away = -away if away[2] > 0 else away
            away = away / np.linalg.norm(away)
            if away[2] > -0.2 or top[2] <= gz:
                tried.append(f"link {g} on A_{ax}: the axis does not point down to the ground")
                continue
            bottom = top + (gz - top[2]) / away[2] * away
            start = top + r * away  # the first r lies inside the link's own hub
            cert, sampled = _column_gaps(jf, caps, start, bottom, r, g, ax, u, poses)
            if cert <= 0:
                tried.append(f"link {g} on A_{ax}: the column comes within {sampled:.4g} of a "
                             f"moving link (certified {cert:.4g})")
            elif best is None or cert > best.clearance:
                best = Grounding(g, ax, top, bottom, r, float(gz), 3.0 * r, foot_h, cert,
                                 sampled)
    if best is None:
        raise FabricationError("no collision-free grounding column: " + "; ".join(tried),
                               "grounding")
    return best


def _ground_below(jf: np.ndarray, caps: list, link: int, u: np.ndarray,
                  poses: np.ndarray) -> float:
    """Lowest point (z) of the linkage swept about ``link`` over the cycle (``poses`` at
    ``u``): sampled, made safe by the motion between samples."""
    lowest = np.inf
    for j in range(6):
        ends = np.array([p for c in caps[j] for p in c[:2]])
        rad = np.repeat([c[2] for c in caps[j]], 2)  # lowest point of each capsule
        z = np.einsum("tj,nj->tn", poses[:, j, 2, :3], ends) + poses[:, j, None, 2, 3] - rad
        step = 0.0
        if j != link:
            center = 0.5 * (ends.min(0) + ends.max(0))
            reach = float(np.max(np.linalg.norm(ends - center, axis=1)))
            step = float(sound_displacement_bounds(jf, link, j, center, reach, u,
                                                   try_motion_bound(jf, link, j, center)).max())
        lowest = min(lowest, float(z.min()) - step)
    return lowest
