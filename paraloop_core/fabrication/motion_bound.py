"""Rigorous continuous-motion bound of a relative link motion (used by carving, grounding and
verification).

**Continuous-motion bound** (:func:`motion_bound`). Write ``theta = pi (u - 1/2)`` and
``Q(theta) = cos(theta)^k R(tan theta)`` for the relative motion ``R`` of degree k: each
coordinate of ``Q`` is a trigonometric polynomial of degree k (same pose as ``R(t)``). With
``P`` its primal part, the angular velocity is ``w = 2 vec(P' P~) / |P|^2`` and a reference point
``c`` moves with ``X' = (N' B - N B') / B^2`` (``N`` numerator of ``R(c)``, ``B = |P|^2``); the
numerators are trigonometric polynomials of degree ``2k`` and ``4k``. Bernstein's inequality
``max|T'| <= deg max|T|`` (valid for vector-valued T) bounds every numerator on a cell of width
``h_c`` about a sample by ``|T(sample)| + (h_c/2) deg max|T|`` and ``B >= b_lo = B(sample) -
(h_c/2) 2k max B`` (so ``B^2 >= b_lo^2``), where ``max|T| <= max_samples|T| / (1 - deg h_c/2)``.
Hence any point within ``radius`` of ``c`` moves at most ``omega * radius + speed`` per unit
theta inside each cell: an upper bound, never an estimate. Integrating it gives how far such
a point can move between time samples; sweeps are dilated by that distance, so carving is
collision-free for the continuous motion.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from paraloop_core.algebra import dq
from paraloop_core.errors import FabricationError
from paraloop_core.linkage import loops


@dataclass(frozen=True)
class MotionBound:
    """Per-cell speed bounds of one relative motion over the cycle (``theta`` in
    ``[-pi/2, pi/2)``, cells of equal width): ``omega`` ``(K,)`` bounds the angular speed,
    ``speed`` ``(K,)`` the speed of ``center`` ``(3,)`` (home frame of the moving link), both per
    unit theta (multiply by pi for per unit u)."""

    omega: np.ndarray
    speed: np.ndarray
    center: np.ndarray

    def rate(self, radius: float) -> np.ndarray:
        """Speed bound ``(K,)`` per unit theta for all points within ``radius`` of ``center``."""
        return self.omega * radius + self.speed

    def cumulative(self, radius: float) -> tuple[np.ndarray, np.ndarray]:
        """Cell edges ``(K+1,)`` in theta and the integrated bound ``(K+1,)`` at them."""
        k = self.omega.size
        edges = np.linspace(-np.pi / 2, np.pi / 2, k + 1)
        return edges, np.concatenate([[0.0], np.cumsum(self.rate(radius) * (np.pi / k))])


def _trig(c: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``Q(theta)`` and ``Q'(theta)`` ``(T, 8)`` for a polynomial ``(k+1, 8)`` (see module)."""
    k = c.shape[0] - 1
    s, co = np.sin(theta)[:, None], np.cos(theta)[:, None]
    q = np.zeros(theta.shape + (8,))
    dq_ = np.zeros_like(q)
    for m in range(k + 1):  # tiny degree
        q += s**m * co ** (k - m) * c[m]
        d = m * s ** max(m - 1, 0) * co ** (k - m + 1) if m > 0 else 0.0
        if m < k:
            d = d - (k - m) * s ** (m + 1) * co ** (k - m - 1)
        dq_ += d * c[m]
    return q, dq_


