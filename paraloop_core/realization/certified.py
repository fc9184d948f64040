"""A certified realization (paper Sec. 5.1) and its Sec. 5.2 design-space radii.

:class:`Realization` is what :mod:`realize` (and :mod:`realize_ee`) return: the polyline, its
proven pair bounds over the whole cycle, and the informational consecutive-bar bounds
(:func:`joint_bounds`, computed on first use).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from paraloop_core.realization import verify
from paraloop_core.realization.offsetting import OFFSET_PAIRS


def joint_bounds(jf: np.ndarray, points: np.ndarray, pairs: np.ndarray, length: float
                 ) -> verify.PairBounds:
    """Proven lower bounds of consecutive bars ``pairs`` (rows of
    :data:`verify.JOINT_PAIRS`). Reported, not required: the paper's model (and so the search)
    lets two links meet at their common joint, where the joint hardware separates them; a
    value below 2 rho says the bars' cylinders overlap near that joint."""
    return verify.polyline_bounds(jf, points, pairs, 1e-3 * length)


@dataclass(frozen=True)
class Realization:
    """A collision-free realization (all coordinates: base frame, home configuration t = inf).

    ``points`` ``(12, 3)``: ``S_0, E_0, ..., S_5, E_5`` (S_i on ``A_{i-1}``, E_i on ``A_i``);
    edge e joins points e and e+1 (mod 12): bar ``S_iE_i`` of link i (e = 2i), pin ``E_iS_{i+1}``
    on ``A_i`` (e = 2i+1). ``radius`` rho and ``separation`` d in design units; ``length`` l of
    the initial polyline; ``shifts`` ``(6,)`` tau in ``{-k, 0, k}`` (shift = tau l / p; any
    integers of at most k for a :mod:`roomy` one);
    ``offsets`` ``(6,)`` in ``{+1, -1, 0}``; ``thin_initial``/``thin`` ``(6, 3)`` the step-1 and
    step-3 polylines; ``pairs`` ``(42, 4)`` rows (edge 1, edge 2, fixed link, moving link);
    ``pair_distance`` ``(42,)`` exact minima over the cycle at ``pair_t`` (inf = home);
    ``design_space_radii`` ``(6,)``; ``stats`` the search counters; ``search_loop`` the loop
    the search certified and this realization's length unit in its units (:attr:`joint_lower`
    is bounded there, as the pairs were).
    """

    joint_factors: np.ndarray
    points: np.ndarray
    radius: float
    separation: float
    length: float
    p: float
    shifts: np.ndarray
    offsets: np.ndarray
    thin_initial: np.ndarray
    thin: np.ndarray
    pairs: np.ndarray
    pair_distance: np.ndarray
    pair_t: np.ndarray
    design_space_radii: np.ndarray
    stats: dict
    pair_lower: np.ndarray
    joint_pairs: np.ndarray
    tolerance: float
    #: proven bound of how far the loop's two float64 readings place a point (:mod:`closure`),
    #: already taken off ``pair_lower`` and ``joint_lower``
    reading_gap: float = 0.0
    search_loop: tuple[np.ndarray, float] | None = field(default=None, repr=False,
                                                         compare=False)

    @cached_property
    def joint_lower(self) -> np.ndarray:
        """Proven lower bounds ``(len(joint_pairs),)`` (design units) of the consecutive bars
        over the cycle (:func:`joint_bounds`, reading gap off). Computed on first use: the
        certificate does not need them, and they cost a third of it (a drag's release)."""
        jf, unit = self.search_loop or (self.joint_factors, 1.0)
        bounds = joint_bounds(jf, self.points / unit, self.joint_pairs, self.length / unit)
        return bounds.lower * unit - self.reading_gap

    def scaled(self, factor: float, joint_factors: np.ndarray) -> Realization:
        """The same realization in a length unit ``1 / factor`` times this one's, on
        ``joint_factors`` (the loop in that unit): every length times ``factor``."""
        f = float(factor)
        loop, unit = self.search_loop or (self.joint_factors, 1.0)
        return replace(self, joint_factors=joint_factors, points=self.points * f,
                       radius=self.radius * f, separation=self.separation * f,
                       length=self.length * f, thin_initial=self.thin_initial * f,
                       thin=self.thin * f, pair_distance=self.pair_distance * f,
                       design_space_radii=self.design_space_radii * f,
                       pair_lower=self.pair_lower * f, tolerance=self.tolerance * f,
                       reading_gap=self.reading_gap * f,
                       search_loop=(loop, unit * f))

    @property
    def min_clearance(self) -> float:
        """Smallest centre-line distance over the checked pairs and the cycle (>= 2 radius)."""
        return float(self.pair_distance.min())

    @property
    def certified_clearance(self) -> float:
        """Proven lower bound of every certified centre-line distance over the cycle
        (>= 2 radius); the consecutive bars are reported apart (``joint_lower``)."""
        return float(self.pair_lower.min())


#: ``(42, 2)``: link of each bar of the :data:`offsetting.OFFSET_PAIRS` rows (-1 for pins).
_PAIR_BARS = np.where(OFFSET_PAIRS[:, :2] % 2 == 0, OFFSET_PAIRS[:, :2] // 2, -1)


def design_space_radii(dist: np.ndarray, rho: float, bars: np.ndarray = _PAIR_BARS,
                       mesh: np.ndarray | None = None) -> np.ndarray:
    """Largest cylinder radius ``(6,)`` about each bar that stays collision-free (Sec. 5.2)
    from the minimum distances ``dist`` ``(N,)`` of rows whose two parts are the bars of links
    ``bars`` ``(N, 2)`` (-1 for a pin or P; default: the rows of
    :data:`offsetting.OFFSET_PAIRS`): two bars share their distance equally, against a pin
    (radius rho) a bar gets ``D - rho``, against P (rows in ``mesh``) all of D."""
    radii = np.full(6, np.inf)
    mesh = np.zeros(len(dist), dtype=bool) if mesh is None else mesh
    for me, other in ((0, 1), (1, 0)):
        bar = bars[:, me]
        cap = np.where(bars[:, other] >= 0, dist / 2.0, np.where(mesh, dist, dist - rho))
        np.minimum.at(radii, bar[bar >= 0], cap[bar >= 0])
    return radii
