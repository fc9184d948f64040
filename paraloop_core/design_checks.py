"""Boundary checks of the design format: the documented limits, reading a file safely and
field validators whose errors are one line naming the JSON path and the accepted range.

The same limits are written in the shipped JSON Schema ``paraloop_core/design.schema.json``
(documented in ``docs/design-format.md``); ``tests/test_fuzz_design.py`` checks that every
design accepted here is accepted by the schema too.
"""

from __future__ import annotations

import json
import math
import os
import stat
from pathlib import Path
from typing import Any

from paraloop_core.errors import DesignFileError, shown, shown_key

#: largest design file or upload (bytes), checked before reading or parsing
MAX_FILE_BYTES = 5 * 2**20
#: deepest nesting of JSON arrays/objects (a valid design needs 4)
MAX_DEPTH = 16
#: longest number literal accepted by the parser (characters; Python's json writes <= 24,
#: and int() of a longer one costs time); a 400-digit number then reaches its field's check
MAX_NUMBER_CHARS = 1000
#: number of poses (``poses``), and at most this many ``motion.extra_poses``
MIN_POSES, MAX_POSES = 3, 1000
#: largest magnitude of any length or other number (design units: positions up to 1e12 keep
#: the required scale invariance from 1e-6 to 1e8 units with room to spare)
MAX_LENGTH = 1e12
#: longest ``name`` and ``end_effector.mesh`` strings
MAX_NAME, MAX_PATH = 1000, 4096
#: ``realization.p`` (shift divisor) and ``realization.max_k`` (search cap)
P_RANGE = (1.0, 1e4)
MAX_K_RANGE = (1, 1000)
#: ``realization.d_fraction`` and ``realization.rho_fraction``
FRACTION_RANGE = (1e-6, 10.0)
#: ``realization.d`` and ``realization.rho`` relative to the poses' extent (max |p_i - p_0|)
RELATIVE_LENGTH_RANGE = (1e-6, 1e3)
#: ``inertia.weight``
WEIGHT_RANGE = (1e-6, 1e6)
#: end-effector vertex indices ``L`` / ``R``
MAX_VERTEX_INDEX = 10**7
#: ``drive``: ``cycle_time_s`` (s), ``max_speed_ratio``, ``max_accel_rad_s2`` upper limit
#: (rad/s^2, lower bound open at 0), ``density_kg_m3``
CYCLE_TIME_RANGE = (0.01, 1e6)
SPEED_RATIO_RANGE = (1.0, 1e3)
MAX_ACCEL = 1e9
DENSITY_RANGE = (1.0, 1e5)
#: the meshes shipped with paraloop (``assets/meshes``), found by file name from any design
BUNDLED_MESHES = Path(__file__).resolve().parent.parent / "assets" / "meshes"


def _g(x: float) -> str:
    return f"{x:g}"


def number(v: Any, path: str, lo: float = -MAX_LENGTH, hi: float = MAX_LENGTH, *,
           lo_open: bool = False, allow_none: bool = False) -> float | None:
    """A finite JSON number (not a bool) in ``[lo, hi]`` (``(lo, hi]`` with ``lo_open``)."""
    if v is None and allow_none:
        return None
    rng = f"{'(' if lo_open else '['}{_g(lo)}, {_g(hi)}]"
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise DesignFileError(path, f"must be a number in {rng}, got {shown(v)}")
    if isinstance(v, float) and not math.isfinite(v):
        raise DesignFileError(path, f"must be a finite number in {rng}, got {shown(v)}")
    if (v <= lo if lo_open else v < lo) or v > hi:  # exact int/float comparison: no overflow
        raise DesignFileError(path, f"must be in {rng}, got {shown(v)}")
    return float(v)


def positive(v: Any, path: str, hi: float = MAX_LENGTH, *, allow_none: bool = False) -> Any:
    """A number in ``(0, hi]``."""
    return number(v, path, 0.0, hi, lo_open=True, allow_none=allow_none)


def integer(v: Any, path: str, lo: int, hi: int) -> int:
    """A true JSON integer (not a bool, not ``2.0``) in ``lo..hi``."""
    if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
        raise DesignFileError(path, f"must be an integer in {lo}..{hi}, got {shown(v)}")
    return int(v)


def flag(v: Any, path: str) -> bool:
    if not isinstance(v, bool):
        raise DesignFileError(path, f"must be true or false, got {shown(v)}")
    return v


def obj(v: Any, path: str) -> dict:
    if not isinstance(v, dict):
        raise DesignFileError(path, f"must be an object, got {type(v).__name__}")
    return v


