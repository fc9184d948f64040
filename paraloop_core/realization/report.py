"""The JSON form of a realization (``paraloop-result`` files; docs/result-format.md)."""

from __future__ import annotations

import numpy as np

from paraloop_core.realization import radii, verify
from paraloop_core.realization.certified import Realization


def _edge_label(e: int) -> str:
    i = e // 2
    return f"S{i}E{i}" if e % 2 == 0 else f"E{i}S{(i + 1) % 6}"


def realization_to_dict(r: Realization) -> dict:
    """JSON-ready dict of a :class:`Realization` (``t`` is null where the minimum is at home)."""
    pairs = [
        {
            "edges": [int(e1), int(e2)],
            "labels": [_edge_label(int(e1)), _edge_label(int(e2))],
            "links": [int(la), int(lb)],
            "min_distance": float(dist),
            "lower_bound": float(low),
            "t": None if np.isinf(t) else float(t),
        }
        for (e1, e2, la, lb), dist, low, t in zip(r.pairs, r.pair_distance, r.pair_lower,
                                                   r.pair_t, strict=True)
    ]
    return {
        "points": r.points.tolist(),
        "radius": r.radius,
        "separation": r.separation,
        "pairs": pairs,
        "min_clearance": r.min_clearance,
        "certified_clearance": r.certified_clearance,
        "tolerance": r.tolerance,
        "relative_tolerance": verify.RELATIVE,
        "reading_gap": r.reading_gap,
        "joint_pairs": [{"edges": [int(e1), int(e2)], "labels": [_edge_label(int(e1)),
                                                                   _edge_label(int(e2))],
                         "lower_bound": float(lo)}
                        for (e1, e2, _, _), lo in zip(r.joint_pairs, r.joint_lower,
                                                       strict=True)],
        "design_space_radii": r.design_space_radii.tolist(),
        "certified_radii": radii.radii_to_dict(radii.certified_radii(r.pairs, r.pair_lower,
                                                                     r.radius)),
        "stats": {key: (float(v) if key == "length_ratio" else int(v))
                  for key, v in r.stats.items()},
        "offsets": [int(o) for o in r.offsets],
        "shifts": [int(s) for s in r.shifts],
        "shift_step": r.length / r.p,
        "initial_length": r.length,
        "thin_polyline": r.thin.tolist(),
    }
