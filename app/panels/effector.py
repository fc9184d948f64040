"""Studio controls of the end-effector (paper Sec. 5.1): the body P moved by the end link.

The values live in ``Design.end_effector``; handlers only edit the state and ask for a full
update, in which the worker loads, validates and realizes P through :func:`pipeline.solve`.
An uploaded mesh is stored in the user data folder under a content-hashed name; the worker
validates it (:meth:`EffectorPanel.check_mesh`) before the design refers to it by absolute
path, so a malformed file never changes the design.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import viser

from app.exports import slug
from app.state import uploaded_meshes_dir, with_uploads
from app.worker import FRAME, FULL
from paraloop_core.design import Design, EndEffectorSettings
from paraloop_core.errors import EndEffectorError
from paraloop_core.realization import endeffector

if TYPE_CHECKING:
    from app.host import StudioHost

BODIES = ("None", "Disc", "Panel", "Mesh")
MESH_TYPES = (".stl", ".obj", ".glb")
MAX_UPLOAD_BYTES = 50 * 2**20


def store_mesh(name: str, content: bytes) -> Path:
    """Save uploaded mesh bytes as ``meshes/<name>-<hash><suffix>`` in the user data folder;
    the same content keeps its file, so designs referring to it stay valid."""
    p = Path(name)
    folder = uploaded_meshes_dir()
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{slug(p.stem)}-{hashlib.sha256(content).hexdigest()[:12]}{p.suffix.lower()}"
    if not path.exists():
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_bytes(content)
        tmp.replace(path)
    return path


def parse_vertex(text: str, name: str) -> int | None:
    """A vertex index from a text field (blank = None, automatic); raises ValueError."""
    text = text.strip()
    if not text:
        return None
    if not text.isdigit():
        raise ValueError(f"{name} must be a vertex index or blank (automatic), got {text!r}")
    return int(text)


def certificate_summary(real: Any) -> str:
    """Markdown summary of a :class:`ee_certificate.EndEffectorRealization`'s certificate."""
    e = real.effector
    gap = real.ee_distance - real.ee_required
    on_p = np.array([label.startswith("P-") for label in real.ee_labels])
    i = int(np.flatnonzero(on_p)[np.argmin(gap[on_p])])
    ok = bool(np.all(gap >= 0.0))
    bounded = int(np.sum(~np.asarray(real.ee_exact, bool)))
    return (f"P: {len(e.vertices)} vertices, {len(e.faces)} faces "
            f"({'closed' if e.closed else 'open'}), L = {e.L}, R = {e.R}.\n\n"
            f"**Certificate:** {'all' if ok else 'NOT all'} {len(gap)} pairs certified "
            f"{'✓' if ok else '✗'}. Min clearance of P {gap[i]:.3g} "
            f"({real.ee_labels[i]}: distance {real.ee_distance[i]:.3g}, required "
            f"{real.ee_required[i]:.3g}); over all pairs {gap.min():.3g}"
            + (f" ({bounded} bounded by P's bounding sphere)." if bounded else "."))


