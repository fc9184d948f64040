"""The nine 6R loops of a generic cubic (MATH section 5) and their kinematics.

A loop joins two factorizations ``F = (a0, a1, a2)`` and ``G = (b0, b1, b2)`` of the same monic
cubic (first norms differ, last norms differ). Its six **joint factors** ``(..., 6, 8)`` are
``[a0, a1, a2, b2, b1, b0]``: axis ``A_i`` (home configuration, t = inf, base frame) is the
rotation axis of joint factor i. Link i lies between ``A_{i-1}`` and ``A_i``; link 0 is the base,
link 3 the end link. Link poses in the base frame:
``L_0 = 1, L_1 = t-a0, L_2 = (t-a0)(t-a1), L_3 = C, L_4 = (t-b0)(t-b1), L_5 = t-b0``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from paraloop_core.algebra import dq, poly
from paraloop_core.algebra.factor import NORM_ORDERS, Factorizations

#: The nine loops as pairs of factorization indices (into :data:`factor.NORM_ORDERS`).
LOOP_PAIRS = np.array(
    [(f, g) for f in range(6) for g in range(f + 1, 6)
     if NORM_ORDERS[f][0] != NORM_ORDERS[g][0] and NORM_ORDERS[f][2] != NORM_ORDERS[g][2]]
)
#: ``True`` where the loop is angle-symmetric (G is F reversed), else double-Bennett.
LOOP_IS_AS = np.array([bool((NORM_ORDERS[g] == NORM_ORDERS[f][::-1]).all()) for f, g in LOOP_PAIRS])
LOOP_KINDS = tuple("angle-symmetric" if a else "double-Bennett" for a in LOOP_IS_AS)
#: Which link pose carries axis i: A_i is fixed in links i and i+1; we use these.
_AXIS_LINK = np.array([0, 1, 2, 4, 5, 0])
#: Orientation sign of joint i's rotation relative to ``+direction`` of its factor.
JOINT_SIGN = np.array([1.0, 1.0, 1.0, -1.0, -1.0, -1.0])


@dataclass(frozen=True)
class Loop:
    """One 6R loop: ``joint_factors`` ``(6, 8)``, ``kind``, ``factorizations`` (f, g) indices."""

    joint_factors: np.ndarray
    kind: str
    factorizations: tuple[int, int]

    @property
    def axes(self) -> np.ndarray:
        """Unit Plücker axes ``(6, 6)`` (direction, moment) in the base frame at t = inf."""
        return factor_axes(self.joint_factors)


def loop_joint_factors(factors: np.ndarray) -> np.ndarray:
    """Joint factors ``(..., 9, 6, 8)`` of the nine loops from six factorizations
    ``(..., 6, 3, 8)`` (order of :data:`LOOP_PAIRS`)."""
    f = factors[..., LOOP_PAIRS[:, 0], :, :]
    g = factors[..., LOOP_PAIRS[:, 1], :, :]
    return np.concatenate([f, g[..., ::-1, :]], axis=-2)


def nine_loops(facts: Factorizations) -> list[Loop]:
    """The nine loops of one cubic's factorizations (unbatched ``facts``)."""
    jf = loop_joint_factors(facts.factors)
    return [
        Loop(jf[k], LOOP_KINDS[k], (int(LOOP_PAIRS[k, 0]), int(LOOP_PAIRS[k, 1])))
        for k in range(len(LOOP_PAIRS))
    ]


def factor_axes(h: np.ndarray) -> np.ndarray:
    """Unit Plücker lines ``(..., 6)`` = ``(p, d) / |p|`` of rotation factors ``h`` ``(..., 8)``."""
    p, d = h[..., 1:4], h[..., 5:8]
    n = np.sqrt((p * p).sum(-1, keepdims=True))
    return np.concatenate([p, d], axis=-1) / n


def norm_roots(joint_factors: np.ndarray) -> np.ndarray:
    """Upper norm roots ``(..., 3)`` (complex) of the loop's cubic, read off its first three
    joint factors: ``t - h`` has norm ``(t - h_0)^2 + |h_vec|^2``, root ``h_0 + i |h_vec|``."""
    h = np.asarray(joint_factors, dtype=np.float64)[..., :3, :]
    return h[..., 0] + 1j * np.linalg.norm(h[..., 1:4], axis=-1)


