"""The versioned JSON design format (documented in ``docs/design-format.md``).

A design is what the user edits: target poses in the world frame (position in design units +
``wxyz``; the first pose is the reference S_0), motion settings, the inertia ellipsoid of the
moving body, the chosen loop and realization settings. Loading validates every field and raises
:class:`~paraloop_core.errors.DesignFileError` naming the JSON path of the first bad field.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from paraloop_core.errors import DesignFileError
from paraloop_core.tolerance import TOL

FORMAT = "paraloop-design"
VERSION = 1
METHODS = ("four-pose", "fit")
CRITERIA = ("base-axes", "end-axes", "length", "extra-poses")


@dataclass(frozen=True)
class Pose:
    """A target pose: ``position`` (3,) world frame, design units; ``wxyz`` (4,) unit quaternion."""

    position: np.ndarray
    wxyz: np.ndarray


@dataclass(frozen=True)
class MotionSettings:
    """``method``: 'four-pose' (exactly 4 poses) or 'fit' (>= 5); ``family`` 0|1; ``mu`` the family
    parameter (None = infinity); ``criterion`` (if set, mu is chosen by :func:`selection.best_mu`);
    ``targets`` (2, 3) world points for the axis criteria; ``extra_poses`` for 'extra-poses'."""

    method: str = "four-pose"
    family: int = 0
    mu: float | None = None
    criterion: str | None = None
    targets: np.ndarray | None = None
    extra_poses: tuple[Pose, ...] = ()


@dataclass(frozen=True)
class InertiaSettings:
    """Inertia ellipsoid of the moving body in its reference frame (see :mod:`metric`)."""

    center: np.ndarray = field(default_factory=lambda: np.zeros(3))
    semi_axes: np.ndarray = field(default_factory=lambda: np.ones(3))
    axes: np.ndarray = field(default_factory=lambda: np.eye(3))
    weight: float = 1.0


@dataclass(frozen=True)
class RealizationSettings:
    """Realization parameters (paper Sec. 5.1): ``p`` shift divisor, bar radius ``rho`` and joint
    offset ``d`` (absolute, design units) or as fractions (``d = d_fraction * l``,
    ``rho = rho_fraction * d``), ``fixed`` vertex positions along their axes, ``max_k`` cap."""

    enabled: bool = True
    p: float = 10.0
    rho: float | None = None
    d: float | None = None
    d_fraction: float = 0.01
    rho_fraction: float = 0.25
    fixed: dict[int, float] = field(default_factory=dict)
    max_k: int = 50


@dataclass(frozen=True)
class EndEffectorSettings:
    """The body moved by the end link (Sec. 5.1): a ``mesh`` file (path relative to the design
    file) or a built-in ``shape`` ('disc' | 'panel'), ``scale``, vertices ``L`` / ``R`` joining
    the end-link bars (None = closest to A_2 / A_3), required ``clearance`` (None = rho)."""

    mesh: str | None = None
    shape: str | None = None
    scale: float = 1.0
    L: int | None = None
    R: int | None = None
    clearance: float | None = None


@dataclass(frozen=True)
class Design:
    """A complete design; edit with ``dataclasses.replace``."""

    name: str
    poses: tuple[Pose, ...]
    motion: MotionSettings = MotionSettings()
    inertia: InertiaSettings = InertiaSettings()
    loop: int = 0
    realization: RealizationSettings = RealizationSettings()
    locked: tuple[int, ...] = ()
    evolution: dict[str, Any] = field(default_factory=dict)
    end_effector: EndEffectorSettings | None = None
    #: folder that relative paths in the design (the end-effector mesh) refer to; not saved
    base_dir: str | None = None

    @property
    def pose_array(self) -> tuple[np.ndarray, np.ndarray]:
        """Positions (m, 3) and wxyz (m, 4)."""
        return (np.array([p.position for p in self.poses]), np.array([p.wxyz for p in self.poses]))


def _num(v: Any, path: str, *, positive: bool = False, allow_none: bool = False) -> float | None:
    if v is None and allow_none:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise DesignFileError(path, f"must be a finite number, got {v!r}")
    if positive and v <= 0:
        raise DesignFileError(path, f"must be > 0, got {v!r}")
    return float(v)


def _vec(v: Any, n: int, path: str) -> np.ndarray:
    if not isinstance(v, (list, tuple)) or len(v) != n:
        raise DesignFileError(path, f"must be a list of {n} numbers, got {v!r}")
    return np.array([_num(x, f"{path}[{i}]") for i, x in enumerate(v)])


def _obj(v: Any, path: str) -> dict:
    if not isinstance(v, dict):
        raise DesignFileError(path, f"must be an object, got {type(v).__name__}")
    return v


def _check_keys(d: dict, allowed: set[str], path: str) -> None:
    extra = sorted(set(d) - allowed)
    if extra:
        raise DesignFileError(f"{path}.{extra[0]}", "unknown field")


def _pose(v: Any, path: str) -> Pose:
    d = _obj(v, path)
    _check_keys(d, {"position", "wxyz"}, path)
    for key in ("position", "wxyz"):
        if key not in d:
            raise DesignFileError(f"{path}.{key}", "missing")
    q = _vec(d["wxyz"], 4, f"{path}.wxyz")
    n = float(np.linalg.norm(q))
    if n < TOL.zero:
        raise DesignFileError(f"{path}.wxyz", "quaternion must be nonzero")
    return Pose(_vec(d["position"], 3, f"{path}.position"), q / n)


def _motion(v: Any) -> MotionSettings:
    d = _obj(v, "motion")
    _check_keys(d, {"method", "family", "mu", "criterion", "targets", "extra_poses"}, "motion")
    method = d.get("method", "four-pose")
    if method not in METHODS:
        raise DesignFileError("motion.method", f"must be one of {METHODS}, got {method!r}")
    family = d.get("family", 0)
    if family not in (0, 1) or isinstance(family, bool):
        raise DesignFileError("motion.family", f"must be 0 or 1, got {family!r}")
    mu = d.get("mu", "inf")
    mu = None if mu == "inf" else _num(mu, "motion.mu")
    crit = d.get("criterion")
    if crit is not None and crit not in CRITERIA:
        raise DesignFileError("motion.criterion", f"must be one of {CRITERIA} or null")
    targets = None
    if d.get("targets") is not None:
        rows = d["targets"]
        if not isinstance(rows, list) or len(rows) != 2:
            raise DesignFileError("motion.targets", "must be two points [[x, y, z], [x, y, z]]")
        targets = np.array([_vec(r, 3, f"motion.targets[{i}]") for i, r in enumerate(rows)])
    extra = d.get("extra_poses", [])
    if not isinstance(extra, list):
        raise DesignFileError("motion.extra_poses", "must be a list of poses")
    extra_poses = tuple(_pose(p, f"motion.extra_poses[{i}]") for i, p in enumerate(extra))
    if crit in ("base-axes", "end-axes") and targets is None:
        raise DesignFileError("motion.targets", f"criterion {crit!r} needs two target points")
    if crit == "extra-poses" and not extra_poses:
        raise DesignFileError("motion.extra_poses", "criterion 'extra-poses' needs poses")
    return MotionSettings(method, int(family), mu, crit, targets, extra_poses)


def _inertia(v: Any) -> InertiaSettings:
    d = _obj(v, "inertia")
    _check_keys(d, {"center", "semi_axes", "axes", "weight"}, "inertia")
    out = InertiaSettings()
    center = _vec(d["center"], 3, "inertia.center") if "center" in d else out.center
    semi = _vec(d["semi_axes"], 3, "inertia.semi_axes") if "semi_axes" in d else out.semi_axes
    if np.any(semi < 0) or np.all(semi == 0):
        raise DesignFileError("inertia.semi_axes", "must be >= 0 and not all zero")
    axes = out.axes
    if "axes" in d:
        rows = d["axes"]
        if not isinstance(rows, list) or len(rows) != 3:
            raise DesignFileError("inertia.axes", "must be 3 rows of 3 numbers")
        axes = np.array([_vec(r, 3, f"inertia.axes[{i}]") for i, r in enumerate(rows)])
        if not np.allclose(axes @ axes.T, np.eye(3), atol=TOL.orthonormal):
            raise DesignFileError("inertia.axes", "rows must be orthonormal")
    weight = _num(d.get("weight", 1.0), "inertia.weight", positive=True)
    return InertiaSettings(center, semi, axes, weight)


def _realization(v: Any) -> RealizationSettings:
    if v is None:
        return RealizationSettings(enabled=False)
    d = _obj(v, "realization")
    keys = {"enabled", "p", "rho", "d", "d_fraction", "rho_fraction", "fixed", "max_k"}
    _check_keys(d, keys, "realization")
    enabled = d.get("enabled", True)
    if not isinstance(enabled, bool):
        raise DesignFileError("realization.enabled", "must be true or false")
    fixed_raw = _obj(d.get("fixed", {}), "realization.fixed")
    fixed = {}
    for k, s in fixed_raw.items():
        if not (isinstance(k, str) and k.isdigit() and 0 <= int(k) < 6):
            raise DesignFileError(f"realization.fixed.{k}", "keys must be vertex indices 0..5")
        fixed[int(k)] = _num(s, f"realization.fixed.{k}")
    max_k = d.get("max_k", 50)
    if isinstance(max_k, bool) or not isinstance(max_k, int) or max_k < 1:
        raise DesignFileError("realization.max_k", f"must be an integer >= 1, got {max_k!r}")
    return RealizationSettings(
        enabled,
        _num(d.get("p", 10.0), "realization.p", positive=True),
        _num(d.get("rho"), "realization.rho", positive=True, allow_none=True),
        _num(d.get("d"), "realization.d", positive=True, allow_none=True),
        _num(d.get("d_fraction", 0.01), "realization.d_fraction", positive=True),
        _num(d.get("rho_fraction", 0.25), "realization.rho_fraction", positive=True),
        fixed,
        max_k,
    )


def design_from_dict(data: Any) -> Design:
    """Validate a parsed JSON design; raises DesignFileError naming the first bad field."""
    d = _obj(data, "design")
    allowed = {"format", "version", "name", "poses", "motion", "inertia", "loop",
               "realization", "locked", "evolution", "end_effector"}
    _check_keys(d, allowed, "design")
    if d.get("format", FORMAT) != FORMAT:
        raise DesignFileError("format", f"must be {FORMAT!r}")
    version = d.get("version", VERSION)
    if version != VERSION:
        raise DesignFileError("version", f"unsupported version {version!r} (this is {VERSION})")
    name = d.get("name", "untitled")
    if not isinstance(name, str):
        raise DesignFileError("name", "must be a string")
    poses_raw = d.get("poses")
    if not isinstance(poses_raw, list) or len(poses_raw) < 4:
        raise DesignFileError("poses", "must be a list of at least 4 poses")
    poses = tuple(_pose(p, f"poses[{i}]") for i, p in enumerate(poses_raw))
    motion = _motion(d.get("motion", {}))
    loop = d.get("loop", 0)
    if isinstance(loop, bool) or not isinstance(loop, int) or not 0 <= loop < 9:
        raise DesignFileError("loop", f"must be an integer 0..8, got {loop!r}")
    locked = d.get("locked", [])
    if not isinstance(locked, list) or any(
        isinstance(i, bool) or not isinstance(i, int) or not 0 <= i < len(poses) for i in locked
    ):
        raise DesignFileError("locked", "must be a list of pose indices")
    return Design(
        name=name,
        poses=poses,
        motion=motion,
        inertia=_inertia(d.get("inertia", {})),
        loop=loop,
        realization=_realization(d.get("realization", {})),
        locked=tuple(sorted(set(locked))),
        evolution=_evolution(d.get("evolution", {}), len(poses)),
        end_effector=_end_effector(d.get("end_effector")),
    )


def _end_effector(v: Any) -> EndEffectorSettings | None:
    if v is None:
        return None
    d = _obj(v, "end_effector")
    _check_keys(d, {"mesh", "shape", "scale", "L", "R", "clearance"}, "end_effector")
    mesh, shape = d.get("mesh"), d.get("shape")
    if (mesh is None) == (shape is None):
        raise DesignFileError("end_effector", "give exactly one of 'mesh' (a file) or 'shape'")
    if mesh is not None and not (isinstance(mesh, str) and mesh):
        raise DesignFileError("end_effector.mesh", "must be a file path")
    if shape is not None and shape not in ("disc", "panel"):
        raise DesignFileError("end_effector.shape", f"must be 'disc' or 'panel', got {shape!r}")
    ends = {}
    for key in ("L", "R"):
        idx = d.get(key)
        if idx is not None and (isinstance(idx, bool) or not isinstance(idx, int) or idx < 0):
            raise DesignFileError(f"end_effector.{key}", "must be a vertex index or null")
        ends[key] = idx
    return EndEffectorSettings(
        mesh, shape, _num(d.get("scale", 1.0), "end_effector.scale", positive=True),
        ends["L"], ends["R"],
        _num(d.get("clearance"), "end_effector.clearance", positive=True, allow_none=True))

def _evolution(v: Any, n_poses: int) -> dict[str, Any]:
    """Evolution settings stay JSON-native in the design; validated by building them once."""
    # local: the evolution stack is heavy
    from paraloop_core.motion.evolution import evolution_settings

    d = dict(_obj(v, "evolution"))
    try:
        settings = evolution_settings(d)
    except (TypeError, ValueError) as exc:
        raise DesignFileError("evolution", str(exc)) from exc
    if settings.four_pose_indices is not None and max(settings.four_pose_indices) >= n_poses:
        raise DesignFileError("evolution.four_pose_indices",
                              f"indices must be < the number of poses ({n_poses})")
    return d


def _pose_dict(p: Pose) -> dict[str, list[float]]:
    return {"position": p.position.tolist(), "wxyz": p.wxyz.tolist()}


def check_pose_count(design: Design) -> None:
    """The motion method's pose count (checked when solving, not when loading: a design being
    edited, e.g. a pose added before switching to 'fit', must still save and load)."""
    n, method = len(design.poses), design.motion.method
    if method == "four-pose" and n != 4:
        raise DesignFileError("poses", f"method 'four-pose' needs exactly 4 poses, got {n} "
                              "(use method 'fit' for 5 or more)")
    if method == "fit" and n < 5:
        raise DesignFileError("poses", f"method 'fit' needs at least 5 poses, got {n}")


def design_to_dict(design: Design) -> dict[str, Any]:
    """JSON-ready dict of a design (round-trips through :func:`design_from_dict`)."""
    r = design.realization
    return {
        "format": FORMAT,
        "version": VERSION,
        "name": design.name,
        "poses": [_pose_dict(p) for p in design.poses],
        "motion": {
            "method": design.motion.method,
            "family": design.motion.family,
            "mu": "inf" if design.motion.mu is None else design.motion.mu,
            "criterion": design.motion.criterion,
            "targets": None if design.motion.targets is None else design.motion.targets.tolist(),
            "extra_poses": [_pose_dict(p) for p in design.motion.extra_poses],
        },
        "inertia": {
            "center": design.inertia.center.tolist(),
            "semi_axes": design.inertia.semi_axes.tolist(),
            "axes": design.inertia.axes.tolist(),
            "weight": design.inertia.weight,
        },
        "loop": design.loop,
        "realization": {
            "enabled": r.enabled, "p": r.p, "rho": r.rho, "d": r.d, "d_fraction": r.d_fraction,
            "rho_fraction": r.rho_fraction, "fixed": {str(k): v for k, v in r.fixed.items()},
            "max_k": r.max_k,
        },
        "locked": list(design.locked),
        "evolution": dict(design.evolution),
        "end_effector": None if design.end_effector is None else {
            "mesh": design.end_effector.mesh, "shape": design.end_effector.shape,
            "scale": design.end_effector.scale, "L": design.end_effector.L,
            "R": design.end_effector.R, "clearance": design.end_effector.clearance},
    }


def load_design(path: str | Path) -> Design:
    """Read and validate a design file; unreadable or non-JSON files raise DesignFileError."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise DesignFileError("file", f"cannot read {path}: {exc}") from exc
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise DesignFileError("file", f"not valid JSON (line {exc.lineno}: {exc.msg})") from exc
    return replace(design_from_dict(data), base_dir=str(Path(path).resolve().parent))


def save_design(design: Design, path: str | Path) -> None:
    """Write a design atomically (temporary file + rename), so a crash never truncates it."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(design_to_dict(design), indent=2) + "\n", encoding="utf-8")
    tmp.replace(path)