def array(v: Any, path: str, lo: int, hi: int, what: str = "items") -> list:
    """A JSON array with ``lo..hi`` entries."""
    if not isinstance(v, (list, tuple)) or not lo <= len(v) <= hi:
        size = f"{lo}" if lo == hi else f"{lo}..{hi}"
        got = f"{len(v)} entries" if isinstance(v, (list, tuple)) else shown(v)
        raise DesignFileError(path, f"must be a list of {size} {what}, got {got}")
    return list(v)


def check_keys(d: dict, allowed: set[str], path: str) -> None:
    """Refuse the first unknown key, naming it and the allowed ones."""
    extra = sorted((k for k in d if k not in allowed), key=str)
    if extra:
        raise DesignFileError(f"{path}.{shown_key(extra[0])}", f"unknown key {shown(extra[0])} "
                              f"at {path} "
                              f"(allowed: {', '.join(sorted(allowed))})")


_DRIVE = {
    "motor": lambda x, p: None if x is None else integer(x, p, 0, 5),
    "cycle_time_s": lambda x, p: number(x, p, *CYCLE_TIME_RANGE),
    "max_speed_ratio": lambda x, p: number(x, p, *SPEED_RATIO_RANGE, allow_none=True),
    "max_accel_rad_s2": lambda x, p: positive(x, p, MAX_ACCEL, allow_none=True),
    "density_kg_m3": lambda x, p: number(x, p, *DENSITY_RANGE),
}


def drive(v: Any) -> dict[str, Any]:
    """The ``drive`` section's given fields, validated (``design.DriveSettings`` keyword
    arguments; absent fields keep their defaults)."""
    d = obj(v, "drive")
    check_keys(d, set(_DRIVE), "drive")
    return {k: _DRIVE[k](x, f"drive.{k}") for k, x in d.items()}


def evolution(v: Any, n_poses: int) -> dict[str, Any]:
    """Evolution settings stay JSON-native in the design; validated by building them once."""
    # local: the evolution stack is heavy
    from paraloop_core.motion.evolution import evolution_settings

    d = dict(obj(v, "evolution"))
    try:
        settings = evolution_settings(d)
    except DesignFileError as exc:
        raise DesignFileError(f"evolution.{exc.field}", exc.message) from exc
    except (TypeError, ValueError) as exc:
        raise DesignFileError("evolution", str(exc)[:200]) from exc
    if settings.four_pose_indices is not None and max(settings.four_pose_indices) >= n_poses:
        raise DesignFileError("evolution.four_pose_indices",
                              f"indices must be < the number of poses ({n_poses})")
    return d


def design_field(param: str | None, design: Any) -> str | None:
    """The design field a realization or end-effector parameter (``ParaloopError.param``)
    came from: ``rho`` is ``realization.rho`` when set, else ``realization.rho_fraction``."""
    r, owner = design.realization, "end_effector" if param in _EE_PARAMS else "realization"
    if param in ("rho", "d") and getattr(r, param) is None:
        param += "_fraction"
    return None if param is None else f"{owner}.{param}"


_EE_PARAMS = ("mesh", "scale", "L", "R", "clearance")


def check_depth(data: Any, path: str = "design") -> None:
    """Refuse nesting deeper than :data:`MAX_DEPTH` (iteratively: no RecursionError)."""
    stack = [(data, 1)]
    while stack:
        node, depth = stack.pop()
        if isinstance(node, dict):
            children: Any = node.values()
        elif isinstance(node, (list, tuple)):
            children = node
        else:
            continue
        if depth > MAX_DEPTH:
            raise DesignFileError(path, f"nested deeper than {MAX_DEPTH} levels")
        stack.extend((c, depth + 1) for c in children)


def read_bytes(path: str | Path) -> bytes:
    """The bytes of a regular file of at most :data:`MAX_FILE_BYTES`; FIFOs, devices and
    directories are refused without blocking (``file`` errors name what the path is)."""
    try:
        st = os.stat(path)
    except (OSError, ValueError) as exc:
        raise DesignFileError("file", f"cannot read: {getattr(exc, 'strerror', None) or exc}")\
            from exc
    if stat.S_ISDIR(st.st_mode):
        raise DesignFileError("file", "cannot read: is a directory")
    if not stat.S_ISREG(st.st_mode):
        raise DesignFileError("file", "cannot read: not a regular file (FIFO, device or socket)")
    _check_size(st.st_size)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0))
        with os.fdopen(fd, "rb") as fh:
            if not stat.S_ISREG(os.fstat(fh.fileno()).st_mode):
                raise DesignFileError("file", "cannot read: not a regular file")
            raw = fh.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise DesignFileError("file", f"cannot read: {exc.strerror or exc}") from exc
    _check_size(len(raw))
    return raw


def _check_size(size: int) -> None:
    if size > MAX_FILE_BYTES:
        raise DesignFileError("file", f"{size} bytes, over the limit of {MAX_FILE_BYTES} bytes "
                              f"({MAX_FILE_BYTES // 2**20} MiB)")


