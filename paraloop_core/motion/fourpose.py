"""Four-pose interpolation by cubic motions (HSS15, paper Sec. 4.2, MATH section 6).

Four world poses ``S_0..S_3`` (unit dual quaternions ``(4, 8)``, any frame) are moved to the
frame of ``S_0``: ``p_i = S_0^-1 S_i`` (``p_0 = 1``). Each of the (at most two) real rulings
``{t - k}`` of the Study quadric through the identity in ``span(p_0..p_3)`` gives a
one-parameter **family** of monic cubics ``C_mu`` (parameter ``mu`` in ``R u {inf}``) with
``C_mu(inf) = 1`` and ``C_mu(t_i) ∝ p_i``. The world motion is ``S_0 C_mu(t) = M(t) S_0`` with
the monic ``M = S_0 C_mu S_0^-1`` (:func:`world_motion`), whose factors are world axes.

Family order: by the visiting order of the poses (increasing t, starting after pose 0 at
``t = inf``) read as an undirected cycle and written ``(0, a, b, c)`` with ``a < c``; ascending
lexicographically (ties: by ``c``). The visiting order is fixed within a family.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from paraloop_core.algebra import dq
from paraloop_core.errors import InterpolationError
from paraloop_core.tolerance import TOL


@dataclass(frozen=True)
class FourPoseFamilies:
    """The interpolating families of four poses.

    ``poses`` ``(4, 8)`` unit world poses ``S_i`` (Study-projected); ``relative`` ``(4, 8)``
    unit ``p_i = S_0^-1 S_i`` (scalar part >= 0, ``p_0 = 1``); per family ``f``: ``c[f]`` ``(4,)``
    with ``c[f, 0] = 1`` and ruling point ``k[f] = sum_i c[f, i] p_i`` ``(8,)`` (S_0 frame,
    zero scalar and dual-scalar part), ``t[f]`` ``(3,)`` the parameters visiting ``p_1..p_3``
    (``p_0`` at ``t = inf``).
    """

    poses: np.ndarray
    relative: np.ndarray
    c: np.ndarray
    k: np.ndarray
    t: np.ndarray

    @property
    def visiting_order(self) -> tuple[tuple[int, ...], ...]:
        """Per family the pose indices in order of increasing t, starting with pose 0."""
        return tuple((0, *(int(i) + 1 for i in np.argsort(tf))) for tf in self.t)


#: number words of the pose counts interpolated here (three: the Bennett quadratic, threepose)
_COUNT = {3: "three", 4: "four"}
#: the motion polynomial through that many poses
_CURVE = {3: "quadratic", 4: "cubic"}


def _check_poses(poses: np.ndarray, count: int) -> np.ndarray:
    s = np.asarray(poses, dtype=np.float64)
    if s.shape != (count, 8):
        raise ValueError(f"{_COUNT[count]}-pose interpolation needs poses of shape ({count}, 8), "
                         f"got {s.shape}")
    if not np.isfinite(s).all():
        raise ValueError("poses must be finite")
    # Primal parts are compared among themselves only: the dual part carries the length unit.
    pn = np.sqrt((s[:, :4] ** 2).sum(-1))
    bad = np.flatnonzero(pn <= TOL.zero * pn.max())
    if bad.size:
        raise ValueError(f"pose {int(bad[0])} has a zero primal part (not a pose)")
    return dq.study_project(dq.normalize(s))


def polar(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Polar form of the Study quadric ``B(x, y) = x_P . y_D + x_D . y_P`` of dual quaternions
    ``(..., 8)`` (broadcasting)."""
    if np.shape(x)[-1:] != (8,) or np.shape(y)[-1:] != (8,):
        raise ValueError(f"dual quaternions (..., 8) needed, got {np.shape(x)}, {np.shape(y)}")
    return (x[..., :4] * y[..., 4:] + x[..., 4:] * y[..., :4]).sum(axis=-1)


