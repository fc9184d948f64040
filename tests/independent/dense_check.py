"""Dense referee of a result's clearance certificate (independent of ``paraloop_core``).

Reads a result dict (``docs/result-format.md``): world motion ``C = M S_0`` (M monic), the six
factorizations, the chosen loop ``[a0, a1, a2, b2, b1, b0]`` and the realization's 12 home
points ``S_0, E_0, ..., S_5, E_5`` (world frame, t = inf). Link i moves in the world frame by
``M_0 = 1, M_1 = t-a0, M_2 = (t-a0)(t-a1), M_3 = M, M_4 = (t-b0)(t-b1), M_5 = t-b0``. Edge
e joins points e and e+1 (mod 12): e = 2i is bar ``S_iE_i`` of link i, e = 2i+1 is the pin
``E_iS_{i+1}`` on axis A_i (fixed in links i and i+1; we move it with link i and check that
link i+1 agrees). Every pair's minimum distance over ``t in R u {inf}`` is sampled densely
(uniform in t's angle, uniform in each joint angle, log-dense near t = inf), then refined by
bounded scalar minimization around the smallest local minima.
"""

from __future__ import annotations

import itertools

import numpy as np
from scipy.optimize import minimize_scalar

from . import dq8, scalar
from .segdist import segment_distance

#: Relative tolerance (times the size of the linkage) of all comparisons.
REL_TOL = 1e-6
#: Thin pairs (links) of MATH section 11.
THIN_PAIRS = ((0, 2), (0, 3), (0, 4), (1, 3), (1, 4), (1, 5), (2, 4), (2, 5), (3, 5))


