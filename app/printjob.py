"""The printed parts of a solved design, built in a child process for the studio's view
(``app.printview``): :func:`printed.make` with the Fabrication folder's options, the parts as
per-link meshes in design units, the report with what *Export all* adds to it (print layout,
parts, bill of materials), and afterwards, on request, the physics check of the same parts.

The child talks over a pipe (:func:`serve`): ``("progress", fraction, message)`` while it
builds, then one of ``("done", Parts)``, ``("refused", text)`` (the parts cannot be built:
a :class:`FabricationError` or :class:`RealizationError`) or ``("bug", traceback)``; then it
answers ``("physics", DriveSettings)`` with ``("physics", report)``, ``("refused", text)`` or
``("bug", traceback)`` until the pipe closes. A process, not a thread: the build holds the
interpreter for seconds (it would slow a drag) and is killed at once when an edit makes it
obsolete.
"""

from __future__ import annotations

import dataclasses
import time
import traceback
from typing import Any

import numpy as np

from paraloop_core import pipeline, printed
from paraloop_core.design import DriveSettings
from paraloop_core.errors import FabricationError, RealizationError
from paraloop_core.fabrication import check, export, printable

Mesh = tuple[np.ndarray, np.ndarray]  # vertices (V, 3) float32, faces (F, 3) uint32
LinkMeshes = tuple[Mesh | None, ...]  # per link 0..5, None: nothing on that link


@dataclasses.dataclass(frozen=True)
class Parts:
    """The printed loop as the studio draws and summarizes it: its ``joint_factors``
    ``(6, 8)`` (design units: the printed loop, which may be another of the nine loops or the
    design's realized again with roomier joints), per link the printed parts ``meshes`` and
    the metal ``hardware`` moving with it (screws, nuts, washers, the rod; home frame at
    ``t = inf``, design units: the export's mm divided by ``scale``; the base plate goes with
    the grounded link), ``scale`` (mm per design unit), the printed ``loop`` and the design's
    ``design_loop``, the ``report`` (``Printed.report`` with the entries *Export all* adds:
    ``print_layout``, ``parts``, ``bill_of_materials``, ``scale_mm_per_unit``), the
    verification's ``samples`` and the build's wall time ``seconds``."""

    joint_factors: np.ndarray
    meshes: LinkMeshes
    hardware: LinkMeshes
    scale: float
    loop: int
    design_loop: int
    report: dict
    samples: int
    seconds: float

    @property
    def same_loop(self) -> bool:
        """Whether the printed loop is the design's loop (realized again, roomier)."""
        return self.loop == self.design_loop


def merged(solids: list, scale: float) -> Mesh | None:
    """Manifold ``solids`` (mm) as one mesh in design units (mm / ``scale``); None if none."""
    if not solids:
        return None
    meshes = [check.part_trimesh(s) for s in solids]
    offsets = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
    verts = np.concatenate([m.vertices for m in meshes]) / scale
    faces = np.concatenate([m.faces + k for m, k in zip(meshes, offsets, strict=True)])
    return verts.astype(np.float32), faces.astype(np.uint32)


def link_meshes(made: printable.Printed) -> tuple[LinkMeshes, LinkMeshes]:
    """``(printed parts, hardware)`` per link in design units (:class:`Parts`)."""
    asm = made.assembly
    ground = made.base.link if made.base is not None else 0

    def on(link: int) -> int:  # a piece on no link (the base) goes with the grounded link
        return link if 0 <= link < 6 else ground

    parts = tuple(merged([p.manifold for p in asm.parts if on(p.link) == i], asm.scale)
                  for i in range(6))
    hardware = tuple(merged([h.solid for h in asm.hardware if on(h.link) == i], asm.scale)
                     for i in range(6))
    return parts, hardware


def build(sol: pipeline.Solution, opts: printable.Options,
          progress: printed.Progress | None = None) -> tuple[Parts, printable.Printed]:
    """The :class:`Parts` of ``sol`` (with a realization) for ``opts``, built as *Export all*
    builds them (:func:`printed.make`), and the :class:`printable.Printed` they come from;
    raises what :func:`printed.make` raises."""
    t0 = time.perf_counter()
    made, _ = printed.make(sol, opts, progress)
    asm = made.assembly
    entries, _, _ = export.report_entries(asm, opts.material)
    report = {**made.report, **entries}
    report["choice"] = {**report["choice"], "note": printed.note(sol, made),
                        "design_loop": sol.design.loop}
    meshes, hardware = link_meshes(made)
    parts = Parts(np.array(asm.joint_factors, float), meshes, hardware, float(asm.scale),
                  made.loop, sol.design.loop, report, opts.samples,
                  time.perf_counter() - t0)
    return parts, made


def serve(conn: Any, sol: pipeline.Solution, opts: printable.Options) -> None:
    """The child process (module docstring): build, answer, then serve physics checks."""
    try:
        parts, made = build(sol, opts, lambda f, m: conn.send(("progress", f, m)))
        conn.send(("done", parts))
    except (FabricationError, RealizationError) as exc:
        conn.send(("refused", str(exc)))
        return
    except Exception:
        conn.send(("bug", traceback.format_exc()))
        return
    while True:
        try:
            kind, settings = conn.recv()
        except (EOFError, OSError):
            return
        if kind != "physics" or not isinstance(settings, DriveSettings):
            continue
        try:
            report, _ = printed.physics_check(made, opts, settings)
            conn.send(("physics", report))
        except (FabricationError, RealizationError, ValueError) as exc:
            conn.send(("refused", str(exc)))
        except Exception:
            conn.send(("bug", traceback.format_exc()))