def parse_bytes(raw: bytes) -> Any:
    """The JSON value of a design file's bytes: at most :data:`MAX_FILE_BYTES` (checked
    first: a huge upload is refused without being decoded), UTF-8 with an optional BOM (dropped),
    then :func:`parse_json`."""
    _check_size(len(raw))
    try:
        text = bytes(raw).decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise DesignFileError("file", f"not UTF-8 text (invalid byte at offset {exc.start})")\
            from exc
    return parse_json(text)


def _constant(name: str) -> Any:
    raise DesignFileError("file", f"{name} is not valid JSON (numbers must be finite)")


def _number(kind: type) -> Any:
    """A parse hook: number literals of at most :data:`MAX_NUMBER_CHARS` characters (a long
    one costs time in ``int``; 1e400 is refused as not finite)."""

    def parse(text: str) -> Any:
        if len(text) > MAX_NUMBER_CHARS:
            raise DesignFileError("file", f"number literal of {len(text)} characters (limit "
                                  f"{MAX_NUMBER_CHARS})")
        value = kind(text)
        if kind is float and not math.isfinite(value):
            raise DesignFileError("file", f"number {text[:40]} is not finite in float64 "
                                  f"(magnitude limit about 1.8e308)")
        return value

    return parse


def _pairs(pairs: list[tuple[str, Any]]) -> dict:
    out = dict(pairs)
    if len(out) != len(pairs):
        seen: set[str] = set()
        for k, _ in pairs:
            if k in seen:
                raise DesignFileError("file", f"duplicate key {shown(k)} in an object")
            seen.add(k)
    return out


def parse_json(text: str) -> Any:
    """Strict JSON: no NaN/Infinity, no duplicate keys, bounded number literals and nesting."""
    try:
        data = json.loads(text, parse_constant=_constant, parse_int=_number(int),
                          parse_float=_number(float), object_pairs_hook=_pairs)
    except json.JSONDecodeError as exc:
        raise DesignFileError("file", f"not valid JSON (line {exc.lineno} column {exc.colno}: "
                              f"{exc.msg})") from exc
    except RecursionError as exc:
        raise DesignFileError("file", f"nested deeper than {MAX_DEPTH} levels") from exc
    check_depth(data, "file")
    return data


def _inside(path: str, folder: str) -> bool:
    try:
        return os.path.commonpath([path, folder]) == folder
    except ValueError:  # another drive
        return False


def _regular(path: str) -> bool | None:
    """True for a regular file, False for anything else that exists, None when missing or
    unreadable (a name too long, a loop of links)."""
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except (OSError, ValueError):
        return None


def resolve_mesh(mesh: str, design_dir: str | Path, mesh_dirs: tuple[str | Path, ...] = ()
                 ) -> str:
    """The file (absolute path) of a loaded design's ``end_effector.mesh``, never one elsewhere
    on the machine: ``design_dir / mesh`` when ``mesh`` is relative and that file lies inside
    ``design_dir`` or a mesh folder (:data:`BUNDLED_MESHES`, ``mesh_dirs``; the examples'
    ``../meshes/x.stl``), links followed; else the file of that *name* in a mesh folder (so a
    copy of the examples' folder still finds its mesh). Anything else (an absolute path, a path
    leaving the folders, a missing file) is refused with one message that does not tell
    whether such a file exists outside them (DesignFileError, field ``end_effector.mesh``)."""
    meshes = [os.path.abspath(d) for d in (BUNDLED_MESHES, *mesh_dirs)]
    roots = [*meshes, os.path.abspath(design_dir)]
    real_roots = [os.path.realpath(r) for r in roots]
    if not os.path.isabs(mesh):
        path = os.path.normpath(os.path.join(roots[-1], mesh))
        if (any(_inside(path, r) for r in roots)
                and any(_inside(os.path.realpath(path), r) for r in real_roots)):
            found = _regular(path)
            if found:
                return path
            if found is False:
                raise DesignFileError("end_effector.mesh", f"{shown(mesh)} is not a regular "
                                      "file (a directory, FIFO or device)")
    name = mesh.replace("\\", "/").rsplit("/", 1)[-1]
    for folder in meshes:
        path = os.path.join(folder, name)
        if (name not in ("", ".", "..") and _inside(os.path.realpath(path),
                                                    os.path.realpath(folder))
                and _regular(path)):
            return path
    raise DesignFileError("end_effector.mesh", f"no mesh file {shown(mesh)} inside the design's "
                          "folder, "
                          "nor a bundled or uploaded mesh of that name; give a path relative to "
                          "the design's folder that stays inside it (absolute paths and paths "
                          "leaving it are not followed)")
