"""Drawing the design and its solution into the viser scene (called by the worker only,
inside ``server.atomic()``).

Scene tree: ``/targets/i`` gizmos (+ ``/frame``), ``/target_labels/i`` their labels (world
frame, spread apart), ``/motion/path`` trajectory,
``/motion/frames`` sampled moving frames, ``/motion/current`` the animated frame with its
``/ellipsoid``, ``/factorizations`` six factorizations' axes (Fig. 5 colours, home pose),
``/loop/axes`` the selected loop's axes and ``/loop/bars``, ``/loop/joints`` the linkage,
``/loop/ghost`` the last realized linkage while the design has none, ``/loop/spaces/i`` the
carved design spaces (moving with their links).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import trimesh
import viser

from paraloop_core.algebra import dq, poly
from paraloop_core.design import Design
from paraloop_core.errors import RealizationError
from paraloop_core.linkage import loops
from paraloop_core.realization import polyline

#: Fig. 5 colours of the six factorizations, in hexagon order of ``factor.NORM_ORDERS``.
FACTOR_COLORS = np.array(
    [[220, 40, 40], [40, 170, 60], [40, 90, 230], [230, 200, 30], [150, 60, 190], [30, 200, 210]],
    dtype=np.uint8,
)
FACTOR_COLOR_NAMES = ("red", "green", "blue", "yellow", "purple", "cyan")
#: Link colours: base link grey, end link (3) dark orange, the others orange.
LINK_COLORS = np.array([[90, 90, 100], [230, 110, 0], [230, 110, 0], [190, 50, 0],
                        [230, 110, 0], [230, 110, 0]], dtype=np.uint8)
JOINT_COLOR = (185, 185, 195)
PATH_COLOR = (40, 40, 70)
#: View layers (GUI checkboxes) and the scene handles they show.
LAYERS = {"Trajectory": ("path",), "Moving frames": ("frames",),
          "Inertia ellipsoid": ("ellipsoid",), "Factorization axes": ("facts",),
          "Loop axes": ("axes",), "Linkage": ("bars", "joints", "effector", "ghost")}
#: The carved design spaces' layer (toggled in the Fabrication panel) and their colours.
SPACES_LAYER = "Design spaces"
SPACE_COLORS = np.vstack([LINK_COLORS[:1], FACTOR_COLORS[:5]])
PATH_SAMPLES = 256
FRAME_SAMPLES = 24

_CYL = trimesh.creation.cylinder(radius=1.0, height=1.0, sections=20)
_SPHERE = trimesh.creation.icosphere(subdivisions=2, radius=1.0)


def design_scale(design: Design) -> float:
    """Characteristic length: the diagonal of the targets' bounding box (at least 1e-3)."""
    pos = design.pose_array[0]
    return max(float(np.linalg.norm(pos.max(0) - pos.min(0))), 1e-3)


def label_positions(targets: np.ndarray, scale: float) -> np.ndarray:
    """Label anchors ``(N, 3)`` for target positions ``(N, 3)``: pushed out from the targets'
    centroid by 0.12 ``scale``, then spread so that no two are closer than 0.12 ``scale``
    (a few relaxation steps; close or coincident targets get staggered heights)."""
    p = np.asarray(targets, float)
    away = p - p.mean(0)
    norm = np.linalg.norm(away, axis=1, keepdims=True)
    away = np.where(norm > 1e-9 * scale, away / np.maximum(norm, 1e-300), [0.0, 0.0, 1.0])
    gap = 0.12 * scale
    out = p + gap * away + np.arange(len(p))[:, None] * [0.0, 0.0, 1e-3 * scale]
    for _ in range(20):
        diff = out[:, None] - out[None]
        dist = np.linalg.norm(diff, axis=-1) + np.eye(len(p)) * gap
        push = np.clip(gap - dist, 0.0, None) / np.maximum(dist, 1e-9 * scale)
        if not push.any():
            break
        out = out + 0.5 * np.einsum("ij,ijk->ik", push, diff)
    return out


