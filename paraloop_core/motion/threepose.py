"""Three-pose interpolation by a quadratic motion: the Bennett motion (Brunnthaler, Schroecker,
Husty 2005; MATH section 4 for its factorizations).

Three world poses ``S_0, S_1, S_2`` (unit dual quaternions ``(3, 8)``) are moved to the frame of
``S_0``: ``p_i = S_0^-1 S_i``. A quadratic motion polynomial is a conic on the Study quadric, so
one through ``1, p_1, p_2`` lies in their plane and is the plane's section with the quadric:
unique. With ``1`` at ``t = inf`` and ``p_1, p_2`` at ``t = 0, 1`` (any other two values give the
same motion reparametrized by ``t -> a t + b``, the same axes) the monic Lagrange form

    C(t) = t (t - 1) + a (t - 1) p_1 + b t p_2

satisfies the Study condition identically in t iff ``a = -B(1, p_2) / B(p_1, p_2)`` and
``b = B(1, p_1) / B(p_1, p_2)`` (``B`` the polar form of the quadric; its quadratic form vanishes
on 1, p_1, p_2, so ``C C~`` has the dual part ``t (t - 1) (a (t - 1) B_1 + b t B_2 + a b B_12)``).
``B(1, p_i)`` is the dual scalar part of ``p_i``: zero when ``S_i`` is reached from ``S_0`` by a
rotation without pitch or a pure translation (:func:`fourpose.relative_poses` refuses it), and
``B(p_1, p_2) = 0`` likewise between ``S_1`` and ``S_2``: then the plane meets the quadric in two
lines (two rotations, no Bennett motion).
"""

from __future__ import annotations

import numpy as np

from paraloop_core.algebra import dq
from paraloop_core.errors import InterpolationError
from paraloop_core.motion.fourpose import polar, relative_poses
from paraloop_core.tolerance import TOL

#: The parameters of ``S_1`` and ``S_2`` (``S_0`` at ``t = inf``) of :func:`three_pose_motion`.
POSE_PARAMETERS = np.array([0.0, 1.0])


def three_pose_motion(poses: np.ndarray) -> np.ndarray:
    """The monic quadratic ``C`` ``(3, 8)`` (ascending, ``S_0`` frame) through three world poses
    ``(3, 8)`` (unit DQs): ``C(inf) = 1``, ``C(0) ∝ S_0^-1 S_1``, ``C(1) ∝ S_0^-1 S_2``
    (:data:`POSE_PARAMETERS`); the world motion is ``S_0 C(t)`` (:func:`fourpose.world_motion`).

    Raises :class:`InterpolationError`: ``coincident``, ``rank`` (the poses span less than a
    plane: distinct poses only do so when one is reached by a zero-pitch turn), ``zero-pitch``
    (a pose reached from ``S_0``, or ``S_2`` from ``S_1``, by a rotation without pitch or a
    pure translation: no Bennett motion); ValueError for malformed input.
    """
    _, rel, _ = relative_poses(poses, 3)
    move = dq.mul(dq.conj(rel[1]), rel[2])  # S_1 -> S_2; its dual scalar part is B(p_1, p_2)
    b12 = float(polar(rel[1], rel[2]))
    if not abs(b12) > TOL.zero_pitch * float(np.sqrt((move[4:] ** 2).sum())):
        raise InterpolationError(
            "pose 2 is reached from pose 1 by a rotation without pitch or a pure translation: "
            "the three poses lie on two rotations through a common pose and no Bennett motion "
            "visits them; move pose 2 along its rotation axis by a small amount", "zero-pitch")
    a, b = -rel[2, 4] / b12, rel[1, 4] / b12  # a, b do not depend on the length unit
    c = np.zeros((3, 8))
    c[0] = -a * rel[1]
    c[1] = a * rel[1] + b * rel[2] - dq.IDENTITY
    c[2] = dq.IDENTITY
    return c