def checked_pairs() -> tuple[list[tuple[int, int]], list[tuple[int, int]]]:
    """The 42 certified edge pairs and the 12 skipped ones (consecutive bars / pins)."""
    checked, skipped = [], []
    for e1, e2 in itertools.combinations(range(12), 2):
        if (e2 - e1) % 12 in (1, 11):
            continue
        same_kind = e1 % 2 == e2 % 2
        gap = min((e2 // 2 - e1 // 2) % 6, (e1 // 2 - e2 // 2) % 6)
        (skipped if same_kind and gap == 1 else checked).append((e1, e2))
    return checked, skipped


def joint_factors(result: dict) -> np.ndarray:
    """Joint factors ``(6, 8)`` ``[a0, a1, a2, b2, b1, b0]`` of the realized loop."""
    k = result["realization"].get("loop", result["loop"])
    f, g = result["loops"][k]["factorizations"]
    fa = np.asarray(result["factorizations"][f]["factors"], float)
    fb = np.asarray(result["factorizations"][g]["factors"], float)
    return np.concatenate([fa, fb[::-1]])


def monic_motion(result: dict) -> np.ndarray:
    """``M = C S_0^-1`` ``(4, 8)`` from ``motion.coefficients`` (``S_0`` = leading coefficient)."""
    c = np.asarray(result["motion"]["coefficients"], float)
    s0 = c[-1]
    inv = dq8.dconj(s0) / np.sum(s0[:4] ** 2)
    return dq8.dmul(c, inv)


def link_motions(jf: np.ndarray) -> list[np.ndarray]:
    """World motion polynomials ``M_0..M_5`` (each ``(deg+1, 8)``, ascending) of the links."""
    a0, a1, a2, b1, b0 = jf[0], jf[1], jf[2], jf[4], jf[5]
    return [np.eye(8)[:1], dq8.from_factors([a0]), dq8.from_factors([a0, a1]),
            dq8.from_factors([a0, a1, a2]), dq8.from_factors([b0, b1]), dq8.from_factors([b0])]


def link_poses(motions: list[np.ndarray], t: np.ndarray) -> np.ndarray:
    """Homogeneous world poses ``(T, 6, 8)`` of the six links at parameters ``t`` ``(T,)``."""
    c, s = dq8.homogeneous(t)
    return np.stack([dq8.poly_at(m, c, s) for m in motions], axis=1)


def move(pose: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Points ``x`` ``(L, K, 3)`` of link l moved by its poses ``(T, L, 8)`` -> ``(T, L, K, 3)``."""
    rot, tr = dq8.rigid(pose)
    return np.einsum("tlij,lkj->tlki", rot, x) + tr[:, :, None, :]


def moving_edges(motions: list[np.ndarray], points: np.ndarray, t: np.ndarray) -> np.ndarray:
    """World endpoints ``(T, 12, 2, 3)`` of the 12 edges at ``t`` (edge 2i and 2i+1 on link i)."""
    pose = link_poses(motions, t)  # (T, 6, 8)
    trio = np.stack([points[0::2], points[1::2], np.roll(points[0::2], -1, axis=0)], axis=1)
    moved = move(pose, trio)  # (T, 6, 3, 3)
    bars, pins = moved[:, :, 0:2], moved[:, :, 1:3]
    return np.stack([bars, pins], axis=2).reshape(len(t), 12, 2, 3)


def sample_parameters(jf: np.ndarray, n: int = 20_500) -> np.ndarray:
    """Sample parameters ``(>= n,)`` over R u {inf} (inf included): uniform in ``atan t``, uniform
    in each distinct joint angle ``t = h0 + |p| tan(...)``, and log-dense in ``1/t`` near 0."""
    h0 = jf[:, 0]
    pn = np.linalg.norm(jf[:, 1:4], axis=1)
    scales = np.unique(np.round(np.stack([h0, pn], axis=1), 12), axis=0)
    m = n // (2 + len(scales))
    u = (np.arange(m) + 0.5) / m
    parts = [np.tan(np.pi * (u - 0.5)), [np.inf]]
    for c0, r in scales:
        parts.append(c0 + r * np.tan(np.pi * (u - 0.5)))
    big = max(1.0, float(np.max(np.abs(h0) + pn)))
    s = np.logspace(-16, 1, m // 2) / big
    parts += [1.0 / s, -1.0 / s]
    return np.unique(np.concatenate(parts))


def _key(t: np.ndarray) -> np.ndarray:
    """Monotone coordinate of the projective line: [-2, 2) with inf at -2 (cyclic)."""
    with np.errstate(divide="ignore"):
        inv = np.where(np.isinf(t), 0.0, 1.0 / np.where(t == 0, 1.0, t))
    return np.where(np.abs(t) <= 1.0, t, np.where(t > 0, 2.0 - inv, -2.0 - inv))


def _to_t(x: float, inverted: bool) -> float:
    if not inverted:
        return x
    return np.inf if x == 0.0 else 1.0 / x


class PairReferee:
    """Distance of edge pairs along the motion: ``dist(t, e1, e2)`` vectorized over t."""

    def __init__(self, jf: np.ndarray, points: np.ndarray):
        self.motions, self.points = link_motions(jf), points
        self._coef = [m.tolist() for m in self.motions]
        pts = [tuple(p) for p in points.tolist()]
        self._ends = [(pts[e], pts[(e + 1) % 12]) for e in range(12)]

    def dist(self, t: np.ndarray, pairs: np.ndarray) -> np.ndarray:
        """Distances ``(T, P)`` of the edge pairs ``pairs`` ``(P, 2)`` at ``t`` ``(T,)``."""
        e = moving_edges(self.motions, self.points, np.atleast_1d(np.asarray(t, float)))
        a, b = e[:, pairs[:, 0]], e[:, pairs[:, 1]]
        return segment_distance(a[..., 0, :], a[..., 1, :], b[..., 0, :], b[..., 1, :])

    def dist1(self, t: float, pair: tuple[int, int]) -> float:
        """Distance of one edge pair at one t (pure-Python path of :meth:`dist`)."""
        c, s = (t, 1.0) if abs(t) <= 1.0 else (1.0, 0.0 if np.isinf(t) else 1.0 / t)
        segs = []
        for e in pair:
            mv = scalar.mover(scalar.pose_at(self._coef[e // 2], c, s))
            segs += [mv(self._ends[e][0]), mv(self._ends[e][1])]
        return scalar.segment_distance(*segs)

    def minimum(self, t: np.ndarray, d: np.ndarray, pair: tuple[int, int], n_refine: int = 4
                ) -> tuple[float, float]:
        """Global minimum ``(value, t)`` of one pair from its samples ``d`` at sorted ``t`` and
        bounded refinement of the ``n_refine`` smallest cyclic local minima."""
        loc = np.flatnonzero((d <= np.roll(d, 1)) & (d <= np.roll(d, -1)))
        loc = loc[np.argsort(d[loc])[:n_refine]]
        best, best_t = float(d.min()), float(t[np.argmin(d)])
        n = len(t)
        for i in loc:
            tl, tm, tr = t[(i - 1) % n], t[i], t[(i + 1) % n]
            inverted = not abs(tm) <= 1.0
            xs = [1.0 / v if inverted and np.isfinite(v) else (0.0 if inverted else v)
                  for v in (tl, tr)]
            lo, hi = min(xs), max(xs)
            if not hi > lo:
                continue
            res = minimize_scalar(lambda x, inv=inverted: self.dist1(_to_t(x, inv), pair),
                                  bounds=(lo, hi), method="bounded",
                options={"xatol": 1e-9 * (hi - lo)})
            if res.fun < best:
                best, best_t = float(res.fun), _to_t(float(res.x), inverted)
        return best, best_t


def _size(points: np.ndarray) -> float:
    return float(np.max(np.linalg.norm(points - points.mean(axis=0), axis=1)))


def check_result(result: dict, n_samples: int = 20_500) -> dict:
    """Referee report of one result dict: ``status`` ('not_found' | 'checked'), per-pair rows
    ``{edges, reported, reported_t, dense_min, t_at_min, at_reported_t, flags}``, ``skipped``
    rows (consecutive bars/pins, info only), ``thin`` rows and design-level ``flags``; the
    ``disagreements`` list holds every row/flag that contradicts the certificate."""
    real = result.get("realization")
    if not real or real.get("status", "found") != "found":
        return {"status": "not_found", "disagreements": []}
    jf = joint_factors(result)
    points = np.asarray(real["points"], float)
    rho = float(real["radius"])
    size = max(_size(points), rho)
    tol = REL_TOL * size
    flags: list[str] = []
    # the factors must multiply to the reported motion (both factorizations of the loop)
    m = monic_motion(result)
    for fac in (jf[:3], jf[:2:-1]):
        err = np.abs(dq8.from_factors(fac) - m).max() / np.abs(m).max()
        if not err < 1e-7:
            flags.append(f"factors-mismatch {err:.1e}")
    t = sample_parameters(jf, n_samples)
    t = t[np.argsort(_key(t), kind="stable")]
    # pin i moves with link i; link i+1 must carry it identically (frame reading check)
    motions = link_motions(jf)
    pose = link_poses(motions, t[:: max(1, len(t) // 2000)])
    pins = np.stack([points[1::2], np.roll(points[0::2], -1, axis=0)], axis=1)  # (6, 2, 3)
    by_i = move(pose, pins)
    by_next = move(np.roll(pose, -1, axis=1), pins)
    frame_err = float(np.abs(by_i - by_next).max())
    # the result declares how far the loop's two float64 readings may place a point apart
    # (``reading_gap``, taken off its lower bounds): checked here, then allowed for below
    gap = float(real.get("reading_gap", 0.0))
    if not frame_err < tol + gap:
        flags.append(f"pin-frame-mismatch {frame_err:.3g}")
    ref = PairReferee(jf, points)
    checked, skipped = checked_pairs()
    # the certificate promises: reported min within its declared tolerance of the true one,
    # and a proven lower bound never above it; consecutive bars carry a lower bound only
    declared = float(real.get("tolerance", 0.0))
    relative = float(real.get("relative_tolerance", 0.0))
    lows = {tuple(sorted(p["edges"])): float(p["lower_bound"])
            for p in real["pairs"] + real.get("joint_pairs", []) if "lower_bound" in p}
    joint = [p for p in skipped if p in lows]
    checked, skipped = checked + joint, [p for p in skipped if p not in lows]
    reported = {tuple(sorted(p["edges"])): p for p in real["pairs"]}
    missing = [p for p in checked if p not in reported and p not in joint]
    if missing:
        flags.append(f"missing-pairs {missing}")
    rows, bad = [], []
    dense = ref.dist(t, np.array(checked + skipped))
    for col, pair in enumerate(checked + skipped):
        dmin, tmin = ref.minimum(t, dense[:, col], pair)
        row = {"edges": list(pair), "dense_min": dmin, "t_at_min": tmin, "flags": []}
        if pair in reported:
            rep = reported[pair]
            rt = np.inf if rep["t"] is None else float(rep["t"])
            at_rt = ref.dist1(rt, pair)
            row.update(reported=float(rep["min_distance"]), reported_t=rep["t"],
                       at_reported_t=at_rt)
            if at_rt < dmin:
                row.update(dense_min=at_rt, t_at_min=rt)
            if abs(at_rt - row["reported"]) > tol + gap:
                row["flags"].append("inconsistent")  # reported value is not dist at its t
            far = lows.get(pair, -np.inf) >= 4 * rho  # proven clear of 2x the need: imprecise
            allowed = row["dense_min"] * (1 + relative) + tol + declared + gap
            if not far and row["reported"] > allowed:
                row["flags"].append("overreported")
            if row["reported"] < 2 * rho * (1 - 1e-12):
                row["flags"].append("reported-below-2rho")
        if pair in lows:
            row["lower_bound"] = lows[pair]
            if lows[pair] > row["dense_min"] + tol:
                row["flags"].append("lower-bound-above-min")  # the proof would be wrong
        if pair in checked and pair not in joint and row["dense_min"] < 2 * rho - tol:
            row["flags"].append("touching")
        rows.append(row)
        if pair in checked and row["flags"]:
            bad.append(row)
    checked_rows, skipped_rows = rows[:len(checked)], rows[len(checked):]
    mc = float(real.get("min_clearance", np.inf))
    if checked_rows and abs(mc - min(r.get("reported", np.inf) for r in checked_rows)) > tol:
        flags.append("min-clearance-mismatch")
    thin = _thin_rows(result, jf, t)
    flags += [f"thin-collision links {r['links']} dense {r['dense_min']:.3g}"
              for r in thin if r["collides"]]
    return {"status": "checked", "radius": rho, "tol": tol, "pairs": checked_rows,
            "skipped": skipped_rows, "thin": thin, "flags": flags,
            "disagreements": bad + [{"flag": f} for f in flags]}


def _thin_rows(result: dict, jf: np.ndarray, t: np.ndarray) -> list[dict]:
    """Dense thin check of the step-3 polyline ``V_0..V_5`` (segment i = [V_{i-1}, V_i] on link
    i): a pair collides when its dense minimum is <= 1e-7 x (sum of the two lengths)."""
    v = np.asarray(result["realization"].get("thin_polyline", []), float)
    if v.shape != (6, 3):
        return []
    pose = link_poses(link_motions(jf), t)
    seg = np.stack([np.roll(v, 1, axis=0), v], axis=1)  # (6, 2, 3)
    moved = move(pose, seg)  # (T, 6, 2, 3)
    out = []
    for i, j in THIN_PAIRS:
        d = segment_distance(moved[:, i, 0], moved[:, i, 1], moved[:, j, 0], moved[:, j, 1])
        lens = np.linalg.norm(seg[i, 1] - seg[i, 0]) + np.linalg.norm(seg[j, 1] - seg[j, 0])
        k = int(np.argmin(d))
        out.append({"links": [i, j], "dense_min": float(d[k]), "t_at_min": float(t[k]),
                    "collides": bool(d[k] <= 1e-7 * lens)})
    return out
