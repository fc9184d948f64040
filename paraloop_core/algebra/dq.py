"""Dual quaternions as batched numpy arrays.

Convention (the single place it is stated; MATH.md section 1, the paper's eq. 13/14):

* A dual quaternion is a float64 array ``(..., 8)`` ordered
  ``[p0, p1, p2, p3, d0, d1, d2, d3]`` meaning ``P + eps D`` with primal ``P`` and dual ``D``,
  each a ``wxyz`` quaternion (scalar first), ``eps**2 = 0``.
* Points act by ``x -> (P x P~ + 2 D P~) / |P|^2`` (vector part), i.e. for a unit pose
  ``R = rot(P)`` and translation ``t = 2 vec(D P~)``, ``D = t P / 2``. Composition
  ``(Q1 Q2)(x) = Q1(Q2(x))``: the right factor acts first.
* Lines are Plücker arrays ``(..., 6)`` = ``(direction l, moment m)`` with ``m = x cross l`` for
  any point ``x`` on the line; they act by ``L -> Q L Q~ / |P|^2``.
* Poses are homogeneous: ``Q`` and ``lambda Q`` (real ``lambda != 0``) are the same displacement.

Other tools (``biquaternion_py``, ``rational_linkages``) use the opposite dual sign; never mix.
"""

from __future__ import annotations

import numpy as np

from paraloop_core.tolerance import TOL

IDENTITY = np.array([1.0, 0, 0, 0, 0, 0, 0, 0])


def _as_dq(q: np.ndarray, name: str = "q") -> np.ndarray:
    q = np.asarray(q, dtype=np.float64)
    if q.shape[-1:] != (8,):
        raise ValueError(f"{name} must have shape (..., 8), got {q.shape}")
    return q


def _quaternion_table() -> np.ndarray:
    """Structure constants ``T[i, j, k]``: ``(a b)_i = sum_jk T[i, j, k] a_j b_k``."""
    t = np.zeros((4, 4, 4))
    sign = {(0, 0): (0, 1), (0, 1): (1, 1), (0, 2): (2, 1), (0, 3): (3, 1),
            (1, 0): (1, 1), (1, 1): (0, -1), (1, 2): (3, 1), (1, 3): (2, -1),
            (2, 0): (2, 1), (2, 1): (3, -1), (2, 2): (0, -1), (2, 3): (1, 1),
            (3, 0): (3, 1), (3, 1): (2, 1), (3, 2): (1, -1), (3, 3): (0, -1)}
    for (j, k), (i, s) in sign.items():
        t[i, j, k] = s
    return t


_QTABLE = _quaternion_table()


def _dq_right_table() -> np.ndarray:
    """:data:`RIGHT`: entry ``[k, 8 j + i]`` is the coefficient of ``b_k`` in ``(a b)_i`` per
    ``a_j`` (primal ``pa pb``, dual ``pa db + da pb``)."""
    t = np.zeros((8, 8, 8))  # [k, j, i]
    t[:4, :4, :4] = t[4:, :4, 4:] = t[:4, 4:, 4:] = _QTABLE.transpose(2, 1, 0)
    return t.reshape(8, 64)


#: Right multiplication as a matrix: ``a b = a @ (b @ RIGHT).reshape(8, 8)`` (a faster
#: product for batched kernels; it rounds differently from :func:`mul`, whose exact rounding
#: the chaotic motion fits rely on).
RIGHT = _dq_right_table()
#: Below this many elements one einsum call beats eight sliced ufunc passes (call overhead
#: dominates small inputs, memory traffic large ones); both compute the same product.
_SMALL = 4096


def right_matrix(b: np.ndarray, table: np.ndarray = RIGHT) -> np.ndarray:
    """Matrices ``(..., 8, k)`` of right multiplication by dual quaternions ``b`` ``(..., 8)``,
    ``a b = a @ right_matrix(b)`` (``table`` :data:`RIGHT` or a column selection of it)."""
    return (b @ table).reshape(b.shape[:-1] + (8, -1))


def qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Quaternion product of ``(..., 4)`` wxyz arrays (broadcasting)."""
    if a.size + b.size <= _SMALL:
        return np.einsum("ijk,...j,...k->...i", _QTABLE, a, b)
    a0, a1, a2, a3 = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    b0, b1, b2, b3 = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3
    out[..., 1] = a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2
    out[..., 2] = a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1
    out[..., 3] = a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0
    return out


def qconj(a: np.ndarray) -> np.ndarray:
    """Quaternion conjugate of ``(..., 4)``."""
    return a * np.array([1.0, -1.0, -1.0, -1.0])


def mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Dual-quaternion product ``(..., 8) x (..., 8) -> (..., 8)`` (broadcasting)."""
    pa, da = a[..., :4], a[..., 4:]
    pb, db = b[..., :4], b[..., 4:]
    return np.concatenate([qmul(pa, pb), qmul(pa, db) + qmul(da, pb)], axis=-1)


_CONJ = np.array([1.0, -1, -1, -1, 1, -1, -1, -1])
_EPS_CONJ = np.array([1.0, 1, 1, 1, -1, -1, -1, -1])


def conj(q: np.ndarray) -> np.ndarray:
    """Dual-quaternion conjugate ``P~ + eps D~`` (an anti-automorphism)."""
    return q * _CONJ


def eps_conj(q: np.ndarray) -> np.ndarray:
    """eps-conjugate ``P - eps D``."""
    return q * _EPS_CONJ


def norm(q: np.ndarray) -> np.ndarray:
    """``Q Q~ = |P|^2 + eps 2 (P.D)`` as a dual number ``(..., 2)``."""
    p, d = q[..., :4], q[..., 4:]
    return np.stack([(p * p).sum(-1), 2.0 * (p * d).sum(-1)], axis=-1)


def study_residual(q: np.ndarray) -> np.ndarray:
    """``P.D / |P|^2`` ``(...)``: zero iff ``q`` satisfies the Study condition (eq. 3)."""
    p, d = q[..., :4], q[..., 4:]
    return (p * d).sum(-1) / (p * p).sum(-1)


def inv(q: np.ndarray) -> np.ndarray:
    """Inverse ``q~ / (q q~)`` (``q q~ = n + eps 2 P.D`` is a central dual number), i.e.
    ``P^-1 - eps P^-1 D P^-1``; raises ValueError where ``P = 0``."""
    q = _as_dq(q)
    p, d = q[..., :4], q[..., 4:]
    n2 = (p * p).sum(-1, keepdims=True)
    if (n2 == 0.0).any():
        raise ValueError("dual quaternion with zero primal part is not invertible")
    c = q * (_CONJ / n2)
    c[..., 4:] -= c[..., :4] * (2.0 * (p * d).sum(-1, keepdims=True) / n2)
    return c


def study_project(q: np.ndarray) -> np.ndarray:
    """Eq. 5: ``D' = D - (P.D / |P|^2) P``, the orthogonal projection onto the Study quadric."""
    q = _as_dq(q)
    p, d = q[..., :4], q[..., 4:]
    s = (p * d).sum(-1, keepdims=True) / (p * p).sum(-1, keepdims=True)
    return np.concatenate([p, d - s * p], axis=-1)


def normalize(q: np.ndarray) -> np.ndarray:
    """Scale to ``|P| = 1`` with ``p0 >= 0`` (a canonical representative of the pose)."""
    q = _as_dq(q)
    n = np.sqrt((q[..., :4] ** 2).sum(-1, keepdims=True))
    sign = np.where(q[..., :1] < 0, -1.0, 1.0)
    return q * sign / n


def scale_lengths(q: np.ndarray, factor: float | np.ndarray) -> np.ndarray:
    """The same displacements ``(..., 8)`` in a length unit ``1 / factor`` times the old one
    (translations and moments times ``factor``): the dual part times ``factor``. Applies
    coefficient-wise to motion polynomials ``(..., n+1, 8)`` too."""
    q = _as_dq(q)
    return np.concatenate([q[..., :4], q[..., 4:] * np.asarray(factor, np.float64)[..., None]],
                          axis=-1)


def translation_of(q: np.ndarray) -> np.ndarray:
    """Translation ``(..., 3)`` of a (not necessarily unit) pose: ``2 vec(D P~) / |P|^2``."""
    p, d = q[..., :4], q[..., 4:]
    return 2.0 * qmul(d, qconj(p))[..., 1:] / (p * p).sum(-1, keepdims=True)


