"""The versioned JSON design format (documented in ``docs/design-format.md``).

A design is what the user edits: target poses in the world frame (position in design units +
``wxyz``; the first pose is the reference S_0), motion settings, the inertia ellipsoid of the
moving body, the chosen loop, realization and drive settings. Loading validates every field
and raises :class:`~paraloop_core.errors.DesignFileError` naming the JSON path of the first
bad field.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from paraloop_core import design_checks as chk
from paraloop_core.design_checks import MAX_LENGTH
from paraloop_core.errors import DesignFileError, shown, shown_key
from paraloop_core.tolerance import TOL

FORMAT = "paraloop-design"
VERSION = 1
METHODS = ("four-pose", "three-pose", "fit")
#: The linkage a design makes: the paradoxical 6R loops of a cubic (methods 'four-pose' and
#: 'fit') or the Bennett 4R of the quadratic through three poses (method 'three-pose').
LINKAGES = ("6R", "bennett")
CRITERIA = ("base-axes", "end-axes", "length", "extra-poses", "smooth-drive")


@dataclass(frozen=True)
class Pose:
    """A target pose: ``position`` (3,) world frame, design units; ``wxyz`` (4,) unit quaternion."""

    position: np.ndarray
    wxyz: np.ndarray


@dataclass(frozen=True)
class MotionSettings:
    """``method``: 'four-pose' (exactly 4 poses), 'three-pose' (exactly 3: the Bennett 4R) or
    'fit' (>= 5); ``family`` 0|1; ``mu`` the family parameter (None = infinity); ``criterion``
    (if set, mu is chosen by :func:`selection.best_mu`); ``targets`` (2, 3) world points for
    the axis criteria; ``extra_poses`` for 'extra-poses'."""

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
class DriveSettings:
    """Motor drive (docs/realization.md, Drive analysis): ``motor`` joint 0..5 (None = the
    recommended one), ``cycle_time_s`` (s), limits on every joint's peak / mean speed and
    angular acceleration (rad/s^2; None = chosen by the planner), material density (kg/m^3)."""

    motor: int | None = None
    cycle_time_s: float = 10.0
    max_speed_ratio: float | None = None
    max_accel_rad_s2: float | None = None
    density_kg_m3: float = 1240.0  # PLA


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
    drive: DriveSettings = DriveSettings()
    #: folder that relative paths in the design (the end-effector mesh) refer to, and folders
    #: whose meshes it finds by file name besides the bundled ones (the studio's uploads);
    #: not saved. A loaded design (base_dir set) finds its mesh only there
    #: (:func:`mesh_file`); one built in Python (base_dir None) uses the path as given.
    base_dir: str | None = None
    mesh_dirs: tuple[str, ...] = ()

    @property
    def linkage(self) -> str:
        """'bennett' for method 'three-pose', else '6R' (:data:`LINKAGES`)."""
        return "bennett" if self.motion.method == "three-pose" else "6R"

    @property
    def pose_array(self) -> tuple[np.ndarray, np.ndarray]:
        """Positions (m, 3) and wxyz (m, 4)."""
        return (np.array([p.position for p in self.poses]), np.array([p.wxyz for p in self.poses]))


def _vec(v: Any, n: int, path: str, lo: float = -MAX_LENGTH, hi: float = MAX_LENGTH) -> np.ndarray:
    items = chk.array(v, path, n, n, "numbers")
    return np.array([chk.number(x, f"{path}[{i}]", lo, hi) for i, x in enumerate(items)])


def _pose(v: Any, path: str) -> Pose:
    d = chk.obj(v, path)
    chk.check_keys(d, {"position", "wxyz"}, path)
    for key in ("position", "wxyz"):
        if key not in d:
            raise DesignFileError(f"{path}.{key}", "missing")
    q = _vec(d["wxyz"], 4, f"{path}.wxyz")
    n = float(np.linalg.norm(q))
    if not n >= TOL.zero:
        raise DesignFileError(f"{path}.wxyz", "quaternion must be nonzero")
    return Pose(_vec(d["position"], 3, f"{path}.position"), q / n)


def _poses(v: Any, path: str, lo: int) -> tuple[Pose, ...]:
    items = chk.array(v, path, lo, chk.MAX_POSES, "poses")
    return tuple(_pose(p, f"{path}[{i}]") for i, p in enumerate(items))


def _choice(v: Any, path: str, options: tuple) -> Any:
    if not isinstance(v, (str, type(None))) or v not in options:
        raise DesignFileError(path, f"must be one of {', '.join(map(shown, options))}, "
                              f"got {shown(v)}")
    return v


def _motion(v: Any, default_method: str) -> MotionSettings:
    d = chk.obj(v, "motion")
    chk.check_keys(d, {"method", "family", "mu", "criterion", "targets", "extra_poses"}, "motion")
    method = _choice(d.get("method", default_method), "motion.method", METHODS)
    family = chk.integer(d.get("family", 0), "motion.family", 0, 1)
    mu = d.get("mu", "inf")
    mu = None if mu == "inf" else chk.number(mu, "motion.mu")
    crit = _choice(d.get("criterion"), "motion.criterion", (*CRITERIA, None))
    targets = None
    if d.get("targets") is not None:
        rows = chk.array(d["targets"], "motion.targets", 2, 2, "points [x, y, z]")
        targets = np.array([_vec(r, 3, f"motion.targets[{i}]") for i, r in enumerate(rows)])
    extra_poses = _poses(d.get("extra_poses", []), "motion.extra_poses", 0)
    if crit in ("base-axes", "end-axes") and targets is None:
        raise DesignFileError("motion.targets", f"criterion {crit!r} needs two target points")
    if crit == "extra-poses" and not extra_poses:
        raise DesignFileError("motion.extra_poses", "criterion 'extra-poses' needs poses")
    return MotionSettings(method, family, mu, crit, targets, extra_poses)


def _inertia(v: Any) -> InertiaSettings:
    d = chk.obj(v, "inertia")
    chk.check_keys(d, {"center", "semi_axes", "axes", "weight"}, "inertia")
    out = InertiaSettings()
    center = _vec(d["center"], 3, "inertia.center") if "center" in d else out.center
    semi = (_vec(d["semi_axes"], 3, "inertia.semi_axes", 0.0) if "semi_axes" in d
            else out.semi_axes)
    if np.all(semi == 0):
        raise DesignFileError("inertia.semi_axes", "must not all be zero")
    axes = out.axes
    if "axes" in d:
        rows = chk.array(d["axes"], "inertia.axes", 3, 3, "rows of 3 numbers")
        axes = np.array([_vec(r, 3, f"inertia.axes[{i}]", -2.0, 2.0) for i, r in enumerate(rows)])
        if not np.allclose(axes @ axes.T, np.eye(3), atol=TOL.orthonormal):
            raise DesignFileError("inertia.axes", "rows must be orthonormal")
    weight = chk.number(d.get("weight", 1.0), "inertia.weight", *chk.WEIGHT_RANGE)
    return InertiaSettings(center, semi, axes, weight)


def _relative_length(v: Any, path: str, extent: float) -> float | None:
    """``rho`` / ``d``: > 0 and, when the poses spread, within RELATIVE_LENGTH_RANGE x extent."""
    x = chk.positive(v, path, allow_none=True)
    lo, hi = chk.RELATIVE_LENGTH_RANGE
    if x is not None and extent > 0 and not lo * extent <= x <= hi * extent:
        raise DesignFileError(path, f"must be in [{lo * extent:.3g}, {hi * extent:.3g}] "
                              f"({lo:g} to {hi:g} times the poses' extent {extent:.3g}), "
                              f"got {x:g}")
    return x


def _realization(v: Any, extent: float) -> RealizationSettings:
    if v is None:
        return RealizationSettings(enabled=False)
    d = chk.obj(v, "realization")
    keys = {"enabled", "p", "rho", "d", "d_fraction", "rho_fraction", "fixed", "max_k"}
    chk.check_keys(d, keys, "realization")
    enabled = chk.flag(d.get("enabled", True), "realization.enabled")
    fixed_raw = chk.obj(d.get("fixed", {}), "realization.fixed")
    fixed = {}
    for k, s in fixed_raw.items():
        if k not in ("0", "1", "2", "3", "4", "5"):
            raise DesignFileError(f"realization.fixed.{shown_key(k)}",
                                  "keys must be vertex indices \"0\"..\"5\"")
        fixed[int(k)] = chk.number(s, f"realization.fixed.{k}")
    return RealizationSettings(
        enabled,
        chk.number(d.get("p", 10.0), "realization.p", *chk.P_RANGE),
        _relative_length(d.get("rho"), "realization.rho", extent),
        _relative_length(d.get("d"), "realization.d", extent),
        chk.number(d.get("d_fraction", 0.01), "realization.d_fraction", *chk.FRACTION_RANGE),
        chk.number(d.get("rho_fraction", 0.25), "realization.rho_fraction",
                   *chk.FRACTION_RANGE),
        fixed,
        chk.integer(d.get("max_k", 50), "realization.max_k", *chk.MAX_K_RANGE),
    )


def design_from_dict(data: Any) -> Design:
    """Validate a parsed JSON design; raises DesignFileError naming the first bad field."""
    d = chk.obj(data, "design")
    chk.check_depth(d)
    allowed = {"format", "version", "name", "poses", "motion", "inertia", "loop",
               "realization", "locked", "evolution", "end_effector", "drive", "linkage"}
    chk.check_keys(d, allowed, "design")
    if d.get("format", FORMAT) != FORMAT:
        raise DesignFileError("format", f"must be {shown(FORMAT)}, got {shown(d['format'])}")
    version = d.get("version", VERSION)
    if type(version) is not int or version != VERSION:
        raise DesignFileError("version", f"must be the integer {VERSION}, got "
                              f"{shown(version)}")
    name = d.get("name", "untitled")
    if not isinstance(name, str) or len(name) > chk.MAX_NAME:
        raise DesignFileError("name", f"must be a string of at most {chk.MAX_NAME} characters, "
                              f"got {shown(name)}")
    if "poses" not in d:
        raise DesignFileError("poses", "missing")
    poses = _poses(d["poses"], "poses", chk.MIN_POSES)
    positions = np.array([p.position for p in poses])
    extent = float(np.max(np.linalg.norm(positions - positions[0], axis=1)))
    motion, loop = _linkage(d, len(poses))
    locked = chk.array(d.get("locked", []), "locked", 0, len(poses), "pose indices")
    locked = [chk.integer(i, f"locked[{j}]", 0, len(poses) - 1) for j, i in enumerate(locked)]
    return Design(
        name=name,
        poses=poses,
        motion=motion,
        inertia=_inertia(d.get("inertia", {})),
        loop=loop,
        realization=_realization(d.get("realization", {}), extent),
        locked=tuple(sorted(set(locked))),
        evolution=chk.evolution(d.get("evolution", {}), len(poses)),
        end_effector=_end_effector(d.get("end_effector")),
        drive=DriveSettings(**chk.drive(d.get("drive", {}))),
    )


def _linkage(d: dict, n_poses: int) -> tuple[MotionSettings, int]:
    """Motion settings and loop of design dict ``d``, checked against its ``linkage``: absent,
    it follows the method ('bennett' for 'three-pose'); the method's default is 'three-pose'
    for a Bennett linkage or, with no linkage given, exactly three poses. A Bennett design has
    one loop (0) and no mu to choose (no criterion)."""
    linkage = _choice(d.get("linkage"), "linkage", (*LINKAGES, None))
    bennett = linkage == "bennett" or (linkage is None and n_poses == 3)
    motion = _motion(d.get("motion", {}), "three-pose" if bennett else "four-pose")
    three = motion.method == "three-pose"
    if linkage is not None and (linkage == "bennett") != three:
        wanted = '"three-pose"' if linkage == "bennett" else '"four-pose" or "fit"'
        raise DesignFileError("motion.method", f"linkage {shown(linkage)} is made by method "
                              f"{wanted}, got {shown(motion.method)}")
    loop = chk.integer(d.get("loop", 0), "loop", 0, 8)
    if three and loop != 0:
        raise DesignFileError("loop", f"a Bennett linkage (three poses) has one loop: 0, got "
                              f"{loop}")
    if three and motion.criterion is not None:
        raise DesignFileError("motion.criterion", "a Bennett linkage (three poses) has one "
                              f"motion: no mu to choose, got {shown(motion.criterion)}")
    return motion, loop


def _end_effector(v: Any) -> EndEffectorSettings | None:
    if v is None:
        return None
    d = chk.obj(v, "end_effector")
    chk.check_keys(d, {"mesh", "shape", "scale", "L", "R", "clearance"}, "end_effector")
    mesh, shape = d.get("mesh"), d.get("shape")
    if (mesh is None) == (shape is None):
        raise DesignFileError("end_effector", "give exactly one of 'mesh' (a file) or 'shape'")
    if mesh is not None and not (isinstance(mesh, str) and 0 < len(mesh) <= chk.MAX_PATH
                                 and "\x00" not in mesh):
        raise DesignFileError("end_effector.mesh", f"must be a file path (1..{chk.MAX_PATH} "
                              f"characters, no NUL), got {shown(mesh)}")
    if shape is not None:
        _choice(shape, "end_effector.shape", ("disc", "panel"))
    ends = {}
    for key in ("L", "R"):
        idx = d.get(key)
        ends[key] = None if idx is None else chk.integer(idx, f"end_effector.{key}", 0,
                                                         chk.MAX_VERTEX_INDEX)
    return EndEffectorSettings(
        mesh, shape, chk.positive(d.get("scale", 1.0), "end_effector.scale"),
        ends["L"], ends["R"],
        chk.positive(d.get("clearance"), "end_effector.clearance", allow_none=True))


def _pose_dict(p: Pose) -> dict[str, list[float]]:
    return {"position": p.position.tolist(), "wxyz": p.wxyz.tolist()}


def check_pose_count(design: Design) -> None:
    """The motion method's pose count (checked when solving, not when loading: a design being
    edited, e.g. a pose added before switching to 'fit', must still save and load)."""
    n, method = len(design.poses), design.motion.method
    if method == "four-pose" and n != 4:
        raise DesignFileError("poses", f"method 'four-pose' needs exactly 4 poses, got {n} "
                              "(use method 'three-pose' for 3, 'fit' for 5 or more)")
    if method == "three-pose" and n != 3:
        raise DesignFileError("poses", f"method 'three-pose' (the Bennett linkage) needs "
                              f"exactly 3 poses, got {n}")
    if method == "fit" and n < 5:
        raise DesignFileError("poses", f"method 'fit' needs at least 5 poses, got {n}")


def design_to_dict(design: Design) -> dict[str, Any]:
    """JSON-ready dict of a design (round-trips through :func:`design_from_dict`)."""
    r = design.realization
    return {
        "format": FORMAT,
        "version": VERSION,
        "name": design.name,
        "linkage": design.linkage,
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
        "drive": asdict(design.drive),
    }


def load_design_bytes(data: bytes, *, base_dir: str | Path,
                      mesh_dirs: tuple[str | Path, ...] = ()) -> Design:
    """Parse and validate a design file's bytes, the one loader of the command line and the
    studio's *Load design*: the limits of :mod:`design_checks` (size, nesting, number
    literals, UTF-8 with an optional BOM, no duplicate keys), and an end-effector mesh that
    :func:`mesh_file` finds inside ``base_dir`` (the design's folder), the bundled meshes or
    ``mesh_dirs``. Raises DesignFileError (field ``file`` for the bytes themselves)."""
    design = replace(design_from_dict(chk.parse_bytes(data)), base_dir=str(base_dir),
                     mesh_dirs=tuple(map(str, mesh_dirs)))
    mesh_file(design)  # refused now, not when solving
    return design


def load_design(path: str | Path, mesh_dirs: tuple[str | Path, ...] = (),
                base_dir: str | Path | None = None) -> Design:
    """Read a design file (a regular file within the size limit) and load it
    (:func:`load_design_bytes`); relative paths inside it refer to ``base_dir``, by default
    the file's folder (an autosave elsewhere gives its design's)."""
    folder = Path(path).resolve().parent if base_dir is None else base_dir
    return load_design_bytes(chk.read_bytes(path), base_dir=folder, mesh_dirs=mesh_dirs)


def mesh_file(design: Design) -> str | None:
    """The end-effector mesh file of ``design`` (None without one): for a loaded design
    (``base_dir`` set) only inside its folder, the bundled meshes or ``mesh_dirs``
    (:func:`design_checks.resolve_mesh`, DesignFileError otherwise); else the path as given."""
    ee = design.end_effector
    if ee is None or ee.mesh is None:
        return None
    if design.base_dir is None:
        return ee.mesh
    return chk.resolve_mesh(ee.mesh, design.base_dir, design.mesh_dirs)


def save_design(design: Design, path: str | Path) -> None:
    """Write a design atomically (temporary file + rename), so a crash never truncates it;
    strict JSON (a non-finite number raises ValueError and writes nothing)."""
    path = Path(path)
    text = json.dumps(design_to_dict(design), indent=2, allow_nan=False) + "\n"
    tmp = path.with_name(path.name + ".tmp")
    try:
        tmp.write_text(text, encoding="utf-8")
        tmp.replace(path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
