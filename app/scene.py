"""Drawing the design and its solution into the viser scene (called by the worker only,
inside ``server.atomic()``).

Scene tree: ``/targets/i`` gizmos (+ ``/frame``), ``/target_labels/i`` their labels (placed
apart on screen, ``app.labels``), ``/motion/path`` trajectory,
``/motion/frames`` sampled moving frames, ``/motion/current`` the animated frame with its
``/ellipsoid``, ``/factorizations`` six factorizations' axes (Fig. 5 colours, home pose),
``/loop/axes`` the selected loop's axes, ``/loop/bars``, ``/loop/elbows``, ``/loop/joints``
the linkage as solid links (``app.links``) or ``/loop/parts/i`` and ``/loop/hardware/i``
per-link meshes (the printed parts, ``app.printview``; :meth:`SceneView.set_parts`),
``/loop/ghost`` the last realized linkage while the design has none, ``/loop/spaces/i`` the
carved design spaces (moving with their links).

The paper's construction aids (factorization and loop axes, the inertia ellipsoid, moving
frames, carved design spaces) are layers that start hidden (:data:`HIDDEN_AT_START`); the
linkage and the trajectory show.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import viser

from app import camera, labels, links
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
PATH_COLOR = (40, 40, 70)
GHOST_COLOR = np.array([150, 150, 160], dtype=np.uint8)
#: The linkage's layer and the scene handles it shows.
LINKAGE = "Linkage"
LINKAGE_KEYS = ("bars", "elbows", "joints", "effector", "ghost")
#: Construction layers (the Construction folder's checkboxes) and the scene handles they show;
#: the carved design spaces and the moving body's own axes are handled apart.
CONSTRUCTION = {"Trajectory": ("path",), "Moving frames": ("frames",),
                "Inertia ellipsoid": ("ellipsoid",), "Factorization axes": ("facts",),
                "Loop axes": ("axes",), "Design spaces": ()}
SPACES_LAYER = "Design spaces"
#: The View folder's layer of the printed parts (:meth:`SceneView.set_parts`): hidden, the
#: solid links show instead.
PARTS = "Printed parts"
#: Layers hidden when the studio starts: the paper's construction aids.
HIDDEN_AT_START = frozenset({"Moving frames", "Inertia ellipsoid", "Factorization axes",
                             "Loop axes", SPACES_LAYER})
SPACE_COLORS = np.vstack([links.LINK_COLORS[:1], FACTOR_COLORS[:5]])
STEEL_COLORS = np.full((6, 3), 175, np.uint8)  # the printed parts' screws, nuts and rod
PATH_SAMPLES = 256
FRAME_SAMPLES = 24


def design_scale(design: Design) -> float:
    """Characteristic length: the diagonal of the targets' bounding box (at least 1e-3)."""
    pos = design.pose_array[0]
    return max(float(np.linalg.norm(pos.max(0) - pos.min(0))), 1e-3)


def axis_segments(lines: np.ndarray, centers: np.ndarray, length: float) -> np.ndarray:
    """Segments ``(N, 2, 3)`` of Plücker lines ``(N, 6)`` centred at the feet of ``centers``."""
    d = lines[:, :3] / np.linalg.norm(lines[:, :3], axis=-1, keepdims=True)
    foot = np.cross(d, lines[:, 3:]) / np.linalg.norm(lines[:, :3], axis=-1, keepdims=True)
    foot = foot + np.sum((centers - foot) * d, -1, keepdims=True) * d
    return np.stack([foot - 0.5 * length * d, foot + 0.5 * length * d], axis=1)


