"""An export folder read for the printed-part checker, and the motion of its parts.

Independent of ``paraloop_core``: the motion comes from ``result.json`` (docs/result-format.md)
through :mod:`dense_check`'s link motions ``M_0..M_5`` (link 0 resting, t = inf the home pose,
every ``M_i(inf) = 1``); the parts move relative to the grounded link g by ``M_g^-1 M_i``. The
STL files are in the home frame in mm (design units times ``scale_mm_per_unit``);
``report.json``'s ``base.world_from_home`` puts them in the standing world (table at z = 0).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from . import dq8
from .dense_check import _key, joint_factors, link_motions, sample_parameters


@dataclass
class Export:
    """One export folder: its JSON files, meshes (home frame, mm) and derived geometry."""

    folder: Path
    result: dict
    report: dict
    scale: float  # mm per design unit
    points_mm: np.ndarray  # (12, 3) S_0, E_0, ..., S_5, E_5 at home
    links: list  # six trimesh.Trimesh, link_<i>.stl
    grounded: int | None  # base.grounded_link (None without a base)
    jf: np.ndarray  # (6, 8) joint factors [a0, a1, a2, b2, b1, b0] of the realized loop

    def mesh(self, name: str) -> trimesh.Trimesh:
        """A part's STL (home frame, mm) by its name without extension."""
        return trimesh.load(self.folder / f"{name}.stl", force="mesh")

    def world_from_home(self) -> np.ndarray:
        """The 4x4 map of the home frame (mm) to the standing world."""
        return np.asarray(self.report["base"]["world_from_home"], float)


def load_export(folder: str | Path) -> Export:
    """Read an export folder (``result.json``, ``report.json``, ``link_<i>.stl``)."""
    folder = Path(folder)
    result = json.loads((folder / "result.json").read_text())
    report = json.loads((folder / "report.json").read_text())
    scale = float(report["scale_mm_per_unit"])
    points = np.asarray(result["realization"]["points"], float) * scale
    links = [trimesh.load(folder / f"link_{i}.stl", force="mesh") for i in range(6)]
    base = report.get("base") or {}
    g = base.get("grounded_link")
    return Export(folder, result, report, scale, points, links,
                  None if g is None else int(g), joint_factors(result))


def parameters(jf: np.ndarray, n: int) -> np.ndarray:
    """At least ``n`` parameters over the projective line (t = inf included), sorted around
    the cycle (by :func:`dense_check._key`)."""
    t = sample_parameters(jf, n)
    while len(t) < n:
        n = int(n * 1.2) + 1
        t = sample_parameters(jf, n)
    return t[np.argsort(_key(t), kind="stable")]


def key_to_t(k: np.ndarray) -> np.ndarray:
    """Inverse of :func:`dense_check._key` on [-2, 2) (-2 is t = inf)."""
    k = np.asarray(k, float)
    with np.errstate(divide="ignore"):
        return np.where(np.abs(k) <= 1.0, k, np.where(k > 0, 1.0 / (2.0 - k), -1.0 / (2.0 + k)))


def relative_motion(ex: Export, t: np.ndarray, ground: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Rotations ``(T, 6, 3, 3)`` and translations ``(T, 6, 3)`` (mm) of the six links relative
    to link ``ground`` at parameters ``t`` ``(T,)``: ``x -> R x + tr`` on home-frame mm."""
    c, s = dq8.homogeneous(np.asarray(t, float))
    poses = np.stack([dq8.poly_at(m, c, s) for m in link_motions(ex.jf)], axis=1)  # (T, 6, 8)
    rel = dq8.dmul(dq8.dconj(poses[:, ground])[:, None, :], poses)
    rot, tr = dq8.rigid(rel)
    return rot, tr * ex.scale


def world_motion(ex: Export, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World rotations ``(T, 6, 3, 3)`` and translations ``(T, 6, 3)`` (mm) of the links with
    the grounded link resting (``world_from_home`` applied)."""
    rot, tr = relative_motion(ex, t, ex.grounded or 0)
    w = ex.world_from_home()
    return np.einsum("ij,tljk->tlik", w[:3, :3], rot), tr @ w[:3, :3].T + w[:3, 3]


def closure_error(ex: Export, t: np.ndarray) -> float:
    """Largest distance (mm) between a joint axis's two points moved by link j and by link
    j+1 over ``t``: the loop read from result.json closes and its axes are the joints'."""
    rot, tr = relative_motion(ex, t)
    err = 0.0
    for j in range(6):
        ends = np.stack([ex.points_mm[2 * j + 1], ex.points_mm[(2 * j + 2) % 12]])
        a = np.einsum("tij,kj->tki", rot[:, j], ends) + tr[:, j, None]
        b = np.einsum("tij,kj->tki", rot[:, (j + 1) % 6], ends) + tr[:, (j + 1) % 6, None]
        err = max(err, float(np.abs(a - b).max()))
    return err


def bars(ex: Export) -> list[tuple[int, np.ndarray, np.ndarray]]:
    """The bars ``(link, start, end)`` in mm: ``S_i E_i`` for each link; with an end effector
    (``result.json`` ``end_effector.end_link`` = S_3, L, R, E_3) link 3 is ``S_3 L`` and
    ``R E_3`` instead."""
    p = ex.points_mm
    out = [(i, p[2 * i], p[2 * i + 1]) for i in range(6)]
    ee = ex.result.get("end_effector") or {}
    if ee.get("end_link"):
        s3, left, right, e3 = np.asarray(ee["end_link"], float) * ex.scale
        out[3:4] = [(3, s3, left), (3, right, e3)]
    return out