def z_to(d: np.ndarray) -> np.ndarray:
    """Unit ``wxyz`` ``(N, 4)`` of the shortest rotations taking +z to unit vectors ``(N, 3)``."""
    q = np.stack([1.0 + d[:, 2], -d[:, 1], d[:, 0], np.zeros(len(d))], axis=-1)
    flip = q[:, 0] < 1e-9  # d = -z: any half turn about a horizontal axis
    q[flip] = [0.0, 1.0, 0.0, 0.0]
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def axis_segments(lines: np.ndarray, centers: np.ndarray, length: float) -> np.ndarray:
    """Segments ``(N, 2, 3)`` of Plücker lines ``(N, 6)`` centred at the feet of ``centers``."""
    d = lines[:, :3] / np.linalg.norm(lines[:, :3], axis=-1, keepdims=True)
    foot = np.cross(d, lines[:, 3:]) / np.linalg.norm(lines[:, :3], axis=-1, keepdims=True)
    foot = foot + np.sum((centers - foot) * d, -1, keepdims=True) * d
    return np.stack([foot - 0.5 * length * d, foot + 0.5 * length * d], axis=1)


def _ellipsoid_vertices(design: Design) -> np.ndarray:
    """The inertia ellipsoid's mesh vertices in the body frame."""
    s = design.inertia
    return s.center + (np.maximum(s.semi_axes, 1e-4 * design_scale(design)) * _SPHERE.vertices) \
        @ s.axes


