"""Step 4 of the realization (paper Sec. 5.1): offsetting and thickening, exact clearance.

On each axis ``A_i`` the vertices ``E_i`` (link i) and ``S_{i+1}`` (link i+1) of the thin vertex
``V_i`` are separated by d. Offset ways at axis i (our reading of Fig. 8): of the two bars
meeting at ``V_i``, the *orange* one encloses the smaller angle with ``+u_i`` (bar oriented away
from ``V_i``; ties: link i+1). It is stacked on the ``+u_i`` side so the two bars never cross
near the joint. Way +1: orange at ``V_i + d u_i``, blue at ``V_i``; way -1: orange at ``V_i``,
blue at ``V_i - d u_i``; way 0: orange at ``V_i + d/2 u_i``, blue at ``V_i - d/2 u_i``.

The 3^6 sequences are tried in the paper's order (all zeros, the sign pattern of the shift, then
the rest by base-3 index) and one is accepted when the exact minimum distance of all 42 edge
pairs (MATH §12) is >= 2 rho. A sequence is rejected early when a sampled distance (an upper
bound of the minimum) is below 2 rho; acceptance always uses the exact minimum. Each pair's
distance depends on at most four offset digits, so values are cached per (pair, digits).
"""

from __future__ import annotations

import itertools

import numpy as np

from paraloop_core.algebra import poly
from paraloop_core.realization.clearance import (
    SAMPLE_U,
    MotionData,
    PairMotions,
    min_distance_batch,
    segment_distance,
    segments_at,
)
from paraloop_core.realization.collision import THIN_PAIRS
from paraloop_core.realization.polyline import axis_frames

#: Offset way of each base-3 digit.
OFFSET_WAYS = np.array([0, 1, -1])
#: Fraction of ``d`` by which the orange vertex sits above ``V_i``, per digit (ways 0, +1, -1).
_ORANGE_LIFT = np.array([0.5, 1.0, 0.0])
#: Digits ``(6,)`` of the 729 sequences / the 3^6 shift patterns, axis 0 most significant.
DIGITS = np.array(list(itertools.product(range(3), repeat=6)))
#: Golden-section steps refining each sampled minimum (keeps it a true distance: an upper bound).
_REFINE_STEPS = 12


def cyclic_distance(a: int, b: int) -> int:
    """Steps between links (or axes) a and b around the six-cycle."""
    return min((b - a) % 6, (a - b) % 6)


def _edge_links(e: int) -> tuple[int, ...]:
    """Links carrying edge e: bar i (e = 2i) is link i, pin i (e = 2i+1) is links i and i+1."""
    i = e // 2
    return (i,) if e % 2 == 0 else (i, (i + 1) % 6)


