"""Roomy realizations for printing (beyond the paper): shifts chosen for room, not length.

The paper's search (:mod:`realize`) takes the *shortest* collision-free polyline and then
offsets and thickens it: right for thin bars, but a printed loop needs millimetres between its
links at a size that fits a printer's bed, that is room *per extent* of the polyline. Many
loops whose shortest polylines pass close to each other somewhere in the cycle have polylines
with ten times the room a little further out along the axes.

:func:`screen` draws shift vectors at random (seeded: the same loop always gets the same draws)
at :data:`SCALES` of the initial polyline's length l and scores each thin polyline by its
*sampled* clearance over the cycle per extent. Where a collision-free polyline of the loop is
known (the design's own realization), draws close round it (:data:`LOCAL_SCALES`) make a second
set: on many loops the free polylines fill a narrow region that the wide draws miss (random
designs 62200 - 62239, on the design's loop: the best score of the wide draws 0 on 6 designs,
of the close ones 0.014 - 0.050; better on 28 of 39, 1.5 times or more on 12). The sampled
minimum is an upper bound of the true one, so the score only orders the candidates; nothing is
concluded from it. The best are ranked by their exact clearance, or less where the two bars
meeting at a joint, split by the pin, come closer as it turns (:func:`joint_clearance`: on
random designs those bars were the pair that kept the printed bars thin).
:func:`realize_roomy` then realizes the best ones exactly as the paper's search does its own:
the exact thin check (step 3), step 4 over the offset sequences with exact minima, and the
sound bounds of :mod:`verify` (:meth:`realize.Search.run_hint`): the certificate is the same.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from paraloop_core.errors import RealizationError
from paraloop_core.realization.certified import Realization
from paraloop_core.realization.clearance import min_distance_batch, segment_distance
from paraloop_core.realization.collision import (
    THIN_PAIRS,
    colliding_polylines,
    polyline_segments,
)
from paraloop_core.realization.offsetting import OFFSET_PAIRS, LoopMotions
from paraloop_core.realization.realize import Search

#: Shift ranges drawn, as shares of the initial polyline's length l (each axis's vertex moves
#: uniformly within +- share l), and draws per range.
SCALES = (0.1, 0.2, 0.4, 0.8)
DRAWS = 192
#: Shift ranges (shares of l) and draws per range round a known collision-free polyline.
LOCAL_SCALES = (0.02, 0.05, 0.1, 0.2)
LOCAL_DRAWS = 96
#: The best screened polylines given the exact thin check, and how many of the
#: collision-free ones among them then get their clearance computed exactly (their order).
CHECKED, EXACT = 48, 12
#: Shift quantum ``l / FINE_P``: the draws as integer steps, like the paper's ``tau l / p``.
FINE_P = 1000
#: Bar radius of the search as a share of the thin polyline's sampled clearance (the offsets
#: and thick bars take the rest); the printed parts are sized on the certified bounds anyway.
RHO_SHARE = 0.3
#: Offset sequences the sound check may refute per polyline before the next is tried (near
#: a singular pose the exact minima can pass sequence after sequence the bounds cannot prove).
REFUTATIONS = 4
#: Angles of a joint's turn at which :func:`joint_clearance` measures its two bars.
TURN_SAMPLES = 36
#: Rows of the nine thin pairs (bar i, bar j) among the 42 offset pairs.
_THIN_ROWS = np.array([int(np.flatnonzero((OFFSET_PAIRS[:, 0] == 2 * i) &
                                          (OFFSET_PAIRS[:, 1] == 2 * j))[0])
                       for i, j in THIN_PAIRS])


def sampled_clearance(lp: LoopMotions, polys: np.ndarray) -> np.ndarray:
    """Least distance ``(C,)`` between non-adjacent segments of thin polylines ``(C, 6, 3)``
    at the sampled poses of ``lp`` (an upper bound of the true minimum over the cycle)."""
    i = np.array([a for a, _ in THIN_PAIRS])
    j = np.array([b for _, b in THIN_PAIRS])
    prev = np.roll(polys, 1, axis=1)
    rot, trans = lp.rot[_THIN_ROWS], lp.trans[_THIN_ROWS]  # (9, T, 3, 3), (9, T, 3)
    b0 = np.einsum("ptab,cpb->cpta", rot, prev[:, j]) + trans  # (C, 9, T, 3)
    b1 = np.einsum("ptab,cpb->cpta", rot, polys[:, j]) + trans
    dist = segment_distance(prev[:, i, None], polys[:, i, None], b0, b1)  # (C, 9, T)
    return dist.min(axis=(1, 2))


def exact_clearance(lp: LoopMotions, polys: np.ndarray) -> np.ndarray:
    """Exact least distance ``(C,)`` between non-adjacent segments of thin polylines
    ``(C, 6, 3)`` over the whole cycle (0 where two meet: the polyline collides)."""
    segs = polyline_segments(polys)
    out = np.full(len(polys), np.inf)
    if len(polys) == 0:
        return out
    for degree in sorted({md.degree for md, _ in lp.thin}):
        group = [k for k in range(len(THIN_PAIRS)) if lp.thin[k][0].degree == degree]
        cand = np.repeat(np.arange(len(polys)), len(group))
        pairs = np.tile(group, len(polys))
        first = np.array([THIN_PAIRS[k][0] for k in pairs])
        second = np.array([THIN_PAIRS[k][1] for k in pairs])
        index = np.array([lp.thin[k][1] for k in pairs])
        dist, _ = min_distance_batch(lp.thin[group[0]][0], index, segs[cand, first],
                                     segs[cand, second])
        out = np.minimum(out, dist.reshape(len(polys), len(group)).min(axis=1))
    return out


def joint_clearance(u: np.ndarray, polys: np.ndarray, pin: np.ndarray) -> np.ndarray:
    """Estimated least distance ``(C,)`` between the two bars that meet at each joint of thin
    polylines ``(C, 6, 3)`` (axis directions ``u`` ``(6, 3)``) once their vertices are split
    into pins of length ``pin`` ``(C,)``: the bar leaning further along the axis at the upper
    end (as step 4's first offsets put it), the other bar turned a whole turn about the axis
    (a joint of the cycle turns once), at :data:`TURN_SAMPLES` angles. It only orders
    candidates (the offsets step 4 takes may differ); nothing is concluded from it."""
    bar_in = np.roll(polys, 1, axis=1) - polys  # (C, 6, 3): link i's bar from V_i
    bar_out = np.roll(polys, -1, axis=1) - polys  # link i+1's bar
    up = _cosine(bar_out, u) >= _cosine(bar_in, u)
    half = np.where(up, 0.5, -0.5) * pin[:, None]  # (C, 6): bar_out's end of the pin
    a0 = polys - half[..., None] * u
    b0 = polys + half[..., None] * u
    theta = np.linspace(0.0, 2.0 * np.pi, TURN_SAMPLES, endpoint=False)
    c, s = np.cos(theta)[:, None], np.sin(theta)[:, None]
    along = np.sum(bar_out * u, -1, keepdims=True) * u  # (C, 6, 3)
    across, side = bar_out - along, np.cross(u, bar_out)
    turned = along[..., None, :] + c * across[..., None, :] + s * side[..., None, :]
    dist = segment_distance(a0[..., None, :], (a0 + bar_in)[..., None, :], b0[..., None, :],
                            b0[..., None, :] + turned)  # (C, 6, K)
    return dist.min(axis=(1, 2))


def _cosine(bar: np.ndarray, u: np.ndarray) -> np.ndarray:
    return np.sum(bar * u, -1) / np.maximum(np.linalg.norm(bar, axis=-1), 1e-300)


@dataclass(frozen=True, eq=False)
class Draws:
    """One loop's drawn thin polylines (:func:`draw`): its ``search`` and motions ``lp``,
    integer shifts ``tau`` ``(C, 6)`` (steps of ``l / FINE_P``), vertices ``polys``
    ``(C, 6, 3)``, their ``extent`` ``(C,)`` and sampled clearance per extent ``sampled``."""

    search: Search
    lp: LoopMotions
    tau: np.ndarray
    polys: np.ndarray
    extent: np.ndarray
    sampled: np.ndarray

    @property
    def promise(self) -> float:
        """The best sampled clearance per extent: cheap, an upper bound of what
        :func:`screen` finds, to order loops before screening them."""
        return float(self.sampled.max())


def draw(joint_factors: np.ndarray, fixed: dict[int, float] | None, in_unit: float,
         seed: int = 0, center: np.ndarray | None = None) -> Draws:
    """The :class:`Draws` of the loop ``joint_factors`` ``(6, 8)``; held vertices (the
    design's ``fixed``) are not shifted. With ``center`` ``(6,)``, integer shifts (steps of
    ``l / FINE_P``) of a collision-free polyline of the loop: the draws close round it
    (:data:`LOCAL_SCALES`) instead of the wide ones."""
    search = Search(joint_factors, fixed, in_unit)
    lp = LoopMotions(search.jf)
    v0, length = search.initial()
    rng = np.random.default_rng(seed)
    if center is None:
        draws = np.concatenate([rng.uniform(-s, s, (DRAWS, 6)) for s in SCALES])
    else:
        draws = np.concatenate([rng.uniform(-s, s, (LOCAL_DRAWS, 6)) for s in LOCAL_SCALES])
    tau = np.rint(draws * FINE_P).astype(int) + (0 if center is None else
                                                  np.asarray(center, int))
    for i in search.fixed or {}:
        tau[:, i] = 0
    polys = v0 + (tau * length / FINE_P)[..., None] * lp.u
    extent = np.ptp(polys, axis=1).max(axis=1)
    return Draws(search, lp, tau, polys, extent, sampled_clearance(lp, polys) / extent)


def screen(d: Draws, pin: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Up to :data:`EXACT` of the drawn thin polylines ``d``, collision-free, best first:
    their indices ``(C,)`` into ``d``, scores ``(C,)`` (per extent: the exact clearance, or
    the joints' bars' with pins of ``pin`` of the extent where less) and exact clearances
    per extent ``(C,)``. The draws are ranked by their sampled clearance (cheap), the
    :data:`CHECKED` best get the exact thin check, the first :data:`EXACT` free ones their
    scores."""
    keep = np.argsort(-d.sampled, kind="stable")[:CHECKED]
    keep = keep[~colliding_polylines(d.lp.thin, d.polys[keep])][:EXACT]
    thin = exact_clearance(d.lp, d.polys[keep]) / d.extent[keep]
    score = np.minimum(thin, joint_clearance(d.lp.u, d.polys[keep], pin * d.extent[keep])
                       / d.extent[keep])
    order = np.argsort(-score, kind="stable")
    return keep[order], score[order], thin[order]


def realize_roomy(d: Draws, *, pin: float, tries: int = 4) -> Realization:
    """A certified realization (:class:`Realization`, as :func:`realize.realize`'s) of the
    loop of ``d`` on one of the ``tries`` best screened polylines, with joint offsets
    ``d = pin x`` the polyline's extent; raises :class:`RealizationError` (``cap-reached``)
    when none of them is certified."""
    search = d.search
    index, _, thin = screen(d, pin)
    for k, sc in zip(index[:tries], thin[:tries], strict=True):
        if not sc > 0:  # no room at all (the thin polyline touches itself)
            continue
        sep = pin * d.extent[k]
        rho = min(RHO_SHARE * sc * d.extent[k], sep / 2)
        real = search.run_hint(d.tau[k], None, p=FINE_P, rho=rho * search.unit,
                               d=sep * search.unit, d_fraction=0.0, rho_fraction=0.0,
                               max_k=int(np.abs(d.tau[k]).max()) or 1,
                               refutations=REFUTATIONS)
        if real is not None:
            return real
    if not len(index):
        raise RealizationError("none of the polylines drawn for this loop that the screen "
                               "checked is collision-free", "cap-reached")
    raise RealizationError(f"none of the {min(tries, len(index))} roomiest collision-free "
                           "polylines drawn for this loop stays collision-free with its "
                           "offsets and bars", "cap-reached")
