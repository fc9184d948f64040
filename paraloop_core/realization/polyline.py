"""Initial closed polyline on the six axes (paper eq. 11, MATH §10).

Axis ``A_i`` at home (t = inf, base frame) is ``q_i + s u_i`` with foot point ``q_i`` (closest
point to the origin) and unit direction ``u_i`` from :func:`loops.factor_axes`. The polyline
``E_i = q_i + s_i u_i`` minimizes ``sum_i |E_i - E_{i+1}|^2`` (indices mod 6) with user-fixed
``s_i`` held; the normal equations are a 6x6 cyclic linear system in the free ``s_i``.
Positions ``s`` are signed, in design units, measured from the foot point along ``+u_i``.
"""

from __future__ import annotations

import numpy as np

from paraloop_core.errors import RealizationError
from paraloop_core.linkage import loops
from paraloop_core.tolerance import TOL


def axis_frames(joint_factors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Foot points ``q`` ``(..., 6, 3)`` and unit directions ``u`` ``(..., 6, 3)`` of the axes."""
    jf = np.asarray(joint_factors, dtype=np.float64)
    pn = np.linalg.norm(jf[..., 1:4], axis=-1)
    if np.any(pn <= TOL.zero * (1.0 + np.abs(jf).max(axis=-1))):
        raise RealizationError(
            "a joint factor has no rotation part (zero axis direction): not a revolute joint",
            "singular-loop",
        )
    ax = loops.factor_axes(jf)
    u, m = ax[..., :3], ax[..., 3:]
    return np.cross(u, m), u


def polyline_length(points: np.ndarray) -> np.ndarray:
    """Length ``(...)`` of closed polylines ``(..., n, 3)`` (closing edge included)."""
    return np.sum(np.linalg.norm(points - np.roll(points, 1, axis=-2), axis=-1), axis=-1)


def shortest_polyline(
    joint_factors: np.ndarray, fixed: dict[int, float] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 11: positions ``s`` ``(6,)`` and vertices ``E`` ``(6, 3)`` of the shortest (least
    squares) closed polyline with ``E_i`` on ``A_i``; ``fixed`` maps i to a held ``s_i``.

    Raises :class:`RealizationError` (``bad-parameters``) for bad ``fixed`` entries and
    (``singular-loop``) when the free positions are not unique (e.g. all axes parallel).
    """
    jf = np.asarray(joint_factors, dtype=np.float64)
    if jf.shape != (6, 8) or not np.all(np.isfinite(jf)):
        raise RealizationError(f"joint factors must be finite (6, 8), got {jf.shape}",
                               "bad-parameters")
    fixed = dict(fixed or {})
    for i, v in fixed.items():
        if not (isinstance(i, (int, np.integer)) and 0 <= i < 6):
            raise RealizationError(f"fixed vertex index must be 0..5, got {i!r}", "bad-parameters",
                                   "fixed")
        if not np.isfinite(v):
            raise RealizationError(f"fixed position of E_{i} must be finite, got {v!r}",
                                   "bad-parameters", "fixed")
    q, u = axis_frames(jf)
    nxt, prv = np.roll(np.arange(6), -1), np.roll(np.arange(6), 1)
    a = 2.0 * np.eye(6)
    a[np.arange(6), nxt] -= np.sum(u * u[nxt], -1)
    a[np.arange(6), prv] -= np.sum(u * u[prv], -1)
    b = np.sum(u * (q[nxt] + q[prv] - 2.0 * q), -1)
    s = np.zeros(6)
    held = np.array(sorted(fixed), dtype=int)
    s[held] = [float(fixed[i]) for i in held]
    free = np.setdiff1d(np.arange(6), held)
    if free.size:
        sub = a[np.ix_(free, free)]
        # The system is a weighted cycle Laplacian: singular iff a free chain can slide along
        # parallel axes without changing any edge (e.g. all axes parallel, nothing fixed).
        if np.linalg.cond(sub) > 1.0 / TOL.singular:
            raise RealizationError(
                "the shortest polyline is not unique: the free axes are (nearly) parallel; "
                "fix a vertex on one of them",
                "singular-loop",
            )
        s[free] = np.linalg.solve(sub, b[free] - a[np.ix_(free, held)] @ s[held])
    return s, q + s[:, None] * u