def _offset_pairs() -> np.ndarray:
    """The 42 checked edge pairs ``(e1, e2, link1, link2)`` (MATH §12 reading)."""
    out = []
    for e1, e2 in itertools.combinations(range(12), 2):
        adjacent = (e2 - e1) % 12 in (1, 11)
        # consecutive bars are separated by the offset, consecutive pins share a link
        consecutive = e1 % 2 == e2 % 2 and cyclic_distance(e1 // 2, e2 // 2) == 1
        if adjacent or consecutive:
            continue
        la, lb = min(((a, b) for a in _edge_links(e1) for b in _edge_links(e2)),
                     key=lambda ab: (cyclic_distance(*ab), ab))
        out.append((e1, e2, la, lb))
    assert len(out) == 42
    return np.array(out)


#: ``(42, 4)``: edge 1, edge 2 (edge e joins points e and e+1 mod 12), fixed link, moving link.
OFFSET_PAIRS = _offset_pairs()
#: Vertex v of the 12-polyline lies on axis ``V_AXIS[v]``; slot 0 = E_i, slot 1 = S_{i+1}.
V_AXIS = np.array([((v // 2) - 1) % 6 if v % 2 == 0 else v // 2 for v in range(12)])
_V_SLOT = np.array([1 if v % 2 == 0 else 0 for v in range(12)])


def _items() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distinct pair geometries: ``pair (I,)``, ``vertex refs (I, 4)`` into the flat vertex
    table ``(axis, digit, slot)``, and ``seq_items (729, 42)``."""
    pair_of, refs, seq_items, start = [], [], np.zeros((729, 42), int), 0
    for p, (e1, e2, _, _) in enumerate(OFFSET_PAIRS):
        verts = np.array([e1, (e1 + 1) % 12, e2, (e2 + 1) % 12])
        axes = np.unique(V_AXIS[verts])
        for code in itertools.product(range(3), repeat=len(axes)):
            dig = dict(zip(axes.tolist(), code, strict=True))
            refs.append([(a * 3 + dig[a]) * 2 + s for a, s in zip(V_AXIS[verts], _V_SLOT[verts],
                                                                     strict=True)])
            pair_of.append(p)
        weights = 3 ** np.arange(len(axes) - 1, -1, -1)  # itertools.product order
        seq_items[:, p] = start + DIGITS[:, axes] @ weights
        start += 3 ** len(axes)
    return np.array(pair_of), np.array(refs), seq_items


_ITEM_PAIR, _ITEM_REFS, _SEQ_ITEMS = _items()


class LoopMotions:
    """Per-loop data shared by all candidates of all k: axis directions ``u`` ``(6, 3)``, the
    relative motions of the 42 pairs grouped by degree (``groups``, ``pair_group``,
    ``pair_index``), the nine thin pairs' ``(data, index)`` and the sampled poses."""

    def __init__(self, jf: np.ndarray):
        _, self.u = axis_frames(jf)
        keys = [(int(a), int(b)) for a, b in OFFSET_PAIRS[:, 2:]]
        # exact kernels batch pairs of one degree k: group index and position per pair
        mot = PairMotions(jf, keys)
        self.groups: dict[int, MotionData] = mot.groups
        where = np.array([mot.where[key] for key in keys])
        self.pair_group, self.pair_index = where[:, 0], where[:, 1]
        # the nine thin pairs are the bar-bar pairs (2i, 2j) with the same relative motions
        self.thin = mot.data(THIN_PAIRS)
        self.rot = np.stack([mot.rot[k][n] for k, n in where])  # (42, T, 3, 3)
        self.trans = np.stack([mot.trans[k][n] for k, n in where])  # (42, T, 3)


class OffsetSearch:
    """Step 4 for one collision-free thin polyline; caches per-item sampled/exact distances."""

    def __init__(self, lp: LoopMotions, v: np.ndarray, d: float, rho: float):
        self.lp, self.rho = lp, rho
        u = lp.u
        bar_in = np.roll(v, 1, axis=0) - v  # link i's bar seen from V_i
        bar_out = np.roll(v, -1, axis=0) - v  # link i+1's bar
        cos_in = np.sum(bar_in * u, -1) / np.maximum(np.linalg.norm(bar_in, axis=-1), 1e-300)
        cos_out = np.sum(bar_out * u, -1) / np.maximum(np.linalg.norm(bar_out, axis=-1), 1e-300)
        next_orange = cos_out >= cos_in
        orange = v[:, None] + (d * _ORANGE_LIFT)[None, :, None] * u[:, None]  # (6, 3, 3)
        blue = orange - d * u[:, None]
        # slot 0 = E_i (link i), slot 1 = S_{i+1} (link i+1)
        slot0 = np.where(next_orange[:, None, None], blue, orange)
        slot1 = np.where(next_orange[:, None, None], orange, blue)
        self.table = np.stack([slot0, slot1], axis=2).reshape(-1, 3)  # flat (axis, digit, slot)
        n = len(_ITEM_PAIR)
        self.upper = np.full(n, np.nan)  # sampled upper bound, replaced by the exact value
        self.exact_t = np.full(n, np.nan)
        self.exact = np.zeros(n, dtype=bool)
        self.moved: np.ndarray | None = None  # (42, 36, T, 3), computed on first sampling
        self.best_u = np.zeros(n)  # sample with the smallest distance, start of refinement
        self.refined = np.zeros(n, dtype=bool)

    def points(self, seq: int) -> np.ndarray:
        """The 12 vertices ``S_0, E_0, ..., S_5, E_5`` ``(12, 3)`` of sequence ``seq``."""
        return self.table[(V_AXIS * 3 + DIGITS[seq][V_AXIS]) * 2 + _V_SLOT]

    def _segments(self, items: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pts = self.table[_ITEM_REFS[items]]  # (I, 4, 3)
        return pts[:, :2], pts[:, 2:]

    def _sample(self, items: np.ndarray, refine: bool) -> None:
        """Upper bounds of the minima: 48 samples; with ``refine``, golden-section refinement
        in ``u`` of values close above 2 rho (worth it only when many sequences compete)."""
        new = items[np.isnan(self.upper[items])]
        if new.size:
            fixed, _ = self._segments(new)
            pair, ref = _ITEM_PAIR[new], _ITEM_REFS[new]
            if self.moved is None:  # all 36 candidate vertices moved by the 42 motions, once
                self.moved = np.einsum("ptab,vb->pvta", self.lp.rot, self.table) + \
                    self.lp.trans[:, None]
            dist = segment_distance(fixed[:, None, 0], fixed[:, None, 1],
                                    self.moved[pair, ref[:, 2]], self.moved[pair, ref[:, 3]])
            best = np.argmin(dist, axis=1)
            self.upper[new] = dist[np.arange(new.size), best]
            self.best_u[new] = SAMPLE_U[best]
        if not refine:
            return
        # Far values never fail and values below 2 rho already reject (true distances).
        up = self.upper[items]
        near = items[~self.refined[items] & ~self.exact[items] & (up >= 2.0 * self.rho)
                     & (up < 4.0 * self.rho)]
        if near.size:
            fixed, moving = self._segments(near)
            self.upper[near] = np.minimum(self.upper[near], self._golden(
                _ITEM_PAIR[near], fixed, moving, self.best_u[near]))
        self.refined[items] = True

    def _golden(self, pair, fixed, moving, u0) -> np.ndarray:
        """Golden-section minimum in ``[u0 - du, u0 + du]`` (vectorized; true distances)."""
        g = (np.sqrt(5.0) - 1.0) / 2.0
        a, b = u0 - SAMPLE_U[1], u0 + SAMPLE_U[1]
        c, e = b - g * (b - a), a + g * (b - a)
        fc, fe = (self._distance_at(pair, fixed, moving, u) for u in (c, e))
        best = np.minimum(fc, fe)
        for _ in range(_REFINE_STEPS):  # one new evaluation per step
            left = fc < fe
            a, b = np.where(left, a, c), np.where(left, e, b)
            c, e, fc, fe = np.where(left, b - g * (b - a), e), np.where(left, c, a + g * (b - a)), \
                np.where(left, np.nan, fe), np.where(left, fc, np.nan)
            x = np.where(left, c, e)
            fx = self._distance_at(pair, fixed, moving, x)
            fc, fe = np.where(left, fx, fc), np.where(left, fe, fx)
            best = np.minimum(best, fx)
        return best

    def _distance_at(self, pair, fixed, moving, u) -> np.ndarray:
        """Distance ``(I,)`` of item segments at per-item parameters ``u`` (periodic)."""
        s = poly.param_to_t(np.mod(u, 1.0))[:, None]  # u of the conditioned s (SAMPLE_U)
        out = np.empty(len(pair))
        for k, md in self.lp.groups.items():
            sel = self.lp.pair_group[pair] == k
            if np.any(sel):
                seg = segments_at(md, self.lp.pair_index[pair[sel]], moving[sel], s[sel])
                out[sel] = segment_distance(fixed[sel, 0], fixed[sel, 1], seg[:, 0, 0],
                                            seg[:, 0, 1])
        return out

    def _exact(self, items: np.ndarray) -> None:
        items = items[~self.exact[items]]
        fixed, moving = self._segments(items)
        pair = _ITEM_PAIR[items]
        for k, md in self.lp.groups.items():
            sel = self.lp.pair_group[pair] == k
            if np.any(sel):
                dist, t = min_distance_batch(md, self.lp.pair_index[pair[sel]], fixed[sel],
                                             moving[sel])
                self.upper[items[sel]], self.exact_t[items[sel]] = dist, t
        self.exact[items] = True

    def run(self, order: np.ndarray) -> tuple[int | None, int]:
        """First sequence of ``order`` that clears ``2 rho`` (or None) and how many were tried.

        Sequences passing the sampled filter are verified exactly in windows of doubling size
        (one batched kernel call per window); the result equals a one-by-one scan.
        """
        need = 2.0 * self.rho
        for chunk in (order[:1], order[1:2], order[2:]):
            rows = _SEQ_ITEMS[chunk]
            self._sample(np.unique(rows), refine=len(chunk) > 1)
            start, window = 0, 1
            while True:
                passing = np.flatnonzero(np.all(self.upper[rows] >= need, axis=1))
                batch = passing[passing >= start][:window]
                if batch.size == 0:
                    break
                self._exact(np.unique(rows[batch]))
                ok = np.all(self.upper[rows[batch]] >= need, axis=1)
                if ok.any():
                    seq = int(chunk[batch[np.argmax(ok)]])
                    return seq, int(np.flatnonzero(order == seq)[0]) + 1
                start, window = batch[-1] + 1, 2 * window
        return None, len(order)

    def certificate(self, seq: int) -> tuple[np.ndarray, np.ndarray]:
        """Exact minima ``(42,)`` and their times ``(42,)`` of an accepted sequence."""
        items = _SEQ_ITEMS[seq]
        return self.upper[items].copy(), self.exact_t[items].copy()


def sequence_order(shift_sign: np.ndarray) -> np.ndarray:
    """The 729 offset sequences: all zeros, the sign pattern of the shift, then the rest."""
    sign_digit = np.where(shift_sign > 0, 1, np.where(shift_sign < 0, 2, 0))
    first = int(sign_digit @ 3 ** np.arange(5, -1, -1))
    rest = [q for q in range(729) if q not in (0, first)]
    return np.array([0] + ([first] if first else []) + rest)