def cycle_samples(joint_factors: np.ndarray, samples: int) -> np.ndarray:
    """Sorted parameters ``u`` in ``[0, 1)`` covering the cycle: ``samples`` uniform in u and
    ``samples // 3`` (at least 8) per norm factor uniform in its rotation angle
    (:func:`poly.cycle_parameters`). Where the motion passes near a singular pose a joint
    turns half a turn within a tiny stretch of u; uniform samples alone leave one cell there
    whose motion bound spans the whole flip (hundreds of mm of slack for a sound check)."""
    h = np.asarray(joint_factors, dtype=np.float64)[:3]
    fast = poly.t_to_param(poly.cycle_parameters(
        h[:, 0], np.linalg.norm(h[:, 1:4], axis=-1), max(samples // 3, 8))) % 1.0
    return np.unique(np.concatenate([np.arange(samples) / samples, fast]))


def _linear_pose(h: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Homogeneous pose of ``t - h`` at ``t`` ``(T,)``: ``(..., T, 8)``; identity at inf."""
    return poly.evaluate_pose(poly.linear(h)[..., None, :, :], t)


def link_poses(joint_factors: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Poses ``(..., T, 6, 8)`` (homogeneous, not unit) of the six links in the base frame."""
    t = np.atleast_1d(np.asarray(t, dtype=np.float64))
    lin = _linear_pose(joint_factors, t)  # (..., 6, T, 8)
    a0, a1, a2, b0, b1 = lin[..., 0, :, :], lin[..., 1, :, :], lin[..., 2, :, :], \
        lin[..., 5, :, :], lin[..., 4, :, :]
    one = np.broadcast_to(dq.IDENTITY, a0.shape)
    l2 = dq.mul(a0, a1)
    out = np.stack([one, a0, l2, dq.mul(l2, a2), dq.mul(b0, b1), b0], axis=-2)
    return out


def axes_at(joint_factors: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Unit Plücker axes ``(..., T, 6, 6)`` of the loop in the base frame at parameters ``t``."""
    poses = link_poses(joint_factors, t)[..., _AXIS_LINK, :]
    axes = factor_axes(joint_factors)[..., None, :, :]
    return dq.transform_lines(poses, axes)


def joint_angles(joint_factors: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Joint angles ``(..., T, 6)`` in rad, in ``(-2 pi, 0)`` for joints 0..2 and ``(0, 2 pi)``
    for 3..5, measured about each factor's ``+direction``; zero at t = inf (home)."""
    t = np.atleast_1d(np.asarray(t, dtype=np.float64))
    h0 = joint_factors[..., None, :, 0]
    pn = np.linalg.norm(joint_factors[..., None, :, 1:4], axis=-1)
    tt = t[:, None]
    phi = np.where(np.isinf(tt), 0.0, 2.0 * np.arctan2(-pn, np.where(np.isinf(tt), 1.0, tt - h0)))
    phi = np.where(np.isinf(tt), np.where(tt > 0, 0.0, -2 * np.pi), phi)
    return JOINT_SIGN * phi


def joint_polys(joint_factors: np.ndarray) -> np.ndarray:
    """Forward joint factors ``T_0..T_5`` ``(..., 6, 2, 8)``: pose of link i+1 in link i's home
    frame is ``T_i``: ``t - a_i`` for i < 3, ``t - b~`` (conjugate) for i >= 3."""
    lin = poly.linear(joint_factors)
    return np.concatenate([lin[..., :3, :, :], poly.conj(lin[..., 3:, :, :])], axis=-3)


def relative_chain(joint_factors: np.ndarray, i: int, j: int) -> np.ndarray:
    """Linear factors ``(..., k, 2, 8)`` (ascending) of the motion of link j in link i's home
    frame: ``R_ij = L_0 L_1 ... L_{k-1}``, ``k = min(|j-i|, 6-|j-i|)``. Each ``L_m`` is a
    rotation about a fixed line of the base frame (a joint axis at home)."""
    if not (0 <= i < 6 and 0 <= j < 6) or i == j:
        raise ValueError(f"links must be distinct indices in 0..5, got {i}, {j}")
    tp = joint_polys(joint_factors)
    fwd = (j - i) % 6
    if fwd <= 3:  # R_ij ∝ T_i ... T_{j-1}
        return tp[..., [(i + s) % 6 for s in range(fwd)], :, :]
    # R_ij ∝ conj(T_j ... T_{i-1}) = conj(T_{i-1}) ... conj(T_j)
    return poly.conj(tp[..., [(j + s) % 6 for s in reversed(range(6 - fwd))], :, :])


def relative_motion(joint_factors: np.ndarray, i: int, j: int) -> np.ndarray:
    """Motion polynomial ``R_ij`` ``(..., k+1, 8)`` of link j in link i's home frame (base
    coordinates at t = inf), up to a real factor: the product of :func:`relative_chain`."""
    chain = relative_chain(joint_factors, i, j)
    out = chain[..., 0, :, :]
    for s in range(1, chain.shape[-3]):
        out = poly.mul(out, chain[..., s, :, :])
    return out
