"""The Bennett 4R loop of a generic monic quadratic (MATH section 4) and its kinematics.

The two factorizations ``C = (t - h1)(t - h2) = (t - k1)(t - k2)`` of a monic quadratic
(:func:`factor.quadratic_factorizations`, one Bennett flip apart) close a 4R loop, laid out as
the 6R loops of :mod:`loops` with two factors per side instead of three: the four **joint
factors** ``(..., 4, 8)`` are ``[h1, h2, k2, k1]``, axis ``A_i`` (home configuration t = inf,
base frame) the rotation axis of joint factor i. Link i lies between ``A_{i-1}`` and ``A_i``;
link 0 is the base, link 2 the end link. Link poses in the base frame:
``L_0 = 1, L_1 = t - h1, L_2 = C, L_3 = t - k1``. The forward joint factors
``t - h1, t - h2, t - k2~, t - k1~`` multiply to ``C C~``, a real polynomial: the loop closes.

Singularity: the four axes at t, unit Pluecker rows of ``J(t)`` ``(4, 6)``, are linearly dependent
for every t (the loop moves); ``S(t)`` is the sum of the squared 3x3 minors of J (moments divided
by ``length``), ``e_3`` of the eigenvalues of ``J J^T`` (Cauchy-Binet), zero iff the rank drops
to 2 (a second degree of freedom, as in a planar or spherical 4R).
"""

from __future__ import annotations

import numpy as np

from paraloop_core.algebra import dq, poly
from paraloop_core.algebra.factor import Factorizations
from paraloop_core.linkage.loops import Loop, factor_axes

KIND = "Bennett"
#: Which link pose carries axis i (A_i is fixed in links i and i+1).
_AXIS_LINK = np.array([0, 1, 3, 0])
#: The four 3x3 principal submatrices of a 4x4 matrix (rows = columns, each leaving one out).
_THREE = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])


def _check(joint_factors: np.ndarray) -> np.ndarray:
    jf = np.asarray(joint_factors, dtype=np.float64)
    if jf.ndim < 2 or jf.shape[-2:] != (4, 8):
        raise ValueError(f"Bennett joint factors must have shape (..., 4, 8), got {jf.shape}")
    if not np.isfinite(jf).all():
        raise ValueError("joint factors must be finite")
    return jf


def loop_joint_factors(factors: np.ndarray) -> np.ndarray:
    """Joint factors ``(..., 4, 8)`` ``[h1, h2, k2, k1]`` of a quadratic's two factorizations
    ``(..., 2, 2, 8)`` (``[[h1, h2], [k1, k2]]``)."""
    f = np.asarray(factors, dtype=np.float64)
    if f.ndim < 3 or f.shape[-3:] != (2, 2, 8):
        raise ValueError(f"factorizations must have shape (..., 2, 2, 8), got {f.shape}")
    return np.concatenate([f[..., 0, :, :], f[..., 1, ::-1, :]], axis=-2)


def bennett_loops(facts: Factorizations) -> list[Loop]:
    """The one loop (``kind`` :data:`KIND`, factorizations ``(0, 1)``) of one quadratic's
    factorizations (unbatched ``facts``)."""
    return [Loop(loop_joint_factors(facts.factors), KIND, (0, 1))]


