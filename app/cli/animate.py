"""``paraloop animate DESIGN.json --out loop.glb``: the realized loop as an animated glTF.

Solves the design (with its realization) and writes one binary glTF 2.0 file: the six links as
capsules (with ``--printed``: the printed parts, as ``paraloop export`` makes them, on their
base), each a node with translation and rotation keyframes over one full cycle, turned as
the design's drive turns it: its motor (recommended unless set) with the speed schedule of its
drive plan, over its cycle time (:func:`app.exports.animation_keyframes`,
:mod:`paraloop_core.fabrication.animate`). ``--out`` is checked
before the solve: a ``.glb`` file name in a writable folder, not existing unless ``--force``;
the file is written atomically (temporary file + rename). Exit status 0 when written, 2 on
refused input (nothing written), 3 when no collision-free realization was found, 1 on an
internal error.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from app.cli import outputs
from app.cli.outputs import EXIT_OK
from app.cli.solve import solve_realized
from app.exports import animation_keyframes
from paraloop_core import pipeline, printed
from paraloop_core.design import Design
from paraloop_core.fabrication import animate


def check_out(out: Path, design: Path, force: bool) -> None:
    """Refuse an unusable ``--out`` before any work (OutputError)."""
    if out.suffix.lower() != ".glb":
        raise outputs.OutputError(f"{out}: give a .glb file name (binary glTF)")
    outputs.check_file_target(out, force)
    outputs.check_not_inputs([out], [design])


def cmd_animate(args: argparse.Namespace) -> int:
    path = Path(args.design)
    out = outputs.output_path(args.out, "--out")
    check_out(out, path, args.force)
    def work(design: Design, sol: pipeline.Solution) -> tuple[bytes, float, str]:
        if args.printed:  # the loop as `paraloop export` prints it, on its base
            made, _ = printed.make(sol)
            glb, how = printed.animation(made, design.drive, args.frames, args.seconds)
            return glb, args.seconds or design.drive.cycle_time_s, \
                f"the printed parts ({made.candidate}), {how}"
        real = sol.realization
        t, cycle, how = animation_keyframes(real, design.drive, args.frames)
        seconds = args.seconds or cycle
        return animate.animated_glb(real.joint_factors, real.points, real.radius,
                                    frames=args.frames, seconds=seconds, t=t), seconds, how

    code, done = solve_realized(path, work)
    if done is None:
        return code
    data, seconds, how = done
    outputs.write_files(out.parent, [(out.name, data)])
    print(f"{path} -> {out}: {args.frames} frames over {seconds:g} s ({how}), "
          f"{len(data) / 1e6:.2f} MB")
    return EXIT_OK


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``animate`` sub-command."""
    p = subparsers.add_parser("animate", help="write the realized loop as an animated glTF")
    p.add_argument("design", help="design JSON file")
    p.add_argument("--out", required=True, help="output .glb file")
    p.add_argument("--frames", type=outputs.int_range(2, 100_000), default=240,
                   help="keyframes over one cycle, the last one repeating the first "
                        "(2..100000; default 240)")
    p.add_argument("--seconds", type=outputs.float_range(0.0, 86_400.0, lo_open=True),
                   default=None, help="duration of one cycle in seconds (default: the "
                   "design's drive.cycle_time_s, 10 unless set)")
    p.add_argument("--printed", action="store_true",
                   help="animate the loop as `paraloop export` prints it: its parts, joints "
                        "and base, resting on its grounded link (millimetres)")
    p.add_argument("--force", action="store_true", help="overwrite an existing --out file")
    p.set_defaults(func=cmd_animate)
