"""Object-dependent metric on poses (paper eq. 8, MATH section 7).

The moving body is represented by its inertia ellipsoid: centre ``c``, orthonormal axes
``e_k`` (rows of ``axes``), semi-axes ``a_k``, all in the body's frame at the reference pose
(design units). ``dist^2(S1, S2) = 1/6 sum_v |S1(v) - S2(v)|^2`` over the six vertices
``v = c +- w a_k e_k`` (``w`` = orientation weight: ``w > 1`` favours orientation).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from paraloop_core.algebra import dq, factor, poly
from paraloop_core.tolerance import TOL


@dataclass(frozen=True)
class Inertia:
    """Inertia ellipsoid: ``center`` (3,), ``axes`` (3, 3) rows ``e_k``, ``semi_axes`` (3,),
    ``weight`` (orientation weight w > 0)."""

    center: np.ndarray
    axes: np.ndarray
    semi_axes: np.ndarray
    weight: float = 1.0

    def __post_init__(self) -> None:
        c = np.asarray(self.center, dtype=np.float64)
        e = np.asarray(self.axes, dtype=np.float64)
        a = np.asarray(self.semi_axes, dtype=np.float64)
        if c.shape != (3,) or e.shape != (3, 3) or a.shape != (3,):
            raise ValueError("inertia needs center (3,), axes (3, 3) and semi_axes (3,)")
        if not (np.all(np.isfinite(c)) and np.all(np.isfinite(e)) and np.all(np.isfinite(a))):
            raise ValueError("inertia values must be finite")
        if np.any(a < 0) or np.all(a == 0):
            raise ValueError("inertia semi-axes must be >= 0 and not all zero")
        if not np.allclose(e @ e.T, np.eye(3), atol=TOL.orthonormal):
            raise ValueError("inertia axes must be orthonormal rows")
        u, _, vt = np.linalg.svd(e)
        e = u @ vt  # the nearest orthonormal matrix: rounding in files must not skew eq. 8
        if not (np.isfinite(self.weight) and self.weight > 0):
            raise ValueError("orientation weight must be a positive number")
        object.__setattr__(self, "center", c)
        object.__setattr__(self, "axes", e)
        object.__setattr__(self, "semi_axes", a)

    @property
    def vertices(self) -> np.ndarray:
        """The six (weighted) ellipsoid vertices ``(6, 3)``: ``c +- w a_k e_k``."""
        d = self.weight * self.semi_axes[:, None] * self.axes
        return self.center + np.concatenate([d, -d], axis=0)

    def with_weight(self, weight: float) -> Inertia:
        return Inertia(self.center, self.axes, self.semi_axes, float(weight))


def sphere(radius: float = 1.0, center: np.ndarray | None = None) -> Inertia:
    """Inertia sphere of the given radius (the paper's validation uses radius 1)."""
    c = np.zeros(3) if center is None else center
    return Inertia(np.asarray(c, float), np.eye(3), np.full(3, float(radius)))


def inertia_from_points(points: np.ndarray, weights: np.ndarray | None = None) -> Inertia:
    """Ellipsoid with the same mean squared displacement as a point set ``(N, 3)``:
    ``c`` = centroid, ``a_k = sqrt(3 lambda_k)`` of the (weighted) covariance (MATH section 7)."""
    x = np.asarray(points, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 3 or len(x) < 2 or not np.all(np.isfinite(x)):
        raise ValueError("points must be a finite (N >= 2, 3) array")
    w = np.ones(len(x)) if weights is None else np.asarray(weights, dtype=np.float64)
    w = w / w.sum()
    c = w @ x
    cov = (x - c).T @ ((x - c) * w[:, None])
    lam, vec = np.linalg.eigh(cov)
    return Inertia(c, vec.T, np.sqrt(3.0 * np.clip(lam, 0.0, None)))


def inertia_from_mesh(vertices: np.ndarray, faces: np.ndarray) -> Inertia:
    """Ellipsoid of a closed triangle mesh's solid (uniform density), exact for eq. 8."""
    import trimesh  # local: only this function needs it

    mesh = trimesh.Trimesh(np.asarray(vertices, float), np.asarray(faces, int), process=True)
    if not mesh.is_watertight or mesh.volume <= 0:
        raise ValueError("mesh must be closed (watertight) with positive volume")
    inertia = mesh.moment_inertia / mesh.mass  # about the centre of mass
    cov = 0.5 * np.trace(inertia) * np.eye(3) - inertia  # second moment of the solid
    lam, vec = np.linalg.eigh(cov)
    return Inertia(mesh.center_mass, vec.T, np.sqrt(3.0 * np.clip(lam, 0.0, None)))


def distance_sq(s1: np.ndarray, s2: np.ndarray, inertia: Inertia) -> np.ndarray:
    """Squared metric distance ``(...)`` between poses ``(..., 8)`` (any nonzero scale).

    Closed form of eq. 8 with ``G = S1~ S2``:
    ``4/|G_P|^2 [g0'^2 + |g' + g x c|^2 + 1/3 sum_k (w a_k)^2 |g x e_k|^2]``.
    """
    s1 = dq.normalize(s1)
    g = dq.mul(dq.conj(s1), np.asarray(s2, dtype=np.float64))
    gv, gd0, gdv = g[..., 1:4], g[..., 4], g[..., 5:8]
    lin = gdv + np.cross(gv, inertia.center)
    a2 = (inertia.weight * inertia.semi_axes) ** 2
    rot = np.cross(gv[..., None, :], inertia.axes)  # (..., 3, 3): g x e_k
    bracket = gd0**2 + np.sum(lin**2, -1) + np.sum(a2 * np.sum(rot**2, -1), -1) / 3.0
    return 4.0 * bracket / np.sum(g[..., :4] ** 2, -1)


def motion_length(c: np.ndarray, inertia: Inertia, samples: int = 192) -> np.ndarray:
    """Length ``(...)`` of the closed motion cycle of ``C`` ``(..., n+1, 8)`` under the metric.

    Approximation: chord sum (a lower bound of the arc length) over ``samples`` parameters
    adapted to the motion (:func:`poly.cycle_parameters` of the norm factors) plus ``t = inf``;
    relative error about 1e-3 at the default for generic cubics.
    """
    c = np.asarray(c, dtype=np.float64)
    n = c.shape[-2] - 1
    if samples < 8 * n:
        raise ValueError(f"motion_length needs at least {8 * n} samples, got {samples}")
    quads, _ = factor.norm_quadratics_batch(c)
    h0 = -0.5 * quads[..., 1]
    r = np.sqrt(np.maximum(quads[..., 0] - h0**2, 0.0))
    t = poly.cycle_parameters(h0, r, samples // n)
    inf = np.full(t.shape[:-1] + (1,), np.inf)
    poses = poly.evaluate_pose(c[..., None, :, :], np.concatenate([inf, t, inf], axis=-1))
    return np.sum(np.sqrt(distance_sq(poses[..., :-1, :], poses[..., 1:, :], inertia)), -1)