def _rulings(p: np.ndarray) -> np.ndarray:
    """Coefficients ``c`` ``(r, 4)`` (``c_0 = 1``, ``r in {1, 2}``) of the real rulings through 1.

    ``p`` ``(4, 8)`` are the relative poses with dual parts scaled to O(1); ``c`` is invariant
    under that scaling (all conditions are homogeneous in the dual part).
    """
    bm = p.T  # (8, 4)
    _, _, vt = np.linalg.svd(bm[[0, 4], :])
    null = vt[2:].T  # (4, 2): combinations with zero scalar and zero dual-scalar part
    kk = bm @ null
    q = 0.5 * polar(kk.T[:, None, :], kk.T[None, :, :])  # (2, 2) quadratic form on the pencil
    lam, vec = np.linalg.eigh(q)
    big = np.abs(lam).max()
    if big <= TOL.zero:
        raise InterpolationError(
            "degenerate poses: the whole pencil through S_0 lies on the Study quadric, so the "
            "rulings are not determined (no unique cubic families)", "rank")
    if lam[0] * lam[1] > 0 and np.abs(lam).min() > TOL.residual * big:
        raise InterpolationError(
            "no real interpolant: the two rulings of the quadric through S_0 spanned by the "
            "four poses are complex (discriminant < 0); move one of the poses", "no-real")
    # v^T q v = 0 for v = sqrt|lam1| e0 +- sqrt|lam0| e1 (lam0 <= 0 <= lam1 up to tolerance).
    a, b = np.sqrt(np.abs(lam[1])), np.sqrt(np.abs(lam[0]))
    v = a * vec[:, 0] + np.array([[b], [-b]]) * vec[:, 1]  # (2, 2): the two signs
    c = v @ null.T
    if (np.abs(c[:, 0]) <= TOL.residual * np.abs(c).max(axis=-1)).any():
        raise InterpolationError(
            "degenerate poses: a ruling through S_0 meets the plane of poses 1..3 in the "
            "hyperplane of zero scalar part, so no family is defined; perturb the poses", "rank")
    return c / c[:, :1]


