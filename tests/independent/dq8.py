"""Minimal dual-quaternion kernel, written independently of ``paraloop_core``.

Convention (MATH.md section 1): a DQ is ``[p0, p1, p2, p3, d0, d1, d2, d3]`` = ``P + eps D``;
a pose moves a point x by ``x -> (P x P~ + 2 D P~) / |P|^2`` (vector part). All functions
broadcast over leading axes.
"""

from __future__ import annotations

import numpy as np


def qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Quaternion product ``(..., 4) x (..., 4) -> (..., 4)`` (scalar first)."""
    a0, a1, a2, a3 = np.moveaxis(a, -1, 0)
    b0, b1, b2, b3 = np.moveaxis(b, -1, 0)
    return np.stack([
        a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
        a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
        a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
        a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0,
    ], axis=-1)


def qconj(a: np.ndarray) -> np.ndarray:
    """Quaternion conjugate ``(..., 4)``."""
    return a * np.array([1.0, -1.0, -1.0, -1.0])


def dmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """DQ product ``(..., 8) x (..., 8) -> (..., 8)``: ``P1 P2 + eps (P1 D2 + D1 P2)``."""
    pa, da, pb, db = a[..., :4], a[..., 4:], b[..., :4], b[..., 4:]
    return np.concatenate([qmul(pa, pb), qmul(pa, db) + qmul(da, pb)], axis=-1)


def dconj(a: np.ndarray) -> np.ndarray:
    """DQ conjugate ``Q~ = P~ + eps D~`` ``(..., 8)``."""
    return np.concatenate([qconj(a[..., :4]), qconj(a[..., 4:])], axis=-1)


def act(q: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Point action of poses ``q`` ``(..., 8)`` on points ``x`` ``(..., 3)`` -> ``(..., 3)``."""
    p, d = q[..., :4], q[..., 4:]
    xq = np.concatenate([np.zeros(x.shape[:-1] + (1,)), x], axis=-1)
    pc = qconj(p)
    num = qmul(qmul(p, xq), pc) + 2.0 * qmul(d, pc)
    return num[..., 1:] / np.sum(p * p, axis=-1, keepdims=True)


def pose_from_pos_wxyz(pos: np.ndarray, wxyz: np.ndarray) -> np.ndarray:
    """Unit pose ``(..., 8)``: rotation ``wxyz`` (normalized) then translation ``pos``."""
    p = np.asarray(wxyz, float) / np.linalg.norm(wxyz, axis=-1, keepdims=True)
    tq = np.concatenate([np.zeros(np.shape(pos)[:-1] + (1,)), pos], axis=-1)
    return np.concatenate([p, 0.5 * qmul(tq, p)], axis=-1)


def pos_wxyz(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position ``(..., 3)`` and unit ``wxyz`` ``(..., 4)`` of poses ``(..., 8)``."""
    p, d = q[..., :4], q[..., 4:]
    n2 = np.sum(p * p, axis=-1, keepdims=True)
    pos = 2.0 * qmul(d, qconj(p))[..., 1:] / n2
    return pos, p / np.sqrt(n2)


def linear_at(h: np.ndarray, c: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Homogeneous value of ``t - h`` at ``t = c / s``: ``c * 1 - s * h`` -> ``(T, ..., 8)``
    for ``h`` ``(..., 8)`` and ``c, s`` ``(T,)`` (``s = 0`` is t = inf, the identity)."""
    one = np.zeros(h.shape)
    one[..., 0] = 1.0
    shape = (-1,) + (1,) * h.ndim
    return np.reshape(c, shape) * one - np.reshape(s, shape) * h


def poly_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Product of DQ polynomials ``(m+1, 8) x (n+1, 8) -> (m+n+1, 8)`` (ascending powers)."""
    out = np.zeros((len(a) + len(b) - 1, 8))
    for i in range(len(a)):
        for j in range(len(b)):
            out[i + j] += dmul(a[i], b[j])
    return out


def from_factors(hs: np.ndarray) -> np.ndarray:
    """Monic polynomial ``(n+1, 8)`` of ``(t - h_0)...(t - h_{n-1})`` for ``hs`` ``(n, 8)``."""
    one = np.eye(8)[0]
    out = np.array([one])
    for h in hs:
        out = poly_mul(out, np.array([-h, one]))
    return out


def homogeneous(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Well-scaled homogeneous pair ``(c, s)`` with ``t = c / s`` (|t| <= 1: (t, 1); else
    (1, 1/t); inf -> (1, 0)) for ``t`` ``(T,)``."""
    t = np.asarray(t, float)
    big = ~(np.abs(t) <= 1.0)
    with np.errstate(divide="ignore"):
        inv = np.where(np.isinf(t), 0.0, 1.0 / np.where(big, t, 1.0))
    return np.where(big, 1.0, t), np.where(big, inv, 1.0)


def rigid(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation matrices ``(..., 3, 3)`` and translations ``(..., 3)`` of poses ``(..., 8)``
    (homogeneous: any nonzero primal norm), so that ``act(q, x) = R x + tr``."""
    p, d = q[..., :4], q[..., 4:]
    n2 = np.sum(p * p, axis=-1)[..., None, None]
    w, x, y, z = np.moveaxis(p, -1, 0)
    rot = np.stack([
        np.stack([w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z], -1),
    ], axis=-2) / n2
    tr = 2.0 * qmul(d, qconj(p))[..., 1:] / n2[..., 0]
    return rot, tr


def poly_at(coef: np.ndarray, c: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Homogeneous value ``sum_j coef_j c^j s^(n-j)`` ``(T, 8)`` of ``coef`` ``(n+1, 8)`` at
    ``t = c / s`` (``c, s`` ``(T,)``)."""
    n = len(coef) - 1
    j = np.arange(n + 1)
    w = np.asarray(c, float)[:, None] ** j * np.asarray(s, float)[:, None] ** (n - j)
    return w @ coef