def link_poses(joint_factors: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Poses ``(..., T, 4, 8)`` (homogeneous, not unit) of the four links in the base frame."""
    jf = _check(joint_factors)
    t = np.atleast_1d(np.asarray(t, dtype=np.float64))
    lin = poly.evaluate_pose(poly.linear(jf)[..., None, :, :], t)  # (..., 4, T, 8)
    one = np.broadcast_to(dq.IDENTITY, lin[..., 0, :, :].shape)
    return np.stack([one, lin[..., 0, :, :], dq.mul(lin[..., 0, :, :], lin[..., 1, :, :]),
                     lin[..., 3, :, :]], axis=-2)


def axes_at(joint_factors: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Unit Pluecker axes ``(..., T, 4, 6)`` of the loop in the base frame at parameters ``t``
    (inf = home)."""
    poses = link_poses(joint_factors, t)[..., _AXIS_LINK, :]
    return dq.transform_lines(poses, factor_axes(_check(joint_factors))[..., None, :, :])


def singularity_curve(joint_factors: np.ndarray, t: np.ndarray,
                      length: float = 1.0) -> np.ndarray:
    """``S(t)`` ``(..., T)`` (module docstring) of loops ``(..., 4, 8)`` at ``t`` ``(T,)``."""
    if not (np.isfinite(length) and length > 0):
        raise ValueError(f"length must be a positive number, got {length!r}")
    j = axes_at(joint_factors, t) * np.array([1.0, 1, 1, 1 / length, 1 / length, 1 / length])
    gram = j @ j.swapaxes(-1, -2)  # (..., T, 4, 4)
    return np.linalg.det(gram[..., _THREE[:, :, None], _THREE[:, None, :]]).sum(axis=-1)


def singularity_min(joint_factors: np.ndarray, samples: int = 64, levels: int = 6,
                    basins: int = 8, length: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """``(min S, t at the min)`` ``(...)`` over the cycle of loops ``(..., 4, 8)``: home and,
    per norm factor ``(t - h0)^2 + r^2`` of the loop's quadratic, the ``samples`` t where its
    rotation angle is uniform (:func:`poly.cycle_parameters`); the ``basins`` lowest sampled
    local minima are refined by ``levels`` zoom levels of 9 points in ``u``
    (:func:`poly.param_to_t`) from their neighbouring samples, shrinking 4x per level. A basin
    narrower than the sample spacing (no sampled local minimum) can be missed."""
    jf = _check(joint_factors)
    if not all(isinstance(v, int) for v in (samples, levels, basins)) or samples < 4 \
            or levels < 0 or basins < 1:
        raise ValueError("samples (>= 4), levels (>= 0) and basins (>= 1) must be integers, "
                         f"got {samples!r}, {levels!r}, {basins!r}")
    flat = jf.reshape(-1, 4, 8)
    best = np.array([_min_one(f, samples, levels, basins, length) for f in flat])  # (L, 2)
    return (best[:, 1].reshape(jf.shape[:-2]),
            poly.param_to_t(best[:, 0]).reshape(jf.shape[:-2]))


def _min_one(jf: np.ndarray, samples: int, levels: int, basins: int, length: float
             ) -> tuple[float, float]:
    """``(u, S)`` of :func:`singularity_min` for one loop ``(4, 8)``."""
    r = np.sqrt((jf[:2, 1:4] ** 2).sum(-1))
    t = poly.cycle_parameters(jf[:2, 0], r, samples)  # sorted and finite: u in (0, 1) sorted
    u = np.concatenate([[0.0], poly.t_to_param(t)])  # u = 0: home, also u = 1
    vals = singularity_curve(jf, poly.param_to_t(u), length)
    ring = np.concatenate([vals[-1:], vals, vals[:1]])  # periodic neighbours
    local = np.flatnonzero((vals <= ring[:-2]) & (vals <= ring[2:]))
    k = local[np.argsort(vals[local])[:basins]]  # (B,), at least the global sampled minimum
    ring_u = np.concatenate([u[-1:] - 1.0, u, [1.0]])
    lo, hi = ring_u[k], ring_u[k + 2]  # the neighbouring samples
    best_u, best_s = u[k], vals[k]
    for _ in range(levels):
        grid = np.linspace(lo, hi, 9, axis=-1)  # (B, 9)
        gv = singularity_curve(jf, poly.param_to_t(grid.ravel() % 1.0), length).reshape(
            grid.shape)
        i = np.argmin(gv, axis=-1)
        v = gv[np.arange(len(k)), i]
        best_u = np.where(v < best_s, grid[np.arange(len(k)), i], best_u)
        best_s = np.minimum(v, best_s)
        step = (hi - lo) / 8
        lo, hi = best_u - step, best_u + step
    j = int(np.argmin(best_s))
    return float(best_u[j] % 1.0), float(best_s[j])