def motion_bound(joint_factors: np.ndarray, i: int, j: int, center: np.ndarray,
                 cells: int = 4096) -> MotionBound:
    """Rigorous speed bounds of link j moving in link i's home frame (module docstring).

    ``center`` ``(3,)`` is a point of link j (home frame, design units). Cells double until the
    norm ``|P|^2`` is bounded away from zero on every cell."""
    c = loops.relative_motion(np.asarray(joint_factors, float), i, j)
    k = c.shape[0] - 1
    x = np.concatenate([[0.0], np.asarray(center, float)])
    while True:
        h = np.pi / cells
        th = -np.pi / 2 + (np.arange(cells) + 0.5) * h
        q, qd = _trig(c, th)
        p, d, pd, dd = q[:, :4], q[:, 4:], qd[:, :4], qd[:, 4:]
        pc, pdc = dq.qconj(p), dq.qconj(pd)
        b = np.sum(p * p, -1)
        bd = 2.0 * np.sum(p * pd, -1)
        aw = 2.0 * np.linalg.norm(dq.qmul(pd, pc)[:, 1:], axis=-1)
        n = (dq.qmul(dq.qmul(p, x), pc) + 2.0 * dq.qmul(d, pc))[:, 1:]
        nd = (dq.qmul(dq.qmul(pd, x), pc) + dq.qmul(dq.qmul(p, x), pdc)
              + 2.0 * dq.qmul(dd, pc) + 2.0 * dq.qmul(d, pdc))[:, 1:]
        nv = np.linalg.norm(nd * b[:, None] - n * bd[:, None], axis=-1)

        def gmax(v: np.ndarray, deg: int, h: float = h) -> float:
            return float(np.max(v)) / (1.0 - deg * h / 2)  # Bernstein + sampling

        if 4 * k * h / 2 < 0.5:
            mb, ma, mn = gmax(b, 2 * k), gmax(aw, 2 * k), gmax(nv, 4 * k)
            b_lo = b - h / 2 * 2 * k * mb  # B >= b_lo on the cell, so B^2 >= b_lo^2
            if np.all(b_lo > 0):
                omega = (aw + h / 2 * 2 * k * ma) / b_lo
                speed = (nv + h / 2 * 4 * k * mn) / b_lo**2
                return MotionBound(omega, speed, np.asarray(center, float))
        if cells >= 1 << 20:
            raise FabricationError(
                f"relative motion of links {i}, {j} passes too close to a singular pose to "
                "bound its speed", "bad-parameters")
        cells *= 4


def _lam(edges: np.ndarray, cum: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Integrated bound at any theta, extended periodically (period pi)."""
    turns = np.floor((theta + np.pi / 2) / np.pi)
    return np.interp(theta - turns * np.pi, edges, cum) + turns * cum[-1]


def displacement_bounds(mb: MotionBound, radius: float, u: np.ndarray) -> np.ndarray:
    """For sorted samples ``u`` ``(T,)`` in ``[0, 1)``: ``(T,)`` bound on how far any point
    within ``radius`` of ``mb.center`` moves between sample k and any time closer (in u) to
    sample k than to its neighbours (cyclic): centre path plus ``min(radius * turned angle,
    2 radius)`` (a rotation moves a point by at most the chord, at most the diameter)."""
    th = np.pi * (np.asarray(u, float) - 0.5)
    nxt = np.append(th[1:], th[0] + np.pi)
    prv = np.insert(th[:-1], 0, th[-1] - np.pi)

    def halves(bound: MotionBound) -> np.ndarray:  # (2, T): integrated bound back / forward
        edges, cum = bound.cumulative(radius)
        lam = _lam(edges, cum, th)
        return np.stack([lam - _lam(edges, cum, (th + prv) / 2),
                         _lam(edges, cum, (th + nxt) / 2) - lam])

    zero = np.zeros_like(mb.omega)
    move = halves(MotionBound(zero, mb.speed, mb.center)) + \
        np.minimum(halves(MotionBound(mb.omega, zero, mb.center)), 2.0 * radius)
    return move.max(axis=0)


def adaptive_params(mb: MotionBound, radius: float, delta: float) -> np.ndarray:
    """Samples ``u`` ``(T,)`` such that every time is within moved distance ``delta`` of a
    sample, for all points within ``radius`` of ``mb.center`` (equal steps of the bound)."""
    edges, cum = mb.cumulative(radius)
    n = max(int(np.ceil(cum[-1] / (2.0 * delta))), 8)
    th = np.interp((np.arange(n) + 0.5) * cum[-1] / n, cum, edges)
    return th / np.pi + 0.5
