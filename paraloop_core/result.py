"""The result JSON of a solved design (``docs/result-format.md``): building it, writing it.

:func:`result_to_dict` takes a :class:`paraloop_core.pipeline.Solution` (not imported: the
pipeline imports this module).
"""

from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from paraloop_core.algebra import factor
from paraloop_core.errors import NumericalError

RESULT_FORMAT = "paraloop-result"
RESULT_VERSION = 1


def _t_json(t: float) -> float | None:
    return None if np.isinf(t) else float(t)


def result_to_dict(sol: Any, drive: bool | None = None) -> dict[str, Any]:
    """The result JSON (see ``docs/result-format.md``). ``drive``: include the drive plan of
    the chosen loop (True), leave it out (False), or include it when the design asks for one,
    i.e. its ``drive`` settings are not the defaults (None). The plan costs a few ms, about
    twice the rest of a solve, so results of designs that never mention a drive skip it."""
    facts = sol.factorizations
    labels = "ABC"
    out: dict[str, Any] = {
        "format": RESULT_FORMAT,
        "version": RESULT_VERSION,
        "design": sol.design.name,
        "convention": "dual quaternion [p0,p1,p2,p3,d0,d1,d2,d3], point action "
        "x -> (P x P~ + 2 D P~)/|P|^2; lines (direction, moment = point x direction)",
        "motion": {
            "coefficients": sol.motion.tolist(),
            "pose_parameters": [_t_json(t) for t in sol.pose_parameters],
            **({} if sol.design.linkage == "bennett" else {  # one motion: no family, no mu
                "family": sol.design.motion.family,
                "mu": _t_json(np.inf if sol.mu is None else sol.mu)}),
            "norm_quadratics": {labels[i]: [float(q[0]), float(q[1]), 1.0]
                                for i, q in enumerate(facts.quadratics)},
        },
        "factorizations": [
            {"norm_order": [labels[i] for i in facts.norm_order[j]],
             "factors": facts.factors[j].tolist()}
            for j in range(len(facts.factors))
        ],
        "loops": [
            {"type": lp.kind, "factorizations": list(lp.factorizations),
             "axes": lp.axes.tolist(), "singularity": float(sol.singularity[k]),
             "singularity_t": _t_json(sol.singularity_t[k])}
            for k, lp in enumerate(sol.loops)
        ],
        "loop": sol.design.loop,
        "linkage": sol.design.linkage,
    }
    a, b, length = factor.conditioning_batch(sol.monic)
    out["conditioning"] = {
        "a": float(a), "b": float(b), "length": float(length),
        "meaning": "the factorization works in s with t = a s + b (norm roots round s = i) "
                   "and lengths divided by 'length'; the certificate in the same s (from the "
                   "loop's norm roots) and its own unit; every t and length here is the "
                   "design's",
    }
    out["motion"]["method"] = sol.design.motion.method
    if sol.fit is not None:
        from paraloop_core.motion import evolution

        out["motion"]["fit"] = evolution.fit_result_to_dict(sol.fit)
    if sol.realization is not None:
        from paraloop_core.realization.report import realization_to_dict

        out["realization"] = {**sol.realization_report, "loop": sol.design.loop,
                              **realization_to_dict(sol.realization)}
    elif sol.realization_report is not None:
        out["realization"] = {**sol.realization_report, "loop": sol.design.loop}
    if sol.end_effector is not None:
        from paraloop_core.realization import ee_certificate

        out["end_effector"] = ee_certificate.ee_to_dict(sol.end_effector)
    wants_drive = drive or (drive is None and _asks_for_drive(sol.design.drive))
    if wants_drive and sol.design.linkage == "bennett":
        out["drive"] = {"error": "drive analysis of a Bennett loop not yet supported (the "
                                 "drive plan is written for 6R loops)"}
    elif wants_drive:
        from paraloop_core.linkage import drive_plan

        try:  # the chosen loop in design units, base link resting; never fails a solve
            out["drive"] = drive_plan.plan_to_dict(drive_plan.plan_drive(
                sol.loop.joint_factors, sol.design.drive, resting_link=0))
        except (ValueError, RuntimeError) as exc:  # RuntimeError: a limit check failed (a bug)
            out["drive"] = {"error": str(exc)}
    return out