def _ellipsoid_vertices(design: Design) -> np.ndarray:
    """The inertia ellipsoid's mesh vertices in the body frame."""
    s = design.inertia
    semi = np.maximum(s.semi_axes, 1e-4 * design_scale(design))
    return s.center + (semi * links.SPHERE.vertices) @ s.axes


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
        self.spaces = links.LinkMeshes(server, "/loop/spaces", SPACE_COLORS, 0.45)  # carved
        self.parts = links.LinkMeshes(server, "/loop/parts", links.LINK_COLORS, 1.0)  # set_parts
        self.hardware = links.LinkMeshes(server, "/loop/hardware", STEEL_COLORS, 1.0)
        self.parts_for: Any = None  # the realization the parts stand for (None: their loop)
        self.realization: Any = None  # the realization on screen (None: a preview or none)
        self.view: labels.View | None = None  # the camera the labels are placed for
        self.end_link: np.ndarray | None = None  # (4, 3) S_3, L, R, E_3 with an end-effector
        # the last realized linkage (joint factors, home points, radius) and, while the design
        # on screen has no realization, the same shown faintly (a "ghost")
        self.last_real: tuple[np.ndarray, np.ndarray, float] | None = None
        self.ghost: tuple[np.ndarray, np.ndarray, float] | None = None
        self.target_positions = np.zeros((0, 3))
        self.locked: tuple[int, ...] = ()

    # --- targets ----------------------------------------------------------------------------
    def set_targets(self, design: Design) -> None:
        """Create, move or restyle the target gizmos to match ``design``."""
        scene = self.server.scene
        if not self.gizmos or abs(np.log(design_scale(design) / self.scale)) > np.log(2.0):
            self._rescale(design)
        if len(self.gizmos) != len(design.poses):
            self._remove_targets()
            for i, pose in enumerate(design.poses):
                g = scene.add_transform_controls(
                    f"/targets/{i}", scale=0.3 * self.scale, disable_sliders=True,
                    position=pose.position, wxyz=pose.wxyz)
                scene.add_frame(f"/targets/{i}/frame", axes_length=0.12 * self.scale,
                                axes_radius=0.006 * self.scale)
                self.labels.append(scene.add_label(f"/target_labels/{i}", f"S{i}",
                                                   anchor="center-center"))
                g.on_update(self._gizmo_callback(i))
                self.gizmos.append(g)
        for i, (g, pose) in enumerate(zip(self.gizmos, design.poses, strict=True)):
            g.position, g.wxyz = pose.position, pose.wxyz
            locked = i in design.locked
            g.active_axes = (not locked,) * 3
            g.disable_rotations = locked
            g.opacity = 0.25 if locked else 1.0
        self.locked = design.locked
        self.place_labels(design.pose_array[0])

    def _remove_targets(self) -> None:
        """Remove the gizmos (their frames with them) and their labels: no stale scene node
        stays behind, in this page or in a page opened later."""
        for handle in (*self.gizmos, *self.labels):
            handle.remove()
        self.gizmos, self.labels = [], []

    def place_labels(self, positions: np.ndarray | None = None) -> None:
        """Place the target labels (targets at ``positions`` ``(N, 3)``, default the last
        ones) so that no two overlap in :attr:`view` (:func:`labels.place`)."""
        if positions is not None:
            self.target_positions = np.asarray(positions, float).reshape(-1, 3)
        if len(self.labels) != len(self.target_positions) or not self.labels \
                or self.view is None:  # placed when the opening framing sets the view
            return
        at = labels.place(self.target_positions, [lb.text for lb in self.labels], self.view)
        for label, p in zip(self.labels, at, strict=True):
            label.position = p

    def set_view(self, view: labels.View | None) -> None:
        """The camera the labels are placed for (a framing); re-places them."""
        self.view = view
        self.place_labels()

    def object_triangles(self) -> np.ndarray:
        """The object as drawn, world triangles ``(M, 3, 3)``: the printed parts when they
        show, else the solid links' bars (and the carried object)."""
        if self.parts_shown() and all(h.visible for _, h in self.parts):
            return np.concatenate([self.parts.triangles(), self.hardware.triangles()])
        out = [np.zeros((0, 3, 3))]
        bars, effector = self.handles.get("bars"), self.handles.get("effector")
        if bars is not None and self.points_home is not None:
            out.append(links.posed_triangles(links.CYLINDER.vertices, links.CYLINDER.faces,
                                             bars.batched_positions, bars.batched_wxyzs,
                                             bars.batched_scales))
        if effector is not None:
            out.append(links.posed_triangles(effector.vertices, effector.faces,
                                             effector.position, effector.wxyz))
        return np.concatenate(out)

    def object_shot(self) -> camera.Subject:
        """The opening framing's subject: the object and the free targets (the gizmos one
        drags; locked targets may fall outside)."""
        free = [i for i in range(len(self.target_positions)) if i not in self.locked]
        return camera.subject(self.object_triangles(), self.target_positions[free])

    def all_shot(self) -> camera.Subject:
        """*Frame all*'s subject: every target, the trajectory and the object as drawn."""
        path = self.handles.get("path")
        return camera.subject(self.object_triangles(), self.target_positions,
                              None if path is None else np.asarray(path.points, float))

    def _rescale(self, design: Design) -> None:
        """New characteristic length: grid, initial camera; sized handles are recreated."""
        self._remove_targets()
        for h in reversed(self.handles.values()):  # children before parents
            h.remove()
        self.handles = {}
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
                "/motion/current/ellipsoid", verts, links.SPHERE.faces, color=(120, 160, 230),
                wireframe=True, opacity=0.5, cast_shadow=False, receive_shadow=False)
        self.target_positions = sol.design.pose_array[0]
        rank = np.argsort(np.argsort(poly.t_to_param(sol.pose_parameters)))
        for i, label in enumerate(self.labels):
            lock = " (locked)" if i in sol.design.locked else ""
            text = f"S{i} #{rank[i] + 1}{lock}" if i < len(rank) else f"S{i}"
            if label.text != text:
                label.text = text
        self.place_labels()  # after the texts: their widths count

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

    # --- per-link meshes ---------------------------------------------------------------------
    def set_spaces(self, joint_factors: np.ndarray, bodies: list) -> None:
        """Replace the carved design spaces: ``bodies[i]`` (vertices, faces) in link i's home
        frame, or None (nothing meshable)."""
        self.spaces.set(joint_factors, bodies)

    def set_parts(self, joint_factors: np.ndarray,
                  meshes: list[tuple[np.ndarray, np.ndarray] | None] | None,
                  hardware: list[tuple[np.ndarray, np.ndarray] | None] | None = None,
                  shown_for: Any = None) -> None:
        """Draw the linkage of the loop ``joint_factors`` as the given per-link meshes
        (``meshes[i]``: vertices ``(V, 3)`` in link i's home frame, the world frame at
        ``t = inf``, design units, and faces ``(F, 3)``; None: nothing for that link) and
        its metal ``hardware`` (the same per link, steel grey) moving with the slider, in
        place of the solid links and the end-effector; ``meshes`` None removes them.
        They show only while that loop is on screen, or, with ``shown_for`` (a
        realization), while the solution on screen has that realization: then the meshes
        may belong to another loop of the same motion (the printed loop) and are posed by
        their own ``joint_factors``. An edit falls back to the solid links until new meshes
        come. Call from the worker, inside ``server.atomic()``, then :meth:`draw_frame` and
        :meth:`apply_layers`."""
        if meshes is None:
            self.parts.clear()
            self.hardware.clear()
            self.parts_for = None
        else:
            self.parts.set(joint_factors, meshes)
            self.hardware.set(joint_factors, hardware or [None] * 6)
            self.parts_for = shown_for

    def parts_shown(self) -> bool:
        """Whether the per-link meshes of :meth:`set_parts` belong to what is on screen."""
        if self.parts_for is None:
            return self.parts.current(self.joint_factors)
        return len(self.parts) > 0 and self.realization is self.parts_for

    # --- loop and linkage -------------------------------------------------------------------
    def set_loop(self, sol: Any, preview: Any = None, preview_radius: float | None = None
                 ) -> None:
        """Choose the linkage geometry: the realization's points, else a drag ``preview``
        (``pipeline.WarmPreview``; bars of ``preview_radius``), else the bare loop polyline."""
        loop = sol.loop
        self.joint_factors = loop.joint_factors
        self.center = sol.design.pose_array[0].mean(0)
        real = sol.realization
        self.realization = real
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
        h = self.handles
        pos, wxyz = dq.to_pos_wxyz(poly.evaluate_pose(self.motion, t)[0])
        h["current"].position, h["current"].wxyz = pos, wxyz
        axes = loops.axes_at(self.joint_factors, t)[0]
        home = self.points_home
        if home is None:  # axes only: centre them at the target centroid
            home = np.repeat(self.center[None], 12, axis=0)
        poses = loops.link_poses(self.joint_factors, t)[0]  # (6, 8)
        link_pos, link_wxyz = dq.to_pos_wxyz(poses)
        if self.spaces.current(self.joint_factors):
            self.spaces.move(link_pos, link_wxyz)
        if self.parts_shown():  # posed by their own loop (the printed one may be another)
            posed = dq.to_pos_wxyz(loops.link_poses(self.parts.joint_factors, t)[0])
            self.parts.move(*posed)
            self.hardware.move(*posed)
        pts = dq.transform_points(np.repeat(poses, 2, axis=0), home)
        mid = 0.5 * (pts[1::2] + np.roll(pts[0::2], -1, axis=0))  # joint i: E_i S_{i+1}
        axis_segs = axis_segments(axes, mid, 0.6 * self.scale)
        end = None
        if self.end_link is not None:  # end link: S_3 -> L and R -> E_3 around P
            end = dq.transform_points(poses[3], self.end_link)
            h["effector"].position, h["effector"].wxyz = link_pos[3], link_wxyz[3]
        self._draw_ghost(t, thickness)
        if "axes" in h:
            h["axes"].points, h["axes"].colors = axis_segs, self.loop_colors
        else:
            h["axes"] = self.server.scene.add_line_segments(
                "/loop/axes", axis_segs, self.loop_colors, thickness=4.0,
                thickness_units="screen")
        solid = links.solid_links(pts, axes[:, :3], self.bar_radius * thickness, end)
        for key, shape in (("bars", links.CYLINDER), ("elbows", links.SPHERE),
                           ("joints", links.CYLINDER)):
            links.draw_instances(self.server, h, key, f"/loop/{key}", shape, solid[key])

    def _draw_ghost(self, t: np.ndarray, thickness: float) -> None:
        """The last realized linkage, faint, while the design on screen has no realization."""
        if self.ghost is None:
            if "ghost" in self.handles:
                self.handles.pop("ghost").remove()
            return
        jf, home, radius = self.ghost
        pts = dq.transform_points(np.repeat(loops.link_poses(jf, t)[0], 2, axis=0), home)
        r = radius * thickness
        p, q, s = links.cylinders(pts[0::2], pts[1::2], r, r)
        links.draw_instances(self.server, self.handles, "ghost", "/loop/ghost", links.CYLINDER,
                             links.Instances(p, q, s, np.tile(GHOST_COLOR, (len(p), 1))),
                             opacity=0.3, cast_shadow=False, receive_shadow=False)

    def apply_layers(self, hidden: set[str]) -> None:
        """Show or hide the layers: the linkage (solid links, or the per-link meshes of
        :meth:`set_parts` when they belong to what is on screen and :data:`PARTS` is not
        hidden; it also needs points) and the construction aids (:data:`CONSTRUCTION`)."""
        parts = PARTS not in hidden and self.parts_shown()
        linkage = LINKAGE not in hidden and self.points_home is not None
        shown = {key: linkage and not (parts and key in ("bars", "elbows", "joints",
                                                         "effector"))
                 for key in LINKAGE_KEYS}
        for layer, keys in CONSTRUCTION.items():
            shown.update((key, layer not in hidden) for key in keys)
        for key, show in shown.items():
            handle = self.handles.get(key)
            if handle is not None and handle.visible != show:
                handle.visible = show
        current = self.handles.get("current")
        if current is not None and current.show_axes == ("Moving frames" in hidden):
            current.show_axes = "Moving frames" not in hidden
        self.parts.show(linkage and parts)
        self.hardware.show(linkage and parts)
        self.spaces.show(SPACES_LAYER not in hidden and self.spaces.current(self.joint_factors))
