"""paraloop core: invertible paradoxical 6R loops from target poses (Li, Nawratil, Rist, Hensel).

The public API a script needs; everything else lives in the stage subpackages
(``algebra`` < ``linkage`` < ``motion`` < ``realization`` < ``fabrication`` < ``validation``,
see docs/architecture.md). Conventions are stated once, in ``paraloop_core.algebra.dq``.

    import paraloop_core as pl
    design = pl.load_design("assets/designs/tv8.json")
    solution = pl.solve(design)
    print(solution.realization.min_clearance)
    pl.save_result(solution, "tv8.result.json")
"""

from paraloop_core.design import Design, Pose, design_from_dict, load_design, save_design
from paraloop_core.errors import (
    DesignFileError,
    FabricationError,
    FitError,
    InterpolationError,
    NonGenericMotionError,
    ParaloopError,
    RealizationError,
)
from paraloop_core.pipeline import Solution, solve
from paraloop_core.result import result_to_dict, save_result

__all__ = [
    "Design", "Pose", "design_from_dict", "load_design", "save_design",
    "Solution", "solve", "result_to_dict", "save_result",
    "ParaloopError", "DesignFileError", "NonGenericMotionError", "InterpolationError",
    "RealizationError", "FitError", "FabricationError",
]
