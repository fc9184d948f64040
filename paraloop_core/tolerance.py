"""The one tolerance object of paraloop (cf. ``trimesh.tol``): every threshold lives here."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Tolerance:
    """Relative thresholds; each is applied to a quantity scaled by a stated reference size."""

    #: ``cosh(d) - 1`` (d the hyperbolic distance of two norm roots in the upper half plane, a
    #: Moebius invariant) above which float64 suspects a real root: a real double root splits by
    #: ~sqrt(eps) and looks like 1e8..1e16 here, so suspects are confirmed in high precision.
    real_separation: float = 1e8
    #: ``sinh(d / 2)`` below which float64 suspects a repeated norm quadratic. Loose on purpose:
    #: eigenvalues of a k-fold root scatter by ~eps**(1/k); suspects are confirmed likewise.
    repeated: float = 1e-4
    #: |P(r1)| / |r| below which the HSS remainder's leading coefficient counts as singular.
    singular: float = 1e-9
    #: |p| / (1 + |h|) below which a linear factor counts as a translation.
    translation: float = 1e-9
    #: |p| / |h_primal| of a joint factor (its norm root's distance from the real line over
    #: its size) below which float64 cannot evaluate the joint near its half turn: the norm
    #: ``(t - h0)^2 + |p|^2`` loses |p|^2 within ~100 eps of h0^2 (random generic designs:
    #: >= 6e-6), and the loop's axes there are rounding noise.
    resolved: float = 1e-7
    #: relative residual of products / Study condition accepted as exact.
    residual: float = 1e-7
    #: smallest / largest singular value of four relative poses (unit dual quaternions, dual
    #: parts scaled to O(1)) at or below which they span less than a 3-space. Their float64
    #: rounding moves singular values by ~1e-16 of the largest (Weyl), so anything above this
    #: is certainly of rank 4: the cubic exists, however ill-conditioned.
    rank: float = 1e-13
    #: relative residual (primal and dual parts each to their own size) of the product of the
    #: float64 factors above which they are refined by Newton steps: motions near a singular
    #: pose lose digits in HSS (2.6e-3 was seen), and the loop must still be the motion.
    factor_residual: float = 1e-10
    #: the same residual after Newton refinement above which the factorization is redone in
    #: high precision (the float64 motion violates the Study condition by ~1e-12, which the
    #: nearest product of exact rotations can amplify ~100-fold: 1e-10 is not always reachable).
    factor_exact: float = 1e-8
    #: max deviation of R R^T from the identity accepted as orthonormal (then re-orthonormalized).
    orthonormal: float = 1e-6
    #: relative metric distance below which two target poses count as the same pose.
    duplicate: float = 1e-9
    #: pitch / offset ratio of a relative pose below which it counts as a zero-pitch rotation.
    zero_pitch: float = 1e-10
    #: absolute zero for normalized quantities (degenerate geometry).
    zero: float = 1e-12


TOL = Tolerance()