def rotation_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix ``(..., 3, 3)`` of the primal part (any nonzero scale)."""
    p = q[..., :4] / np.linalg.norm(q[..., :4], axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(p, -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=-2,
    )


def transform_points(q: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Apply poses ``(..., 8)`` to points ``(..., 3)`` (broadcasting): ``R x + t``."""
    q = np.asarray(q, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    p = q[..., :4]
    n2 = (p * p).sum(-1, keepdims=True)
    xq = np.concatenate([np.zeros(x.shape[:-1] + (1,)), x], axis=-1)
    rx = qmul(qmul(p, xq), qconj(p))[..., 1:]
    return (rx + 2.0 * qmul(q[..., 4:], qconj(p))[..., 1:]) / n2


def transform_lines(q: np.ndarray, lines: np.ndarray) -> np.ndarray:
    """Apply poses ``(..., 8)`` to Plücker lines ``(..., 6)``: ``Q L Q~ / |P|^2``."""
    lines = np.asarray(lines, dtype=np.float64)
    z = np.zeros(lines.shape[:-1] + (1,))
    ldq = np.concatenate([z, lines[..., :3], z, lines[..., 3:]], axis=-1)
    y = mul(mul(q, ldq), conj(q))
    n2 = (q[..., :4] ** 2).sum(-1, keepdims=True)
    return np.concatenate([y[..., 1:4], y[..., 5:8]], axis=-1) / n2


def from_pos_wxyz(position: np.ndarray, wxyz: np.ndarray) -> np.ndarray:
    """Unit pose ``(..., 8)`` from a position ``(..., 3)`` and a ``wxyz`` quaternion ``(..., 4)``.
    """
    position = np.asarray(position, dtype=np.float64)
    wxyz = np.asarray(wxyz, dtype=np.float64)
    if position.shape[-1:] != (3,) or wxyz.shape[-1:] != (4,):
        raise ValueError("position must be (..., 3) and wxyz (..., 4)")
    n = np.sqrt((wxyz * wxyz).sum(-1, keepdims=True))
    if not np.isfinite(n).all() or (n < TOL.zero).any():
        raise ValueError("wxyz quaternion must be finite and nonzero")
    p = wxyz / n
    tq = np.concatenate([np.zeros(position.shape[:-1] + (1,)), position], axis=-1)
    p, tq = np.broadcast_arrays(p, tq)
    return np.concatenate([p, 0.5 * qmul(tq, p)], axis=-1)


def to_pos_wxyz(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position ``(..., 3)`` and unit ``wxyz`` ``(..., 4)`` (``w >= 0``) of poses ``(..., 8)``."""
    qn = normalize(q)
    return translation_of(qn), qn[..., :4]


def to_matrix(q: np.ndarray) -> np.ndarray:
    """Homogeneous 4x4 matrices ``(..., 4, 4)`` of poses ``(..., 8)``."""
    q = _as_dq(q)
    out = np.zeros(q.shape[:-1] + (4, 4))
    out[..., :3, :3] = rotation_matrix(q)
    out[..., :3, 3] = translation_of(q)
    out[..., 3, 3] = 1.0
    return out


def matrix_to_wxyz(rot: np.ndarray) -> np.ndarray:
    """Unit ``wxyz`` quaternions ``(..., 4)`` of rotation matrices ``(..., 3, 3)``."""
    r = np.asarray(rot, dtype=np.float64)
    # Shepperd's method, vectorized: take the best-conditioned of the four candidate formulas.
    tr = np.trace(r, axis1=-2, axis2=-1)
    cand = np.stack(
        [
            np.stack([1 + tr, r[..., 2, 1] - r[..., 1, 2], r[..., 0, 2] - r[..., 2, 0],
                      r[..., 1, 0] - r[..., 0, 1]], -1),
            np.stack([r[..., 2, 1] - r[..., 1, 2], 1 + 2 * r[..., 0, 0] - tr,
                      r[..., 0, 1] + r[..., 1, 0], r[..., 0, 2] + r[..., 2, 0]], -1),
            np.stack([r[..., 0, 2] - r[..., 2, 0], r[..., 0, 1] + r[..., 1, 0],
                      1 + 2 * r[..., 1, 1] - tr, r[..., 1, 2] + r[..., 2, 1]], -1),
            np.stack([r[..., 1, 0] - r[..., 0, 1], r[..., 0, 2] + r[..., 2, 0],
                      r[..., 1, 2] + r[..., 2, 1], 1 + 2 * r[..., 2, 2] - tr], -1),
        ],
        axis=-2,
    )
    diag = np.stack([tr, r[..., 0, 0], r[..., 1, 1], r[..., 2, 2]], -1)
    best = np.take_along_axis(cand, np.argmax(diag, -1)[..., None, None], axis=-2)[..., 0, :]
    best = best / np.linalg.norm(best, axis=-1, keepdims=True)
    return np.where(best[..., :1] < 0, -best, best)


def from_matrix(mat: np.ndarray) -> np.ndarray:
    """Unit poses ``(..., 8)`` from homogeneous matrices ``(..., 4, 4)`` (or ``(..., 3, 4)``)."""
    mat = np.asarray(mat, dtype=np.float64)
    if mat.shape[-2:] not in ((4, 4), (3, 4)):
        raise ValueError(f"matrix must be (..., 4, 4), got {mat.shape}")
    return from_pos_wxyz(mat[..., :3, 3], matrix_to_wxyz(mat[..., :3, :3]))


def rotation_about_line(direction: np.ndarray, point: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Unit pose rotating by ``angle`` (rad, right-hand about ``+direction``) about a line."""
    u = np.asarray(direction, dtype=np.float64)
    u = u / np.linalg.norm(u, axis=-1, keepdims=True)
    c = np.asarray(point, dtype=np.float64)
    half = 0.5 * np.asarray(angle, dtype=np.float64)[..., None]
    m = np.cross(c, u)
    s = np.sin(half)
    return np.concatenate(
        [np.cos(half), s * u, np.zeros_like(half), s * m], axis=-1
    )


def translation(t: np.ndarray) -> np.ndarray:
    """Pure translation ``1 + eps t/2`` ``(..., 8)`` for ``t`` ``(..., 3)``."""
    t = np.asarray(t, dtype=np.float64)
    out = np.zeros(t.shape[:-1] + (8,))
    out[..., 0] = 1.0
    out[..., 5:] = 0.5 * t
    return out


def screw_parameters(q: np.ndarray) -> dict[str, np.ndarray]:
    """Screw axis and motion of poses ``(..., 8)`` (Chasles).

    Returns ``direction`` (unit, ``(..., 3)``), ``moment`` (``(..., 3)``), ``angle`` in
    ``[0, pi]`` (rad), ``pitch_distance`` (translation along the axis). For a pure translation
    the direction is the translation direction, the moment zero and the angle zero.
    """
    qn = normalize(q)
    p0, pv = qn[..., 0], qn[..., 1:4]
    d0, dv = qn[..., 4], qn[..., 5:8]
    s = np.linalg.norm(pv, axis=-1)
    angle = 2.0 * np.arctan2(s, p0)
    rot = s > TOL.zero
    safe_s = np.where(rot, s, 1.0)
    u = pv / safe_s[..., None]
    # Q = cos(a/2) + sin(a/2) (u + eps m) with dual angle a + eps d: matching parts gives
    # d0 = -sin(a/2) d/2 and dv = sin(a/2) m + cos(a/2) (d/2) u.
    dist = np.where(rot, -2.0 * d0 / safe_s, 2.0 * np.linalg.norm(dv, axis=-1))
    moment = (dv - np.cos(angle / 2)[..., None] * 0.5 * dist[..., None] * u) / safe_s[..., None]
    t = translation_of(qn)
    tnorm = np.linalg.norm(t, axis=-1, keepdims=True)
    u = np.where(rot[..., None], u, t / np.where(tnorm > 0, tnorm, 1.0))
    moment = np.where(rot[..., None], moment, 0.0)
    return {"direction": u, "moment": moment, "angle": angle, "pitch_distance": dist}
