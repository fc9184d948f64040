"""Certificate of a realization with an end-effector (paper Sec. 5.1): the pair rows it checks,
the result :class:`EndEffectorRealization` with its home geometry and JSON, and the
design-space radii over all rows.

The rows, exact checks added by the search of :mod:`realize_ee`: thin stage, the two bars
against the thin segments they do not touch and P against the segments of links 0, 1, 2, 4, 5
(:mod:`facecollide`); step 4, every pair of :data:`offsetting.OFFSET_PAIRS` without the dropped
bar ``S_3E_3`` (>= 2 rho), the bars ``S_3L``, ``RE_3`` against the other edges (>= 2 rho; like
consecutive bars, ``S_3L``/``S_2E_2`` and ``RE_3``/``S_4E_4`` are skipped) and P against every
other edge (>= ``ee_clearance``, default rho: no bar cylinder enters P). Edges fixed in link 3
(pins on ``A_2``, ``A_3``) are checked once at home. A closed P must not contain any other edge
(one point each, at home).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from paraloop_core.algebra import dq
from paraloop_core.linkage import loops
from paraloop_core.realization import certified
from paraloop_core.realization.certified import Realization
from paraloop_core.realization.collision import THIN_PAIRS
from paraloop_core.realization.endeffector import EndEffector
from paraloop_core.realization.offsetting import OFFSET_PAIRS, cyclic_distance

#: Part code of P in the pair tables.
MESH = -1


def _edge_link(e: int) -> int:
    """Link carrying edge e, relative to link 3: a pin takes the neighbour closer to 3."""
    i = e // 2
    return i if e % 2 == 0 else min((i, (i + 1) % 6), key=lambda j: cyclic_distance(3, j))


def _thin_rows() -> list[tuple[tuple[int, int], tuple[int, int], tuple[int, int]]]:
    """Thin stage rows ``(fixed part, moving segment, (link a, link b))``; points 0..5 are the
    thin vertices, 6 = L, 7 = R; a part ``(MESH, MESH)`` is P."""
    seg = {i: ((i - 1) % 6, i) for i in range(6)}
    rows = [(seg[i], seg[j], (i, j)) for i, j in THIN_PAIRS if 3 not in (i, j)]
    rows += [((2, 6), seg[j], (3, j)) for j in (0, 1, 4, 5)]  # V_2 L
    rows += [((7, 3), seg[j], (3, j)) for j in (0, 1, 2, 5)]  # R V_3
    return rows + [((MESH, MESH), seg[j], (3, j)) for j in (0, 1, 2, 4, 5)]


def _step4_rows() -> list[tuple[tuple[int, int], tuple[int, int], tuple[int, int], str]]:
    """Step-4 rows ``(fixed part, moving edge, (link a, link b), label)``; points 0..11 are
    ``S_0, E_0, ..., S_5, E_5``, 12 = L, 13 = R. Link a == b marks a pair static in link 3."""
    edge = {e: (e, (e + 1) % 12) for e in range(12)}
    name = {e: (f"S{e // 2}E{e // 2}" if e % 2 == 0 else f"E{e // 2}S{(e // 2 + 1) % 6}")
            for e in range(12)}
    rows = [(edge[e1], edge[e2], (la, lb), f"{name[e1]}-{name[e2]}")
            for e1, e2, la, lb in OFFSET_PAIRS.tolist() if 6 not in (e1, e2)]
    others = [e for e in range(12) if e != 6]
    for part, label, skip in (((6, 12), "S3L", (4, 5)), ((13, 7), "RE3", (7, 8))):
        rows += [(part, edge[e], (3, _edge_link(e)), f"{label}-{name[e]}")
                 for e in others if e not in skip]
    return rows + [((MESH, MESH), edge[e], (3, _edge_link(e)), f"P-{name[e]}") for e in others]


#: Thin stage rows, see :func:`_thin_rows`.
THIN_ROWS = _thin_rows()
#: Step-4 rows, see :func:`_step4_rows`: the kept base pairs first, then the end-effector rows.
STEP4_ROWS = _step4_rows()
#: The rows of :data:`offsetting.OFFSET_PAIRS` kept (without the bar ``S_3E_3``, edge 6).
BASE_PAIRS = OFFSET_PAIRS[~np.any(OFFSET_PAIRS[:, :2] == 6, axis=1)]
#: ``(rows,)``: the step-4 row is P against an edge.
IS_MESH = np.array([r[0][0] == MESH for r in STEP4_ROWS])
#: ``(rows,)``: the step-4 row is static in link 3 (checked once at home).
IS_STATIC = np.array([r[2][0] == r[2][1] for r in STEP4_ROWS])


@dataclass(frozen=True)
class EndEffectorRealization:
    """Bars and pins as a :class:`certified.Realization` (its ``pairs`` omit the dropped bar
    ``S_3E_3``), the attached ``effector``, and the certificate of the end-effector rows:
    ``ee_labels``, ``ee_links`` ``(N, 2)``, ``ee_distance``/``ee_t`` ``(N,)`` (exact minima over
    the cycle; ``ee_exact`` False where P's bounding sphere already gives a certified lower
    bound), ``ee_required`` ``(N,)`` (2 rho for bars, ``ee_clearance`` for P)."""

    realization: Realization
    effector: EndEffector
    ee_labels: tuple[str, ...]
    ee_links: np.ndarray
    ee_distance: np.ndarray
    ee_t: np.ndarray
    ee_exact: np.ndarray
    ee_required: np.ndarray

    def end_link(self) -> np.ndarray:
        """End-link path ``(4, 3)`` at home: ``S_3, L, R, E_3``."""
        pts, v = self.realization.points, self.effector.vertices
        return np.stack([pts[6], v[self.effector.L], v[self.effector.R], pts[7]])


def ee_segments(r: EndEffectorRealization) -> tuple[np.ndarray, np.ndarray]:
    """Home geometry of the certificate rows: fixed parts ``(N, 2, 3)`` in link 3 (NaN where
    the part is P) and the moving edges ``(N, 2, 3)`` (carried by ``ee_links[:, 1]``)."""
    pts = np.concatenate([r.realization.points, r.end_link()[1:3]])  # 12 = L, 13 = R
    rows = STEP4_ROWS[len(BASE_PAIRS):]
    fixed = np.array([pts[list(f)] if f[0] != MESH else np.full((2, 3), np.nan)
                      for f, _, _, _ in rows])
    return fixed, np.array([pts[list(m)] for _, m, _, _ in rows])


def effector_at(r: EndEffectorRealization, t: np.ndarray) -> np.ndarray:
    """Vertices of P ``(T, V, 3)`` at parameters ``t`` ``(T,)`` (base/world frame)."""
    pose = loops.link_poses(r.realization.joint_factors, t)[:, 3]
    return dq.transform_points(pose[:, None], r.effector.vertices[None])


def ee_to_dict(r: EndEffectorRealization) -> dict:
    """JSON-ready end-effector part of the result (``t`` null where the minimum is at home)."""
    e = r.effector
    return {
        "vertices": e.vertices.tolist(), "faces": e.faces.tolist(), "L": e.L, "R": e.R,
        "closed": e.closed, "end_link": r.end_link().tolist(),
        "pairs": [{"label": lab, "links": [int(a), int(b)], "min_distance": float(dist),
                   "t": None if np.isinf(t) else float(t), "exact": bool(ex),
                   "required": float(req)}
                  for lab, (a, b), dist, t, ex, req in zip(
                      r.ee_labels, r.ee_links, r.ee_distance, r.ee_t, r.ee_exact,
                      r.ee_required, strict=True)],
        "min_clearance": float(np.min(r.ee_distance - r.ee_required)),
    }


def _bar_of(part: tuple[int, int]) -> int:
    """Link whose bar ``part`` is (``S_3L``, ``RE_3`` count for link 3), -1 for pins and P."""
    if part in ((6, 12), (13, 7)):
        return 3
    return part[0] // 2 if part[0] >= 0 and part[0] % 2 == 0 and part[1] == part[0] + 1 else -1


_ROW_BARS = np.array([(_bar_of(f), _bar_of(m)) for f, m, _, _ in STEP4_ROWS])  # (rows, 2)


def design_space_radii(dist: np.ndarray, rho: float) -> np.ndarray:
    """Sec. 5.2 radii ``(6,)`` over all step-4 rows (:func:`certified.design_space_radii`): bar
    vs bar splits D evenly, a bar keeps ``D - rho`` from a pin and ``D`` from P."""
    return certified.design_space_radii(dist, rho, _ROW_BARS, IS_MESH)
