"""One Newton step on the factors of a monic cubic (:func:`factor.refine_cubic_factors`).

``C = (t - h_0)(t - h_1)(t - h_2)``: 24 coefficient equations (coefficients 0..2 of C) in the
21 free coefficients of the rotation factors (the dual scalar stays 0), least squares.
"""

from __future__ import annotations

import numpy as np

from paraloop_core.algebra import dq, poly

#: Unknowns of a rotation factor (the dual scalar stays 0).
FREE = np.array([0, 1, 2, 3, 5, 6, 7])


def cubic_step(h: np.ndarray, c_monic: np.ndarray) -> np.ndarray:
    """Newton step ``(..., 3, 7)`` (on :data:`FREE` of each factor) for factors ``h``
    ``(..., 3, 8)`` of monic cubics ``c_monic`` ``(..., 4, 8)`` (broadcasting)."""
    r = c_monic - poly.from_factors(h)
    step = _least_squares(_jacobian(h), r[..., :3, :].reshape(*r.shape[:-2], 24)[..., None])
    return step[..., 0].reshape(*h.shape[:-2], 3, 7)


def _jacobian(h: np.ndarray) -> np.ndarray:
    """``d C / d h_i e_k = -(L_0..L_{i-1}) e_k (L_{i+1}..L_2)`` ``(..., 24, 21)`` (rows: the
    coefficients 0..2 of C, 8 components each; columns: the free units ``e_k`` of h_0, h_1,
    h_2) of ``C = L_0 L_1 L_2``, ``L_i = t - h_i``, as 8 x 8 multiplication matrices: ``a e_k``
    is column k of the left matrix of a, ``e_k b`` row k of the right matrix of b."""
    h0, h1, h2 = h[..., 0, :], h[..., 1, :], h[..., 2, :]
    right = dq.right_matrix(h)  # (..., 3, 8, 8): a h_i = a @ right[i]
    r1t, r2t = np.swapaxes(right[..., 1, :, :], -1, -2), np.swapaxes(right[..., 2, :, :], -1, -2)
    l0 = _left_matrix(h0)
    eye = np.broadcast_to(np.eye(8), l0.shape)
    # -e_k (t - h1)(t - h2): coefficients h1 h2, -(h1 + h2), 1 on the right of e_k
    p12 = np.swapaxes(dq.right_matrix(dq.mul(h1, h2)), -1, -2)
    b0 = np.stack([p12, -(r1t + r2t), eye], axis=-3)
    # -(t - h0) e_k (t - h2) = -(h0 e_k h2 - t (h0 e_k + e_k h2) + t^2 e_k)
    b1 = np.stack([l0 @ r2t, -(l0 + r2t), eye], axis=-3)
    # -(t - h0)(t - h1) e_k: coefficients h0 h1, -(h0 + h1), 1 on the left of e_k
    b2 = np.stack([_left_matrix(dq.mul(h0, h1)), -(l0 + _left_matrix(h1)), eye], axis=-3)
    blocks = -np.stack([b0, b1, b2], axis=-3)[..., FREE]  # (..., 3 coeff, 3 factor, 8, 7)
    return np.swapaxes(blocks, -3, -2).reshape(*h.shape[:-2], 24, 21)


def _left_matrix(a: np.ndarray) -> np.ndarray:
    """``(..., 8, 8)`` with ``a b = _left_matrix(a) @ b`` (column k: ``a e_k``)."""
    return np.einsum("...i,kic->...ck", a, dq.RIGHT.reshape(8, 8, 8))


def _least_squares(jac: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Least-squares solutions ``(..., n, 1)`` of ``jac`` ``(..., m, n)`` (m >= n) ``x = rhs``
    ``(..., m, 1)``: by QR (a quarter of an SVD's time) where the columns are independent to
    1e-10, else by the pseudo-inverse (what near-rank-deficient items need)."""
    q, r = np.linalg.qr(jac)
    diag = np.abs(np.diagonal(r, axis1=-2, axis2=-1))
    full = diag.min(axis=-1) > 1e-10 * diag.max(axis=-1)
    out = np.empty(jac.shape[:-2] + (jac.shape[-1], 1))
    if full.any():
        out[full] = np.linalg.solve(r[full], np.swapaxes(q[full], -1, -2) @ rhs[full])
    if not full.all():
        out[~full] = np.linalg.pinv(jac[~full]) @ rhs[~full]
    return out