class EffectorPanel:
    """The 'End-effector' folder; ``guard`` wraps handlers (see :func:`panels.handler`)."""

    def __init__(self, gui: viser.GuiApi, studio: StudioHost,
                 guard: Callable[[Callable[[Any], None]], Callable[[Any], None]]) -> None:
        self.studio = studio
        self.mesh: str | None = None  # the mesh "Mesh" stands for (last used or uploaded)
        with gui.add_folder("Carried object", expand_by_default=False):
            self.body = gui.add_dropdown(
                "Object", BODIES, initial_value="None",
                hint="a body the end link carries, e.g. a shading panel (the paper's "
                     "end-effector P, Sec. 5.1): it moves with the loop and the bars keep "
                     "clear of it")
            self.inputs = {
                "scale": gui.add_number("Object size", initial_value=1.0, min=1e-6, step=0.05,
                                        hint="disc radius, panel height or mesh scale factor, "
                                             "in design units"),
                "clearance": gui.add_number(
                    "Object clearance", initial_value=0.0, min=0.0, step=0.005,
                    hint="the distance kept between the object and every bar and pin centre "
                         "line, in design units; 0 = the bar radius (ρ)"),
                "L": gui.add_text("Left attachment", "",
                                  hint="the object's vertex joined to the end link's first "
                                       "bar end (the paper's L, joined to S_3); blank = the "
                                       "vertex closest to joint axis A_2"),
                "R": gui.add_text("Right attachment", "",
                                  hint="the object's vertex joined to the end link's second "
                                       "bar end (the paper's R, joined to E_3); blank = the "
                                       "vertex closest to joint axis A_3"),
            }
            self.upload = gui.add_upload_button("Upload object mesh", icon=viser.Icon.UPLOAD,
                                                mime_type=",".join(MESH_TYPES),
                                                hint="an STL, OBJ or GLB file in design units "
                                                     "(up to 50 MiB)")
            self.file = gui.add_markdown("*No mesh file.*")
            self.report = gui.add_markdown("*No end-effector.*")
        self.body.on_update(guard(lambda _: self._edit(self.body.value)))
        for key, handle in self.inputs.items():
            handle.on_update(guard(lambda _, key=key: self._edit(self.body.value, f"ee.{key}")))
        self.upload.on_upload(guard(self._upload))

    # --- handlers (edit the state only) -----------------------------------------------------
    def _settings(self, body: str) -> EndEffectorSettings | None:
        """The settings the widgets describe with ``body``; raises ValueError."""
        if body == "None":
            return None
        if body == "Mesh" and self.mesh is None:
            raise ValueError("upload a mesh file first (" + ", ".join(MESH_TYPES) + ")")
        scale = float(self.inputs["scale"].value)
        clearance = float(self.inputs["clearance"].value)
        if not (math.isfinite(scale) and scale > 0):
            raise ValueError(f"the scale must be > 0, got {scale:g}")
        if not (math.isfinite(clearance) and clearance >= 0):
            raise ValueError(f"the clearance must be >= 0, got {clearance:g}")
        return EndEffectorSettings(
            mesh=self.mesh if body == "Mesh" else None,
            shape=None if body == "Mesh" else body.lower(), scale=scale,
            L=parse_vertex(self.inputs["L"].value, "L"),
            R=parse_vertex(self.inputs["R"].value, "R"), clearance=clearance or None)

    def _edit(self, body: str, merge: str | None = None, sync: bool = False,
              **changes: Any) -> None:
        """Commit the widgets' settings (``changes`` override fields; ``merge`` as in
        :meth:`StudioState.commit`); a bad value is refused, the design's is written back."""
        studio = self.studio
        try:
            settings = self._settings(body)
        except ValueError as exc:
            studio.notify("Carried object", f"{exc} (the design is unchanged)", error=True)
            studio.request(FRAME, sync=True)
            return
        if settings is not None:
            settings = dataclasses.replace(settings, **changes)
        if settings != studio.state.design.end_effector:
            # an uploaded mesh is found among the uploads (Design.mesh_dirs), never by its path
            studio.state.edit(lambda d: dataclasses.replace(
                with_uploads(d) if body == "Mesh" else d, end_effector=settings), merge)
            studio.request(FULL, sync=sync)

    def _upload(self, event: Any) -> None:
        upload = event.target.value
        suffix = Path(upload.name).suffix.lower()
        try:
            if suffix not in MESH_TYPES:
                raise ValueError(f"expected {', '.join(MESH_TYPES)}, got {suffix or 'no suffix'}")
            if len(upload.content) > MAX_UPLOAD_BYTES:
                raise ValueError(f"{len(upload.content) / 2**20:.0f} MiB is more than the "
                                 f"limit {MAX_UPLOAD_BYTES // 2**20} MiB")
        except ValueError as exc:
            self.studio.notify(f"Cannot use {upload.name}", f"{exc} (the design is unchanged)",
                               error=True)
            return
        # hashing and writing the file is the worker's job: callbacks stay cheap
        self.studio.state.add_task("mesh", (upload.name, upload.content))
        self.studio.request(FRAME)

    # --- worker side ------------------------------------------------------------------------
    def check_mesh(self, upload: tuple[str, bytes]) -> None:
        """Store and validate an upload ``(name, content)`` (worker); a good mesh becomes the
        design's end-effector with automatic L and R, a bad one is deleted and reported."""
        name, content = upload
        try:
            path = store_mesh(name, content)
        except OSError as exc:
            self.studio.notify(f"Cannot use {name}", f"{exc} (the design is unchanged)",
                               error=True)
            return
        try:
            body = endeffector.load_mesh(path)
        except EndEffectorError as exc:
            path.unlink(missing_ok=True)
            self.studio.notify("Cannot use the mesh", f"{exc} (the design is unchanged)",
                               error=True)
            return
        self.mesh = str(path)
        self.file.content = f"Mesh file: `{path.name}` ({len(body.faces)} faces used)"
        self._edit("Mesh", sync=True, L=None, R=None)

    def sync(self, design: Design) -> None:
        """Show the design's end-effector (inside :func:`panels.writing_back`)."""
        ee = design.end_effector
        if ee is None:
            self.body.value = "None"
            return
        self.body.value = "Mesh" if ee.mesh else ee.shape.capitalize()
        if ee.mesh and ee.mesh != self.mesh:
            self.mesh = ee.mesh
            self.file.content = f"Mesh file: `{Path(ee.mesh).name}`"
        values = {"scale": ee.scale, "clearance": ee.clearance or 0.0,
                  "L": "" if ee.L is None else str(ee.L), "R": "" if ee.R is None else str(ee.R)}
        for key, value in values.items():
            self.inputs[key].value = value

    def show(self, sol: Any) -> None:
        """The certificate summary of a full solution."""
        if sol.design.end_effector is None:
            self.report.content = "*No end-effector.*"
        elif sol.end_effector is None:
            self.report.content = ("*Not realized with the end-effector* (Realize is off or no "
                                   "collision-free realization was found).")
        else:
            self.report.content = certificate_summary(sol.end_effector)