def relative_poses(poses: np.ndarray, count: int = 4
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(s, rel, scaled)`` of ``count`` (3 or 4) world poses ``(count, 8)`` (unit DQs): the
    Study-projected unit poses, the relative poses ``p_i = S_0^-1 S_i`` (``p_0 = 1``) and the
    same with dual parts scaled to O(1), after the checks both interpolations need.

    Raises :class:`InterpolationError` with reason ``coincident`` (two poses equal), ``rank``
    (the poses span less than a projective ``(count - 1)``-space) or ``zero-pitch`` (a pose is
    reached from S_0 by a rotation without pitch or a pure translation); ValueError for
    malformed input.
    """
    if count not in _COUNT:
        raise ValueError(f"count must be 3 or 4, got {count!r}")
    s = _check_poses(poses, count)
    rel = dq.normalize(dq.mul(dq.inv(s[0]), s))
    rel[0] = dq.IDENTITY
    # Scale lengths to O(1) for the rank and tolerance tests (c and t are scale invariant).
    length = np.sqrt((rel[:, 4:] ** 2).sum(-1)).max()
    scaled = rel.copy()
    scaled[:, 4:] *= 1.0 / length if length > 0 else 1.0
    gap = np.minimum(np.abs(scaled[:, None] - scaled).max(-1),
                     np.abs(scaled[:, None] + scaled).max(-1))  # same pose up to sign
    close = (gap <= TOL.residual) & np.triu(np.ones((count, count), dtype=bool), 1)
    if close.any():
        i, j = divmod(int(close.argmax()), count)  # the first pair i < j, row-major
        raise InterpolationError(
            f"poses {i} and {j} coincide (within tolerance): {_COUNT[count]} distinct poses "
            "are needed", "coincident")
    sv = np.linalg.svd(scaled, compute_uv=False)
    if sv[-1] <= TOL.rank * sv[0]:
        raise InterpolationError(
            f"degenerate poses: the {_COUNT[count]} poses span less than a projective "
            f"{count - 1}-space in the Study quadric (rank < {count}), so no {_CURVE[count]} "
            "interpolates them", "rank")
    # Pitch relative to the pose's own displacement (not to the largest one), so a pose that
    # is merely close to S_0 is accepted: it is visited at a large |t|. Products of unit inputs
    # carry round-off ~1e-16 |D|, so a ratio above TOL.zero_pitch is certain.
    ratio = np.abs(scaled[1:, 4]) / np.maximum(np.sqrt((scaled[1:, 4:] ** 2).sum(-1)), 1e-300)
    flat = np.flatnonzero(ratio <= TOL.zero_pitch)
    if len(flat):
        i = int(flat[0]) + 1
        raise InterpolationError(
            f"pose {i} is reached from pose 0 by a rotation without pitch or a pure translation "
            f"(translation along the axis / offset = {ratio[i - 1]:.1e} <= {TOL.zero_pitch:g}): "
            "within the precision of the input it lies on a ruling through S_0 and cannot be "
            f"visited; move pose {i} along its rotation axis by a small amount", "zero-pitch")
    return s, rel, scaled


def four_pose_families(poses: np.ndarray) -> FourPoseFamilies:
    """Both cubic families through four world poses ``(4, 8)`` (unit DQs, any frame).

    Raises :class:`InterpolationError` with reason ``coincident``, ``rank``, ``no-real`` or
    ``zero-pitch`` (:func:`relative_poses`); ValueError for malformed input.
    """
    s, rel, scaled = relative_poses(poses)
    c = _rulings(scaled)
    k = c @ rel
    t = polar((c @ scaled)[:, None, :], scaled[None, 1:]) / scaled[1:, 4]
    keys = []
    for tf, cf in zip(t, c, strict=True):
        seq = [0, *(int(i) + 1 for i in np.argsort(tf))]
        keys.append((tuple(seq if seq[1] < seq[3] else [0, *seq[:0:-1]]), tuple(cf)))
    order = sorted(range(len(c)), key=keys.__getitem__)
    return FourPoseFamilies(s, rel, c[order], k[order], t[order])


def _family(fams: FourPoseFamilies, family: int) -> int:
    if not isinstance(fams, FourPoseFamilies):
        raise ValueError("fams must be a FourPoseFamilies (from four_pose_families)")
    if family not in range(len(fams.c)):
        raise ValueError(f"family must be 0 or 1, got {family!r}")
    return int(family)


def bad_mu_mask(fams: FourPoseFamilies, family: int, mus: np.ndarray) -> np.ndarray:
    """Mask ``(M,)``: ``mu`` is (within tolerance) one of ``c_0, t_1, t_2, t_3``, where the
    family degenerates (``mu = t_i`` makes ``C_mu(t_i) = 0``; ``mu = c_0`` is a pole)."""
    f = _family(fams, family)
    bad = np.r_[fams.c[f, 0], fams.t[f]]
    mus = np.asarray(mus, dtype=np.float64)
    return (np.abs(mus[..., None] - bad) <= TOL.residual * (1.0 + np.abs(bad))).any(axis=-1)


def four_pose_motion_batch(fams: FourPoseFamilies, family: int, mus: np.ndarray) -> np.ndarray:
    """Monic cubics ``C_mu`` ``(M, 4, 8)`` (S_0 frame, ascending) for ``mus`` ``(M,)``
    (``inf`` allowed). Raises :class:`InterpolationError` (``bad-mu``) if any mu is excluded."""
    f = _family(fams, family)
    mus = np.asarray(mus, dtype=np.float64)
    if mus.ndim != 1 or np.isnan(mus).any():
        raise ValueError(f"mus must be a 1-D array without NaN, got shape {mus.shape}")
    bad = bad_mu_mask(fams, f, mus)
    if bad.any():
        mu = float(mus[np.argmax(bad)])
        raise InterpolationError(
            f"mu = {mu:.9g} is excluded: it equals c_0 = 1 or a visiting parameter t_i "
            f"{np.round(fams.t[f], 9).tolist()} where the cubic degenerates; choose another mu",
            "bad-mu")
    c, t, p = fams.c[f], fams.t[f], fams.relative[1:]
    inf = np.isinf(mus)
    mf = np.where(inf, 0.0, mus)[:, None]
    w = c[1:] * np.where(inf[:, None], 1.0, (mf - t) / (mf - c[0]))  # (M, 3)
    # prod_j (t - t_j) and the products leaving out one root, ascending and monic, written out
    # from the three roots (a numpy.polynomial call per product costs more than the cubic)
    t0, t1, t2 = t.tolist()
    full = np.array([-t0 * t1 * t2, t0 * t1 + t0 * t2 + t1 * t2, -(t0 + t1 + t2), 1.0])
    others = np.array([[t1 * t2, -(t1 + t2), 1.0, 0.0], [t0 * t2, -(t0 + t2), 1.0, 0.0],
                       [t0 * t1, -(t0 + t1), 1.0, 0.0]])
    return full[:, None] * dq.IDENTITY - np.einsum("mi,ik,il->mkl", w, others, p)


def four_pose_motion(fams: FourPoseFamilies, family: int, mu: float | None) -> np.ndarray:
    """The monic cubic ``C_mu`` ``(4, 8)`` of ``family`` in the S_0 frame (``mu = None``: inf)."""
    mu = np.inf if mu is None else float(mu)
    return four_pose_motion_batch(fams, family, np.array([mu]))[0]


def world_motion(reference: np.ndarray, c_rel: np.ndarray) -> np.ndarray:
    """Monic world motion ``M = S_0 C S_0^-1`` ``(..., 4, 8)`` of ``c_rel`` ``(..., 4, 8)``.

    The body pose at t is ``M(t) S_0`` (``reference = S_0`` ``(8,)``); factors of M are axes in
    world coordinates at the home configuration ``t = inf``.
    """
    s0 = np.asarray(reference, dtype=np.float64)
    c_rel = np.asarray(c_rel, dtype=np.float64)
    if s0.shape != (8,) or c_rel.shape[-1] != 8 or c_rel.ndim < 2:
        raise ValueError(f"need reference (8,) and c_rel (..., n+1, 8), got {s0.shape}, "
                         f"{c_rel.shape}")
    return dq.mul(dq.mul(s0, c_rel), dq.inv(s0))
