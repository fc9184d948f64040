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
from paraloop_core.fabrication import export, layout, printable

#: Parameters of the cycle at which the preview's parts are verified (``Options.samples``):
#: fewer than *Export all*'s 720, to keep the preview a few seconds; the verification stays
#: sound between samples (a proven motion bound), only coarser.
PREVIEW_SAMPLES = 90

Mesh = tuple[np.ndarray, np.ndarray]  # vertices (V, 3) float32, faces (F, 3) uint32


@dataclasses.dataclass(frozen=True)
class Parts:
    """The printed loop as the studio draws and summarizes it: its ``joint_factors``
    ``(6, 8)`` (design units: the printed loop, which may be another of the nine loops or the
    design's realized again with roomier joints), per link the ``meshes`` (home frame at
    ``t = inf``, design units: its printed part with the pins, caps and metal hardware moving
    with it, the base plate and rod with the grounded link; None: nothing), the printed
    ``loop`` and the design's ``design_loop``, the ``report`` (``Printed.report`` with
    ``print_layout``, ``parts`` and ``bill_of_materials`` as *Export all* writes them), the
    verification's ``samples`` and the build's wall time ``seconds``."""

    joint_factors: np.ndarray
    meshes: tuple[Mesh | None, ...]
    loop: int
    design_loop: int
    report: dict
    samples: int
    seconds: float

    @property
    def same_loop(self) -> bool:
        """Whether the printed loop is the design's loop (realized again, roomier)."""
        return self.loop == self.design_loop


def link_meshes(made: printable.Printed) -> tuple[Mesh | None, ...]:
    """Per link the printed parts and hardware that move with it, in design units
    (:class:`Parts`); a piece on no link (the base, ``link -1``) goes with the grounded
    link."""
    asm = made.assembly
    ground = made.base.link if made.base is not None else 0
    pieces: list[list] = [[] for _ in range(6)]
    for link, solid in [(p.link, p.manifold) for p in asm.parts] + \
            [(h.link, h.solid) for h in asm.hardware]:
        pieces[link if 0 <= link < 6 else ground].append(solid.to_mesh())
    out: list[Mesh | None] = []
    for meshes in pieces:
        if not meshes:
            out.append(None)
            continue
        verts, faces, n = [], [], 0
        for m in meshes:
            v = np.asarray(m.vert_properties, float)[:, :3]
            verts.append(v)
            faces.append(np.asarray(m.tri_verts, np.int64) + n)
            n += len(v)
        out.append(((np.concatenate(verts) / asm.scale).astype(np.float32),
                    np.concatenate(faces).astype(np.uint32)))
    return tuple(out)


def full_report(made: printable.Printed, opts: printable.Options) -> dict:
    """``made.report`` with the entries *Export all* adds (``print_layout``: plates and
    support per part; ``parts``: masses; ``bill_of_materials``), computed the same way."""
    asm = made.assembly
    meshes = export.part_meshes(asm)
    placements = layout.bed_layout(meshes, export.downs(asm), asm.printer.bed_mm)
    return {**made.report,
            "print_layout": layout.layout_entry(placements, asm.printer.bed_mm),
            "parts": export.parts_entry(asm, meshes, opts.material),
            "bill_of_materials": export.bill_of_materials(asm, opts.material)}


def build(sol: pipeline.Solution, opts: printable.Options,
          progress: printed.Progress | None = None) -> tuple[Parts, printable.Printed]:
    """The :class:`Parts` of ``sol`` (with a realization) for ``opts`` and the
    :class:`printable.Printed` they come from; raises what :func:`printed.make` raises."""
    t0 = time.perf_counter()
    made, _ = printed.make(sol, opts, progress)
    report = full_report(made, opts)
    report["choice"] = {**report["choice"], "note": printed.note(sol, made),
                        "design_loop": sol.design.loop}
    parts = Parts(np.array(made.assembly.joint_factors, float), link_meshes(made), made.loop,
                  sol.design.loop, report, opts.samples, time.perf_counter() - t0)
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