class SceneView:
    """Owns every scene handle; only the worker calls its methods."""

    def __init__(self, server: viser.ViserServer,
                 on_gizmo: Callable[[int, viser.TransformControlsEvent], Any]) -> None:
        self.server = server
        self._on_gizmo = on_gizmo
        self.gizmos: list[viser.TransformControlsHandle] = []
        self.labels: list[Any] = []
        self.handles: dict[str, Any] = {}
        self.scale = 1.0
        self.points_home: np.ndarray | None = None  # (12, 3) linkage at t = inf
        self.joint_factors: np.ndarray | None = None
        self.bar_radius = 0.01
        self.center = np.zeros(3)
        self.loop_colors = np.zeros((6, 2, 3), dtype=np.uint8)
        self.motion: np.ndarray | None = None
        self.spaces: list[tuple[int, Any]] = []  # (link, mesh handle) of carved spaces
        self.spaces_jf: np.ndarray | None = None  # the loop they were carved for
        self.end_link: np.ndarray | None = None  # (4, 3) S_3, L, R, E_3 with an end-effector
        # the last realized linkage (joint factors, home points, radius) and, while the design
        # on screen has no realization, the same shown faintly (a "ghost")
        self.last_real: tuple[np.ndarray, np.ndarray, float] | None = None
        self.ghost: tuple[np.ndarray, np.ndarray, float] | None = None
        self.target_positions = np.zeros((0, 3))

    # --- targets ----------------------------------------------------------------------------
    def set_targets(self, design: Design) -> None:
        """Create, move or restyle the target gizmos to match ``design``."""
        scene = self.server.scene
        if not self.gizmos or abs(np.log(design_scale(design) / self.scale)) > np.log(2.0):
            self._rescale(design)
        if len(self.gizmos) != len(design.poses):
            for g in self.gizmos:
                g.remove()
            self.gizmos, self.labels = [], []
            for i, pose in enumerate(design.poses):
                g = scene.add_transform_controls(
                    f"/targets/{i}", scale=0.3 * self.scale, disable_sliders=True,
                    position=pose.position, wxyz=pose.wxyz)
                scene.add_frame(f"/targets/{i}/frame", axes_length=0.12 * self.scale,
                                axes_radius=0.006 * self.scale)
                self.labels.append(scene.add_label(f"/target_labels/{i}", f"S{i}"))
                g.on_update(self._gizmo_callback(i))
                self.gizmos.append(g)
        for i, (g, pose) in enumerate(zip(self.gizmos, design.poses, strict=True)):
            g.position, g.wxyz = pose.position, pose.wxyz
            locked = i in design.locked
            g.active_axes = (not locked,) * 3
            g.disable_rotations = locked
            g.opacity = 0.25 if locked else 1.0
        self.place_labels(design.pose_array[0])

    def place_labels(self, positions: np.ndarray) -> None:
        """Move the target labels next to the targets at ``positions`` ``(N, 3)``."""
        self.target_positions = np.asarray(positions, float)
        if len(self.labels) == len(positions):
            for label, at in zip(self.labels, label_positions(positions, self.scale),
                                 strict=True):
                label.position = at

    def extent_points(self) -> np.ndarray:
        """World points ``(N, 3)`` that framing must show: targets, trajectory, the linkage
        (or its ghost) over the cycle."""
        parts = [self.target_positions.reshape(-1, 3)]
        if "path" in self.handles:
            parts.append(np.asarray(self.handles["path"].points, float).reshape(-1, 3))
        t = poly.param_to_t(np.linspace(0.0, 1.0, 33)[:-1])
        for jf, home in ((self.joint_factors, self.points_home),
                         (None, None) if self.ghost is None else self.ghost[:2]):
            if jf is not None and home is not None:
                links = np.repeat(loops.link_poses(jf, t), 2, axis=1)  # (T, 12, 8)
                parts.append(dq.transform_points(links, home).reshape(-1, 3))
        pts = np.concatenate(parts)
        return pts[np.all(np.isfinite(pts), axis=1)]

    def _rescale(self, design: Design) -> None:
        """New characteristic length: grid, initial camera; sized handles are recreated."""
        for g in self.gizmos:
            g.remove()
        for h in reversed(self.handles.values()):  # children before parents
            h.remove()
        self.gizmos, self.labels, self.handles = [], [], {}
        self.scale = design_scale(design)
        low = design.pose_array[0][:, 2].min() - 0.25 * self.scale
        self.server.scene.add_grid("/grid", width=3 * self.scale, height=3 * self.scale,
                                   cell_size=self.scale / 8, position=(0.0, 0.0, low))

    def _gizmo_callback(self, i: int) -> Callable[[viser.TransformControlsEvent], Any]:
        async def callback(event: viser.TransformControlsEvent) -> None:
            self._on_gizmo(i, event)

        return callback

    # --- motion -----------------------------------------------------------------------------
    def draw_motion(self, sol: Any) -> None:
        """Trajectory, sampled frames, visit-order labels and the inertia ellipsoid."""
        self.motion = sol.motion
        t = poly.param_to_t(np.linspace(0.0, 1.0, PATH_SAMPLES + 1))
        pos = dq.translation_of(poly.evaluate_pose(sol.motion, t))
        segs = np.stack([pos[:-1], pos[1:]], axis=1)
        tf = poly.param_to_t(np.linspace(0.0, 1.0, FRAME_SAMPLES, endpoint=False))
        fpos, fwxyz = dq.to_pos_wxyz(poly.evaluate_pose(sol.motion, tf))
        h = self.handles
        scene = self.server.scene
        if "path" not in h:
            h["path"] = scene.add_line_segments("/motion/path", segs, PATH_COLOR, thickness=3.0,
                                                thickness_units="screen")
            h["frames"] = scene.add_batched_axes(
                "/motion/frames", fwxyz, fpos, axes_length=0.05 * self.scale,
                axes_radius=0.002 * self.scale)
            h["current"] = scene.add_frame("/motion/current", axes_length=0.12 * self.scale,
                                           axes_radius=0.006 * self.scale)
        else:
            h["path"].points = segs
            h["frames"].batched_positions, h["frames"].batched_wxyzs = fpos, fwxyz
        verts = _ellipsoid_vertices(sol.design)
        if "ellipsoid" in h:
            h["ellipsoid"].vertices = verts
        else:
            h["ellipsoid"] = scene.add_mesh_simple(
                "/motion/current/ellipsoid", verts, _SPHERE.faces, color=(120, 160, 230),
                wireframe=True, opacity=0.5, cast_shadow=False, receive_shadow=False)
        self.place_labels(sol.design.pose_array[0])
        rank = np.argsort(np.argsort(poly.t_to_param(sol.pose_parameters)))
        for i, label in enumerate(self.labels):
            lock = " (locked)" if i in sol.design.locked else ""
            label.text = f"S{i} #{rank[i] + 1}{lock}" if i < len(rank) else f"S{i}"

    def draw_factorizations(self, sol: Any) -> None:
        """Axes of the six factorizations at the home pose, coloured as the paper's Fig. 5."""
        f = sol.factorizations.factors.reshape(18, 8)
        center = sol.design.pose_array[0].mean(0)
        segs = axis_segments(loops.factor_axes(f), np.broadcast_to(center, (18, 3)),
                             0.8 * self.scale)
        colors = np.repeat(FACTOR_COLORS, 3, axis=0)[:, None, :].repeat(2, axis=1)
        if "facts" in self.handles:
            self.handles["facts"].points = segs
        else:
            self.handles["facts"] = self.server.scene.add_line_segments(
                "/factorizations", segs, colors, thickness=1.5, thickness_units="screen")

    # --- design spaces ----------------------------------------------------------------------
    def set_spaces(self, joint_factors: np.ndarray, bodies: list) -> None:
        """Replace the carved design spaces: ``bodies[i]`` (vertices, faces) in link i's home
        frame, or None (nothing meshable)."""
        for _, h in self.spaces:
            h.remove()
        self.spaces_jf = np.array(joint_factors, float)
        self.spaces = [(i, self.server.scene.add_mesh_simple(
            f"/loop/spaces/{i}", np.asarray(b[0], np.float32), np.asarray(b[1], np.uint32),
            color=tuple(int(c) for c in SPACE_COLORS[i]), opacity=0.45, side="double",
            cast_shadow=False, receive_shadow=False))
            for i, b in enumerate(bodies) if b is not None]

    def spaces_current(self) -> bool:
        """Whether the carved spaces belong to the loop on screen."""
        jf = self.joint_factors
        return (self.spaces_jf is not None and jf is not None
                and np.array_equal(self.spaces_jf, jf))

    # --- loop and linkage -------------------------------------------------------------------
    def set_loop(self, sol: Any, preview: Any = None, preview_radius: float | None = None
                 ) -> None:
        """Choose the linkage geometry: the realization's points, else a drag ``preview``
        (``pipeline.WarmPreview``; bars of ``preview_radius``), else the bare loop polyline."""
        loop = sol.loop
        self.joint_factors = loop.joint_factors
        self.center = sol.design.pose_array[0].mean(0)
        real = sol.realization
        self.ghost = None if real is not None or preview is not None else self.last_real
        if real is not None:
            self.points_home = np.asarray(real.points, float)
            self.bar_radius = float(real.radius)
            self.last_real = (loop.joint_factors, self.points_home, self.bar_radius)
        elif preview is not None:
            self.points_home = np.asarray(preview.points, float)
            self.bar_radius = float(preview_radius or 0.01 * self.scale)
        else:  # the shortest closed polyline on the axes (eq. 11): S_i = E_{i-1}
            try:
                e = polyline.shortest_polyline(loop.joint_factors)[1]
                self.points_home = np.stack([np.roll(e, 1, axis=0), e], axis=1).reshape(12, 3)
            except RealizationError:  # (nearly) parallel axes: axes only, no bars
                self.points_home = None
            self.bar_radius = 0.01 * self.scale
        f, g = loop.factorizations
        colors = np.repeat(FACTOR_COLORS[[f, g]], 3, axis=0)[:, None, :].repeat(2, axis=1)
        self.loop_colors = colors
        ee = getattr(sol, "end_effector", None)
        self._set_effector(ee if ee is not None or preview is None or preview.effector is None
                           else preview)

    def _set_effector(self, ee: Any) -> None:
        """The end-effector P (home vertices, world frame) moving with link 3, and the end
        link's path S_3 L + P + R E_3 replacing the bar S_3 E_3 (Sec. 5.1); ``ee`` has the
        attached ``effector`` and ``end_link()`` (an ``EndEffectorRealization`` or a drag
        preview), or is None."""
        old = self.handles.pop("effector", None)
        if old is not None:
            old.remove()
        if (ee is None) != (self.end_link is None):  # the bar count changes: rebuild
            for key in ("bars", "joints", "axes"):
                if key in self.handles:
                    self.handles.pop(key).remove()
        self.end_link = None if ee is None else ee.end_link()
        if ee is not None:
            self.handles["effector"] = self.server.scene.add_mesh_simple(
                "/loop/effector", ee.effector.vertices.astype(np.float32),
                ee.effector.faces.astype(np.uint32), color=(250, 200, 40), side="double")

    def draw_frame(self, u: float, thickness: float = 1.0) -> None:
        """Pose the animated frame, the loop's axes and the linkage at ``t = param_to_t(u)``;
        bars are drawn ``thickness`` times their radius (1 = true size)."""
        if self.motion is None or self.joint_factors is None or "current" not in self.handles:
            return
        t = poly.param_to_t(np.array([u]))
        scene, h = self.server.scene, self.handles
        pos, wxyz = dq.to_pos_wxyz(poly.evaluate_pose(self.motion, t)[0])
        h["current"].position, h["current"].wxyz = pos, wxyz
        axes = loops.axes_at(self.joint_factors, t)[0]
        home = self.points_home
        if home is None:  # axes only: centre them at the target centroid
            home = np.repeat(self.center[None], 12, axis=0)
        links = loops.link_poses(self.joint_factors, t)[0]  # (6, 8)
        if self.spaces and self.spaces_current():
            pos, wxyz = dq.to_pos_wxyz(links)
            for i, handle in self.spaces:
                handle.position, handle.wxyz = pos[i], wxyz[i]
        pts = dq.transform_points(np.repeat(links, 2, axis=0), home)
        e = pts[1::2]  # E_i on A_i
        s_next = np.roll(pts[0::2], -1, axis=0)  # S_{i+1} on A_i
        axis_segs = axis_segments(axes, 0.5 * (e + s_next), 0.6 * self.scale)
        r = self.bar_radius * thickness
        starts, ends, bar_colors = pts[0::2], e, LINK_COLORS
        if self.end_link is not None:  # end link: S_3 -> L and R -> E_3 around P
            end = dq.transform_points(links[3], self.end_link)
            starts = np.vstack([starts[:3], end[[0, 2]], starts[4:]])
            ends = np.vstack([ends[:2], [ends[2], end[1], ends[3]], ends[4:]])
            bar_colors = np.vstack([LINK_COLORS[:4], LINK_COLORS[3:]])
            pose, wxyz = dq.to_pos_wxyz(links[3])
            h["effector"].position, h["effector"].wxyz = pose, wxyz
        bar_p, bar_q, bar_s = self._cylinders(starts, ends, r, r)
        joint_p, joint_q, joint_s = self._cylinders(e, s_next, 1.8 * r, 6.0 * r, axes[:, :3])
        self._draw_ghost(t, thickness)
        if "bars" not in h:
            h["axes"] = scene.add_line_segments("/loop/axes", axis_segs, self.loop_colors,
                                                thickness=4.0, thickness_units="screen")
            h["bars"] = scene.add_batched_meshes_simple(
                "/loop/bars", _CYL.vertices, _CYL.faces, bar_q, bar_p, batched_scales=bar_s,
                batched_colors=bar_colors, lod="off")
            h["joints"] = scene.add_batched_meshes_simple(
                "/loop/joints", _CYL.vertices, _CYL.faces, joint_q, joint_p,
                batched_scales=joint_s, batched_colors=JOINT_COLOR, lod="off")
            return
        h["axes"].points, h["axes"].colors = axis_segs, self.loop_colors
        for key, (p, q, s) in (("bars", (bar_p, bar_q, bar_s)),
                               ("joints", (joint_p, joint_q, joint_s))):
            h[key].batched_positions, h[key].batched_wxyzs, h[key].batched_scales = p, q, s

    def _draw_ghost(self, t: np.ndarray, thickness: float) -> None:
        """The last realized linkage, faint, while the design on screen has no realization."""
        if self.ghost is None:
            if "ghost" in self.handles:
                self.handles.pop("ghost").remove()
            return
        jf, home, radius = self.ghost
        pts = dq.transform_points(np.repeat(loops.link_poses(jf, t)[0], 2, axis=0), home)
        p, q, s = self._cylinders(pts[0::2], pts[1::2], radius * thickness, radius * thickness)
        if "ghost" in self.handles:
            g = self.handles["ghost"]
            g.batched_positions, g.batched_wxyzs, g.batched_scales = p, q, s
        else:
            self.handles["ghost"] = self.server.scene.add_batched_meshes_simple(
                "/loop/ghost", _CYL.vertices, _CYL.faces, q, p, batched_scales=s,
                batched_colors=(150, 150, 160), opacity=0.3, lod="off", cast_shadow=False,
                receive_shadow=False)

    def apply_layers(self, hidden: set[str]) -> None:
        """Show or hide the view layers (the linkage also needs polyline points)."""
        for layer, keys in LAYERS.items():
            for key in keys:
                handle = self.handles.get(key)
                if handle is None:
                    continue
                show = layer not in hidden and (layer != "Linkage" or self.points_home is not None)
                if handle.visible != show:
                    handle.visible = show
        show = SPACES_LAYER not in hidden and self.spaces_current()
        for _, handle in self.spaces:
            if handle.visible != show:
                handle.visible = show

    @staticmethod
    def _cylinders(a: np.ndarray, b: np.ndarray, radius: float, min_len: float,
                   fallback: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
        """Instance positions, wxyz and scales of cylinders from ``a`` to ``b`` (``(N, 3)``);
        shorter ones get ``min_len`` along ``fallback`` directions (joint pins)."""
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
