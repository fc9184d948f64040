"""Selection of a cubic within a four-pose family (paper Sec. 4.2): scores of ``mu`` and a scan.

Every criterion is a score ``(M,)`` of many ``mu`` at once (lower is better); ``mu`` values
where the family degenerates (:func:`fourpose.bad_mu_mask`) or the cubic is not generic
(nonzero :func:`factor.all_factorizations_batch` code) score ``inf``. Criteria and parameters:

* ``"base-axes"`` / ``"end-axes"``: ``points`` ``(2, 3)`` world targets for the axes
  ``(A_0, A_5)`` resp. ``(A_2, A_3)`` of loop ``loop`` (0..8, order of ``loops.LOOP_PAIRS``),
  optional ``weights`` ``(2,)`` (0 ignores an axis). Score = weighted sum of squared
  point-line distances; axes are world lines at the home configuration (body at ``S_0``).
* ``"length"``: ``inertia`` (:class:`metric.Inertia`, body frame), optional ``samples``
  (default 192); score = metric length of the whole cycle as a chord sum (a lower bound, as
  :func:`metric.motion_length`) over samples adapted to the motion: for each norm factor
  ``(t - h0)^2 + r^2`` the t where that factor's rotation angle is uniform,
  ``t = h0 + r cot(pi (j + 1/2) / K)``, merged and sorted, plus ``t = inf``. Uniform samples
  in u miss fast parts (a factor with small r turns fully within ``|t - h0| ~ r``) and
  underestimate the length there, which a minimization then seeks out.
* ``"extra-poses"``: ``poses`` ``(E, 8)`` world poses, ``inertia``; score = sum over the poses
  of the squared metric distance to the closest pose of the motion: critical points of MATH
  section 8 (2a) plus motion-adapted samples, polished on the distance (see
  :func:`closest.closest_pose`; never above a 20001-sample scan in tests).
* ``"smooth-drive"``: optional ``loop`` (0..8, default 0) and ``motor`` (joint 0..5 of that
  loop, default None = the best motor); score = :func:`drive.smooth_drive_penalty` of the
  loop's joint factors: the worst over the six joints of peak / mean speed with the motor
  turning at constant speed (>= 1; 1 = every joint turns uniformly). It depends only on the
  cubic's norm roots and on which joints carry them, so it is unchanged by conjugation
  (S_0 frame = world frame) and, with the best motor, the same for all nine loops (each loop
  carries every norm root on two joints); a fixed ``motor`` makes the loop matter.

The metric is left invariant, so length and pose distances are computed in the S_0 frame.
"""

from __future__ import annotations

import numpy as np

from paraloop_core.algebra import dq, factor
from paraloop_core.errors import NonGenericMotionError
from paraloop_core.linkage import drive, loops
from paraloop_core.motion import closest, metric
from paraloop_core.motion.fourpose import (
    FourPoseFamilies,
    bad_mu_mask,
    four_pose_motion_batch,
    world_motion,
)

CRITERIA = ("base-axes", "end-axes", "length", "extra-poses", "smooth-drive")
_AXIS_INDEX = {"base-axes": (0, 5), "end-axes": (2, 3)}
_PARAMS = {
    "base-axes": {"points", "loop", "weights"},
    "end-axes": {"points", "loop", "weights"},
    "length": {"inertia", "samples"},
    "extra-poses": {"poses", "inertia"},
    "smooth-drive": {"loop", "motor"},
}


def _check_params(criterion: str, params: dict) -> None:
    if criterion not in CRITERIA:
        raise ValueError(f"unknown criterion {criterion!r}; choose one of {CRITERIA}")
    extra = set(params) - _PARAMS[criterion]
    if extra:
        raise ValueError(f"criterion {criterion!r} takes {sorted(_PARAMS[criterion])}, "
                         f"got unexpected {sorted(extra)}")
    if criterion in ("length", "extra-poses") and not isinstance(
            params.get("inertia"), metric.Inertia):
        raise ValueError(f"criterion {criterion!r} needs inertia=metric.Inertia(...)")


def _loop_index(loop: object) -> int:
    if isinstance(loop, bool) or loop not in range(len(loops.LOOP_PAIRS)):
        raise ValueError(f"loop must be an index 0..{len(loops.LOOP_PAIRS) - 1}, got {loop!r}")
    return int(loop)


def smooth_drive_scores(c_monic: np.ndarray, loop: int = 0, motor: int | None = None
                        ) -> tuple[np.ndarray, np.ndarray]:
    """Smooth-drive penalties ``(...)`` of monic cubics ``(..., 4, 8)`` (``inf`` where not
    generic) and the :func:`factor.all_factorizations_batch` codes ``(...)``; ``loop`` 0..8,
    ``motor`` joint 0..5 or None (the best). See the module docstring."""
    loop = _loop_index(loop)
    if motor is not None:
        drive.check_index("motor", motor, 0, 5)  # before the batch factorization
    facts = factor.all_factorizations_batch(c_monic)
    jf = loops.loop_joint_factors(facts.factors)[..., loop, :, :]
    good = (facts.code == 0) & np.isfinite(jf).all(axis=(-2, -1))
    out = np.full(good.shape, np.inf)
    out[good] = drive.smooth_drive_penalty(jf[good], motor)
    return out, facts.code


def _axis_score(c_world: np.ndarray, axes_idx: tuple[int, int], params: dict) -> tuple:
    points = np.asarray(params.get("points"), dtype=np.float64)
    if points.shape != (2, 3) or not np.all(np.isfinite(points)):
        raise ValueError(f"points must be a finite (2, 3) array of world points, got "
                         f"{points.shape}")
    weights = np.asarray(params.get("weights", (1.0, 1.0)), dtype=np.float64)
    if weights.shape != (2,) or np.any(weights < 0) or not np.all(np.isfinite(weights)):
        raise ValueError("weights must be two finite numbers >= 0")
    loop = _loop_index(params.get("loop", 0))
    facts = factor.all_factorizations_batch(c_world)
    jf = loops.loop_joint_factors(facts.factors)[..., loop, list(axes_idx), :]
    ax = loops.factor_axes(jf)  # (M, 2, 6) unit world lines
    d2 = np.sum((np.cross(points, ax[..., :3]) - ax[..., 3:]) ** 2, axis=-1)
    return d2 @ weights, facts.code


def score_mu(fams: FourPoseFamilies, family: int, mus: np.ndarray, criterion: str,
             **params) -> np.ndarray:
    """Scores ``(M,)`` of ``mus`` ``(M,)`` (``inf`` allowed) under ``criterion`` (lower is
    better); ``inf`` where the cubic is excluded or not generic. See the module docstring."""
    _check_params(criterion, params)
    mus = np.asarray(mus, dtype=np.float64)
    if mus.ndim != 1 or np.any(np.isnan(mus)):
        raise ValueError(f"mus must be a 1-D array without NaN, got shape {mus.shape}")
    out = np.full(mus.shape, np.inf)
    ok = ~bad_mu_mask(fams, family, mus)
    if not np.any(ok):
        return out
    c_rel = four_pose_motion_batch(fams, family, mus[ok])
    if criterion in _AXIS_INDEX:
        score, code = _axis_score(world_motion(fams.poses[0], c_rel), _AXIS_INDEX[criterion],
                                  params)
    elif criterion == "smooth-drive":
        score, code = smooth_drive_scores(c_rel, params.get("loop", 0), params.get("motor"))
    else:
        facts = factor.all_factorizations_batch(c_rel)  # conjugation keeps genericity
        code, inertia = facts.code, params["inertia"]
        if criterion == "length":
            score = metric.motion_length(c_rel, inertia, params.get("samples", 192))
        else:
            poses = np.asarray(params.get("poses"), dtype=np.float64)
            if poses.ndim != 2 or poses.shape[1] != 8 or len(poses) == 0 or not np.all(
                    np.isfinite(poses)) or np.any(np.linalg.norm(poses[:, :4], axis=1) == 0):
                raise ValueError("poses must be a finite (E >= 1, 8) array of poses")
            targets = dq.mul(dq.inv(fams.poses[0]), poses)
            score = np.sum(closest.closest_pose(c_rel[:, None], targets, inertia)[1], -1)
    out[ok] = np.where(code == 0, score, np.inf)
    return out


def _theta_to_mu(c0: float, theta: np.ndarray) -> np.ndarray:
    """``mu = c_0 + tan(theta)``, theta mod pi; ``theta = +-pi/2`` gives ``inf``."""
    edge = np.abs(np.cos(theta)) < 1e-15
    return np.where(edge, np.inf, c0 + np.tan(np.where(edge, 0.0, theta)))


def best_mu(fams: FourPoseFamilies, family: int, criterion: str, scan: int = 256,
            levels: int = 8, basins: int = 3, **params) -> tuple[float | None, float]:
    """``(mu, score)`` minimizing ``criterion`` over ``mu = c_0 + tan(theta)`` (``None`` = inf).

    ``scan`` equally spaced theta in ``[-pi/2, pi/2)`` (theta = -pi/2 is mu = inf); the
    ``basins`` lowest sampled local minima are refined together by ``levels`` zoom levels of 9
    points (each shrinks the bracket 4x: theta accurate to about ``pi / scan / 4**levels``).
    Raises NonGenericMotionError if no scanned mu gives a generic cubic.
    """
    if not all(isinstance(v, int) for v in (scan, levels, basins)) or scan < 8 or levels < 0 \
            or not 1 <= basins <= scan:
        raise ValueError("scan (>= 8), levels (>= 0) and basins (1..scan) must be ints")
    if family not in (0, 1):
        raise ValueError(f"family must be 0 or 1, got {family!r}")
    c0 = float(fams.c[family, 0])
    theta = -0.5 * np.pi + np.pi * np.arange(scan) / scan
    vals = score_mu(fams, family, _theta_to_mu(c0, theta), criterion, **params)
    if not np.any(np.isfinite(vals)):
        raise NonGenericMotionError(
            "no mu of this family gives a generic cubic (every scanned cubic has a real norm "
            "root, a repeated factor or a translational factor)", "real-root")
    local = (vals <= np.roll(vals, 1)) & (vals <= np.roll(vals, -1))  # theta is periodic
    j = np.argsort(np.where(local, vals, np.inf))[:basins]
    best_t, best_v, half = theta[j], vals[j], np.pi / scan
    for _ in range(levels):
        grid = best_t[:, None] + np.linspace(-half, half, 9)
        gv = score_mu(fams, family, _theta_to_mu(c0, grid.ravel()), criterion,
                      **params).reshape(grid.shape)
        i = np.argmin(gv, axis=-1)
        better = gv[np.arange(len(i)), i] < best_v
        best_t = np.where(better, grid[np.arange(len(i)), i], best_t)
        best_v = np.where(better, gv[np.arange(len(i)), i], best_v)
        half /= 4.0
    k = int(np.argmin(best_v))
    mu = float(_theta_to_mu(c0, best_t[k]))
    return (None if np.isinf(mu) else mu), float(best_v[k])
