"""The linkage drawn as an object: solid links (a tube per bar, rounded ends, a hub per link
at each joint) as instanced cylinders and spheres, cheap to move while dragging, and per-link
meshes moving with their links (carved design spaces, printable parts).

Geometry is in the world frame at one parameter ``t``: the realization's 12 points
``S_0 E_0 .. S_5 E_5`` carried by their links (bar ``S_iE_i`` of link i, joint ``i`` the
segment ``E_iS_{i+1}`` on axis ``A_i``). Per-link meshes are given in their link's home frame
(the world frame at ``t = inf``) and posed with ``loops.link_poses``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
import trimesh
import viser
from viser import transforms as tf

#: Link colours: base link grey, end link (3) dark orange, the others orange.
LINK_COLORS = np.array([[90, 90, 100], [230, 110, 0], [230, 110, 0], [190, 50, 0],
                        [230, 110, 0], [230, 110, 0]], dtype=np.uint8)
#: Hub radius and shortest hub (half a joint) in bar radii.
HUB_RADIUS = 1.8
HUB_MIN = 1.5

CYLINDER = trimesh.creation.cylinder(radius=1.0, height=1.0, sections=24)
SPHERE = trimesh.creation.icosphere(subdivisions=2, radius=1.0)


def z_to(d: np.ndarray) -> np.ndarray:
    """Unit ``wxyz`` ``(N, 4)`` of the shortest rotations taking +z to unit vectors ``(N, 3)``."""
    q = np.stack([1.0 + d[:, 2], -d[:, 1], d[:, 0], np.zeros(len(d))], axis=-1)
    flip = q[:, 0] < 1e-9  # d = -z: any half turn about a horizontal axis
    q[flip] = [0.0, 1.0, 0.0, 0.0]
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def cylinders(a: np.ndarray, b: np.ndarray, radius: float, min_len: float,
              fallback: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
    """Instance positions, wxyz and scales of unit :data:`CYLINDER` s from ``a`` to ``b``
    (``(N, 3)``); with ``fallback`` directions ``(N, 3)`` shorter ones get ``min_len`` along
    them (joint hubs)."""
    v = b - a
    n = np.linalg.norm(v, axis=-1)
    short = n < min_len
    d = v / np.where(n > 0, n, 1.0)[:, None]
    if fallback is not None:
        fb = fallback / np.linalg.norm(fallback, axis=-1, keepdims=True)
        d = np.where(short[:, None], fb, d)
    length = np.maximum(n, min_len) if fallback is not None else np.maximum(n, 1e-9)
    scales = np.stack([np.full(len(a), radius), np.full(len(a), radius), length], axis=-1)
    return 0.5 * (a + b), z_to(d), scales


@dataclasses.dataclass(frozen=True)
class Instances:
    """Batched mesh instances: positions ``(N, 3)``, wxyz ``(N, 4)``, scales ``(N, 3)`` and
    colours ``(N, 3)`` uint8."""

    positions: np.ndarray
    wxyzs: np.ndarray
    scales: np.ndarray
    colors: np.ndarray


def solid_links(pts: np.ndarray, axis_dirs: np.ndarray, radius: float,
                end_link: np.ndarray | None = None) -> dict[str, Instances]:
    """The linkage at one ``t`` as solid links: ``bars`` (tubes ``S_iE_i`` of ``radius``),
    ``elbows`` (spheres closing every tube end) and ``joints`` (per joint ``i`` two hubs of
    :data:`HUB_RADIUS` bar radii on axis ``A_i``, link i's from ``E_i`` and link i+1's from
    ``S_{i+1}``, meeting halfway). ``pts`` ``(12, 3)`` world points, ``axis_dirs`` ``(6, 3)``
    the joint axes' directions, ``end_link`` ``(4, 3)`` world ``S_3, L, R, E_3`` when an
    end-effector replaces the bar ``S_3E_3`` by ``S_3L`` and ``RE_3``."""
    starts, ends, colors = pts[0::2], pts[1::2], LINK_COLORS
    e, s_next = pts[1::2], np.roll(pts[0::2], -1, axis=0)
    if end_link is not None:
        starts = np.vstack([starts[:3], end_link[[0, 2]], starts[4:]])
        ends = np.vstack([ends[:3], [end_link[1], ends[3]], ends[4:]])
        colors = np.vstack([LINK_COLORS[:4], LINK_COLORS[3:]])
    bars = Instances(*cylinders(starts, ends, radius, radius), colors)
    tips = np.vstack([starts, ends])
    n = len(tips)
    elbows = Instances(tips, np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)), np.full((n, 3), radius),
                       np.vstack([colors, colors]))
    joints = _hubs(e, s_next, axis_dirs, HUB_RADIUS * radius, HUB_MIN * radius)
    return {"bars": bars, "elbows": elbows, "joints": joints}


def _hubs(e: np.ndarray, s_next: np.ndarray, axis_dirs: np.ndarray, radius: float,
          min_len: float) -> Instances:
    """Two hubs per joint on its axis, meeting at the middle ``m`` of ``E_iS_{i+1}``: link
    i's on the ``E_i`` side, link i+1's on the other, each half the joint long (at least
    ``min_len``)."""
    v = s_next - e
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    fb = axis_dirs / np.linalg.norm(axis_dirs, axis=-1, keepdims=True)
    a = np.where(n > 1e-12 * max(float(n.max()), 1.0), v / np.maximum(n, 1e-300), fb)
    half = np.maximum(0.5 * n, min_len)
    mid = 0.5 * (e + s_next)
    q = z_to(a)
    scales = np.hstack([np.full((len(e), 2), radius), half])
    return Instances(np.vstack([mid - 0.5 * half * a, mid + 0.5 * half * a]), np.vstack([q, q]),
                     np.vstack([scales, scales]),
                     np.vstack([LINK_COLORS, np.roll(LINK_COLORS, -1, axis=0)]))


def draw_instances(server: viser.ViserServer, handles: dict[str, Any], key: str, path: str,
                   shape: trimesh.Trimesh, inst: Instances, **style: Any) -> None:
    """Create ``handles[key]`` (batched ``shape`` at ``path``) or move its instances; the
    handle is recreated when the instance count changes."""
    h = handles.get(key)
    if h is not None and len(h.batched_positions) != len(inst.positions):
        handles.pop(key).remove()
        h = None
    if h is None:
        handles[key] = server.scene.add_batched_meshes_simple(
            path, shape.vertices, shape.faces, inst.wxyzs, inst.positions,
            batched_scales=inst.scales, batched_colors=inst.colors, lod="off", **style)
        return
    h.batched_positions, h.batched_wxyzs, h.batched_scales = \
        inst.positions, inst.wxyzs, inst.scales
    if not np.array_equal(h.batched_colors, inst.colors):
        h.batched_colors = inst.colors


def posed_triangles(vertices: np.ndarray, faces: np.ndarray, positions: np.ndarray,
                    wxyzs: np.ndarray, scales: np.ndarray | float = 1.0) -> np.ndarray:
    """Triangles ``(M, 3, 3)`` of a mesh placed at ``positions`` ``(3,)`` or ``(K, 3)`` with
    rotations ``wxyzs`` and per-axis ``scales`` (instances: ``K`` copies)."""
    pos = np.asarray(positions, float).reshape(-1, 3)
    rot = tf.SO3(np.asarray(wxyzs, float).reshape(-1, 4)).as_matrix().reshape(-1, 3, 3)
    scale = np.broadcast_to(np.asarray(scales, float).reshape(-1, 3) if np.ndim(scales)
                            else float(scales), (len(pos), 3))
    v = np.asarray(vertices, float)
    world = np.einsum("kij,kvj->kvi", rot, v[None] * scale[:, None]) + pos[:, None]
    return world[:, np.asarray(faces)].reshape(-1, 3, 3)


class LinkMeshes:
    """Meshes of the six links (some may be missing) in their home frames, drawn at
    ``path/i`` and moved with their links; they belong to one loop (its joint factors)."""

    def __init__(self, server: viser.ViserServer, path: str, colors: np.ndarray,
                 opacity: float) -> None:
        self.server, self.path, self.colors, self.opacity = server, path, colors, opacity
        self.handles: list[tuple[int, Any]] = []  # (link, mesh handle)
        self.joint_factors: np.ndarray | None = None

    def set(self, joint_factors: np.ndarray,
            bodies: Sequence[tuple[np.ndarray, np.ndarray] | None]) -> None:
        """Replace the meshes: ``bodies[i]`` (vertices ``(V, 3)``, faces ``(F, 3)``) of link
        i in its home frame (design units), or None."""
        self.clear()
        self.joint_factors = np.array(joint_factors, float)
        self.handles = [(i, self.server.scene.add_mesh_simple(
            f"{self.path}/{i}", np.asarray(b[0], np.float32), np.asarray(b[1], np.uint32),
            color=tuple(int(c) for c in self.colors[i]), opacity=self.opacity,
            side="double" if self.opacity < 1.0 else "front",
            cast_shadow=False, receive_shadow=False))
            for i, b in enumerate(bodies) if b is not None]

    def clear(self) -> None:
        for _, h in self.handles:
            h.remove()
        self.handles, self.joint_factors = [], None

    def current(self, joint_factors: np.ndarray | None) -> bool:
        """Whether the meshes belong to the loop of ``joint_factors``."""
        return (bool(self.handles) and joint_factors is not None
                and self.joint_factors is not None
                and np.array_equal(self.joint_factors, joint_factors))

    def move(self, positions: np.ndarray, wxyzs: np.ndarray) -> None:
        """Pose link i's mesh at ``positions[i]``, ``wxyzs[i]`` (``(6, 3)``, ``(6, 4)``)."""
        for i, h in self.handles:
            h.position, h.wxyz = positions[i], wxyzs[i]

    def show(self, visible: bool) -> None:
        for _, h in self.handles:
            if h.visible != visible:
                h.visible = visible

    def triangles(self) -> np.ndarray:
        """The meshes' triangles ``(M, 3, 3)`` as posed (world frame)."""
        return np.concatenate([posed_triangles(h.vertices, h.faces, h.position, h.wxyz)
                               for _, h in self.handles] or [np.zeros((0, 3, 3))])

    def __iter__(self) -> Iterator[tuple[int, Any]]:
        """The ``(link, mesh handle)`` pairs."""
        return iter(self.handles)

    def __len__(self) -> int:
        return len(self.handles)