def _asks_for_drive(settings: Any) -> bool:
    """Whether drive settings differ from the defaults (``design.DriveSettings()``; compared
    field by field: design is above this module)."""
    return type(settings)() != settings


def save_result(sol: Any, path: str | Path, drive: bool | None = None) -> None:
    """Write the result JSON of ``sol`` (``drive`` as :func:`result_to_dict`) to ``path``
    atomically (strict JSON: no NaN/Infinity)."""
    write_json_atomic(Path(path), result_to_dict(sol, drive))


def write_json_atomic(path: Path, data: dict[str, Any]) -> None:
    """Strict JSON to a temporary file beside ``path``, then a rename: a failure never leaves a
    half-written file or the temporary behind. A NaN or infinite value raises NumericalError
    naming where it is (and writes nothing)."""
    try:
        text = json_text(data)
    except ValueError:
        raise_non_finite(data)
        raise
    fd, tmp = temp_file(path.parent, path.name)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def json_text(data: Any) -> str:
    """Strict JSON text of ``data`` (ValueError on NaN or infinity): one object member or one
    element of an array of objects per line, indented one space per level; any other array on
    one line (a pose, a polynomial's coefficients). Readable, and ~10x faster than
    ``json.dumps(indent=...)``: the leaves go through the C encoder, which ``indent`` disables."""
    import json

    leaf = json.JSONEncoder(allow_nan=False, separators=(", ", ": ")).encode

    def text(node: Any, pad: str) -> str:
        inner = pad + " "
        if isinstance(node, dict) and node:
            # a key that is not a string is spelled as json spells it ({1: 0} -> "1")
            rows = (f"{inner}{leaf(k) if isinstance(k, str) else leaf({k: 0})[1:-4]}: "
                    f"{text(v, inner)}" for k, v in node.items())
        elif isinstance(node, (list, tuple)) and any(isinstance(v, dict) for v in node):
            rows = (inner + text(v, inner) for v in node)
        else:
            return leaf(node)
        brackets = "{}" if isinstance(node, dict) else "[]"
        return brackets[0] + "\n" + ",\n".join(rows) + "\n" + pad + brackets[1]

    return text(data, "") + "\n"


def raise_non_finite(data: Any, where: str = "result") -> None:
    """Raise NumericalError naming the first NaN or infinite number in JSON-like ``data``
    (nested dicts and lists); return when there is none."""
    stack = [(where, data)]
    while stack:
        path, node = stack.pop()
        if isinstance(node, dict):
            stack.extend((f"{path}.{k}", v) for k, v in node.items())
        elif isinstance(node, (list, tuple)):
            stack.extend((f"{path}[{i}]", v) for i, v in enumerate(node))
        elif isinstance(node, float) and not math.isfinite(node):
            raise NumericalError(f"{path} is {node} (float64 broke down on this design; "
                                 "please report it with the design file to the paraloop "
                                 "issue tracker)")


def temp_file(folder: Path, name: str) -> tuple[int, Path]:
    """A new temporary file ``.<name>.*.tmp`` in ``folder`` (descriptor, path), with the mode
    a plain ``open`` would give (0666 less the umask), not ``mkstemp``'s 0600: renamed into
    place it is the file the user expects."""
    fd, tmp = tempfile.mkstemp(prefix=f".{name[:100]}.", suffix=".tmp", dir=folder)
    try:
        os.fchmod(fd, 0o666 & ~_umask())
    except BaseException:
        os.close(fd)
        os.unlink(tmp)
        raise
    return fd, Path(tmp)


def _umask() -> int:
    """The process umask, read without changing it where Linux tells it (``os.umask`` sets it
    for a moment, which another thread creating a file would see)."""
    try:
        with open("/proc/self/status", encoding="ascii", errors="replace") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask
