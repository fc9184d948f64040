"""The one tolerance object of paraloop (cf. ``trimesh.tol``): every threshold lives here."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Tolerance:
    """Relative thresholds; each is applied to a quantity scaled by a stated reference size."""

    #: |Im z| / (1 + |z|) below which a root of the norm polynomial counts as real.
    root_imag: float = 1e-7
    #: relative distance below which two norm quadratics count as equal (repeated factor).
    #: Loose on purpose: eigenvalues of a k-fold root scatter by ~eps**(1/k) (6e-6 for k = 3).
    repeated: float = 1e-4
    #: |P(r1)| / |r| below which the HSS remainder's leading coefficient counts as singular.
    singular: float = 1e-9
    #: |p| / (1 + |h|) below which a linear factor counts as a translation.
    translation: float = 1e-9
    #: relative residual of products / Study condition accepted as exact.
    residual: float = 1e-7
    #: max deviation of R R^T from the identity accepted as orthonormal (then re-orthonormalized).
    orthonormal: float = 1e-6
    #: relative metric distance below which two target poses count as the same pose.
    duplicate: float = 1e-9
    #: absolute zero for normalized quantities (degenerate geometry).
    zero: float = 1e-12


TOL = Tolerance()
