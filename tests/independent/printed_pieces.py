"""A link printed in pieces, checked on the files (independent of paraloop_core).

A part of ``report.json`` with ``printed_as`` (``pieces``, ``dowels``) is its link assembled
(``<name>.stl``); the 3MF holds the pieces instead. Checks:

* the pieces lie within the link (their union outside it: at most a thousandth of its volume:
  the collision check of the link then covers them), overlap nowhere, and make up the link
  but for at most :data:`MAX_REMOVED_SHARE` of its volume (dowel bores, flat print faces);
* each dowel pin (``origin_mm``, ``axis``, ``pieces``: the first piece on the side of
  ``-axis``) sits in a bore in both pieces that holds it (:func:`joint_profile.held`) over at
  least 1.5 pin diameters on each side of the cut, with walls and floor >= the profile wall.
"""

from __future__ import annotations

import re

import manifold3d as m3
import numpy as np

from .joint_profile import STEP_MM, floor, held, profile, run_length, thinnest_wall

#: Largest share of the link's volume in no piece.
MAX_REMOVED_SHARE = 0.05
#: Engagement of a dowel in each piece, in pin diameters.
MIN_ENGAGEMENT_D = 1.5


def _solid(mesh) -> m3.Manifold:
    return m3.Manifold(m3.Mesh(vert_properties=np.asarray(mesh.vertices, np.float32),
                               tri_verts=np.asarray(mesh.faces, np.uint32)))


def _pin_d(text: str) -> float:
    m = re.match(r"\s*([0-9.]+)\s*x", text)
    return float(m.group(1)) if m else float("nan")


def check_pieces(ex, wall: float) -> tuple[list[dict], list[str]]:
    """Figures and failures of every link printed in pieces of the export ``ex``."""
    rows, fails = [], []
    for part in ex.report.get("parts", []):
        spec = part.get("printed_as")
        if not spec:
            continue
        name = part["name"]
        link = ex.mesh(name)
        pieces = {n: ex.mesh(n) for n in spec["pieces"]}
        whole = _solid(link)
        solids = {n: _solid(m) for n, m in pieces.items()}
        union = m3.Manifold.batch_boolean(list(solids.values()), m3.OpType.Add)
        outside = (union - whole).volume()
        missing = (whole - union).volume()
        overlap = max(((solids[a] ^ solids[b]).volume() for i, a in enumerate(solids)
                       for b in list(solids)[i + 1:]), default=0.0)
        row = {"part": name, "pieces": list(pieces), "outside_mm3": outside,
               "missing_share": missing / whole.volume(), "overlap_mm3": overlap, "dowels": []}
        rows.append(row)
        if not outside <= 1e-3 * whole.volume():
            fails.append(f"pieces: {name}'s pieces reach {outside:.1f} mm^3 outside the link")
        if not overlap <= 1e-3 * whole.volume():
            fails.append(f"pieces: {name}'s pieces overlap by {overlap:.1f} mm^3")
        if not row["missing_share"] <= MAX_REMOVED_SHARE:
            fails.append(f"pieces: {name}'s pieces leave out {row['missing_share']:.1%} of it")
        for k, dw in enumerate(spec["dowels"]):
            d = _pin_d(dw["pin"])
            origin, axis = np.asarray(dw["origin_mm"], float), np.asarray(dw["axis"], float)
            for side, piece in zip((-1, 1), dw["pieces"], strict=True):
                reach = max(dw["depth_mm"]) + 3 * wall
                p = profile(pieces[piece], origin, axis * side, 0.0, reach)
                hold = held(p, d / 2)
                engaged = run_length(hold)
                w = thinnest_wall(p, hold)[0]
                fl = floor(p, p.s > 0)
                row["dowels"].append({"dowel": k, "piece": piece, "engagement_mm": engaged,
                                      "wall_mm": w, "floor_mm": fl})
                if not engaged >= MIN_ENGAGEMENT_D * d:
                    fails.append(f"pieces: the dowel {k} of {name} is held {engaged:.1f} mm "
                                 f"in {piece} < {MIN_ENGAGEMENT_D:g} x {d:g} mm")
                if not w >= wall - STEP_MM:
                    fails.append(f"pieces: {piece}'s wall around dowel {k} is {w:.2f} mm < "
                                 f"{wall:g} mm")
                if fl is None or not fl >= wall - STEP_MM:
                    fails.append(f"pieces: {piece}'s bore for dowel {k} has "
                                 f"{'no floor' if fl is None else f'a {fl:.2f} mm floor'} "
                                 f"(< {wall:g} mm)")
    return rows, fails
