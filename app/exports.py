"""What the studio's export buttons download, and the fabrication settings as core options.

*Export result* downloads the result JSON (:func:`export_files`); *Export all* one zip
``paraloop-<design>.zip`` (:func:`export_zip`) with that JSON and, when the design has a
realization, the fabrication output of :func:`export.export_design_parts` (STL per link,
``paraloop.3mf``, ``assembly.glb``, ``report.json`` with the verification).
"""

from __future__ import annotations

import io
import json
import zipfile
from collections.abc import Callable
from typing import Any

import numpy as np

from app.state import FabSettings
from paraloop_core import pipeline
from paraloop_core.fabrication import export
from paraloop_core.fabrication.parts import PartSpec, design_scale

#: Carving orders offered by the panel: target links first to last, each carved by the later.
ORDER_PRESETS = {"base first": (0, 1, 2, 3, 4, 5), "end first": (3, 2, 4, 1, 5, 0)}
CUSTOM = "custom"


def slug(name: str) -> str:
    """A file-name-safe version of a design name."""
    s = "".join(c if c.isalnum() or c in "-_" else "-" for c in name)[:60].strip("-")
    return s or "design"


def export_files(solution: pipeline.Solution) -> list[tuple[str, bytes]]:
    """Files ``(name, content)`` exported for a solved design: the result JSON."""
    result = json.dumps(pipeline.result_to_dict(solution), indent=1) + "\n"
    return [("paraloop-result.json", result.encode("utf-8"))]


def parse_order(text: str) -> list[tuple[int, int]]:
    """``'0-1, 0-2, ...'`` (target-source) -> pairs; every pair of the six links exactly once.
    Raises ValueError naming the problem."""
    pairs = []
    for item in filter(None, (s.strip() for s in text.replace(";", ",").split(","))):
        a, sep, b = item.partition("-")
        if not sep or not a.strip().isdigit() or not b.strip().isdigit():
            raise ValueError(f"'{item}': expected target-source, e.g. 0-3")
        pair = (int(a), int(b))
        if not (0 <= pair[0] < 6 and 0 <= pair[1] < 6) or pair[0] == pair[1]:
            raise ValueError(f"'{item}': links are 0..5 and differ")
        pairs.append(pair)
    seen = {frozenset(p) for p in pairs}
    if len(seen) != len(pairs):
        raise ValueError("a pair of links is listed twice")
    if len(seen) != 15:
        raise ValueError(f"list all 15 pairs of the six links (got {len(seen)}), so every "
                         "two design spaces are carved against each other")
    return pairs


def carve_order(fab: FabSettings) -> list[tuple[int, int]]:
    """The ``(target, source)`` pairs of the chosen preset or of the custom text."""
    if fab.order == CUSTOM:
        return parse_order(fab.custom_order)
    links = ORDER_PRESETS[fab.order]
    return [(a, b) for k, a in enumerate(links) for b in links[k + 1:]]


def fabrication_options(real: Any, fab: FabSettings, carved: bool) -> dict[str, Any]:
    """Keyword options of :func:`export.export_parts` (and, with ``carved``, of
    :func:`export.carve_design_spaces`) for a realization and the panel's settings."""
    opts: dict[str, Any] = {"spec": PartSpec(size_mm=fab.size_mm, clearance_mm=fab.clearance_mm,
                                             print_in_place=fab.print_in_place)}
    if carved:
        scale = design_scale(np.asarray(real.points, float), fab.size_mm)
        opts["space_radius"] = (fab.space_radius_mm / scale if fab.space_radius_mm > 0
                                else float(np.median(real.design_space_radii)))
        opts["resolution"] = fab.resolution
        opts["order"] = carve_order(fab)
    return opts


def carve_spaces(real: Any, fab: FabSettings,
                 progress: Callable[[float, str], None] | None = None,
                 effector: Any = None) -> tuple[Any, list]:
    """Carve and mesh the realization's design spaces with the panel's settings; an
    end-effector (``Solution.end_effector``) is part of link 3."""
    return export.carve_design_spaces(real.joint_factors, real.points, real.radius,
                                           **fabrication_options(real, fab, True),
                                           effector=effector, progress=progress)


def export_zip(solution: pipeline.Solution, fab: FabSettings,
               progress: Callable[[float, str], None] | None = None,
               ) -> tuple[str, bytes, dict | None]:
    """``(zip name, zip bytes, report or None)``: the result JSON plus, when the design has a
    realization, the fabrication files. Raises :class:`FabricationError` on bad settings."""
    files = export_files(solution)
    report = None
    real = solution.realization
    if real is not None:
        opts = fabrication_options(real, fab, fab.carved_parts)
        parts = export.export_design_parts(real.joint_factors, real.points, real.radius,
                                                ground=fab.ground, progress=progress,
                                                effector=solution.end_effector, **opts)
        files += parts
        report = json.loads(dict(parts)["report.json"])
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in files:
            zf.writestr(name, data)
    return f"paraloop-{slug(solution.design.name)}.zip", buf.getvalue(), report
