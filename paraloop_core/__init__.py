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

from __future__ import annotations

import importlib
from typing import Any

#: public name -> module that defines it; imported on first use, so that importing a light
#: submodule (``paraloop_core.errors``) does not load numpy and the pipeline
_PUBLIC = {
    **dict.fromkeys(("Design", "Pose", "design_from_dict", "load_design", "load_design_bytes",
                     "save_design"), "paraloop_core.design"),
    **dict.fromkeys(("Solution", "solve"), "paraloop_core.pipeline"),
    **dict.fromkeys(("result_to_dict", "save_result"), "paraloop_core.result"),
    **dict.fromkeys(("ParaloopError", "DesignFileError", "NonGenericMotionError",
                     "InterpolationError", "RealizationError", "FitError", "FabricationError",
                     "EndEffectorError", "NumericalError"), "paraloop_core.errors"),
}
__all__ = list(_PUBLIC)


def __getattr__(name: str) -> Any:
    if name not in _PUBLIC:
        raise AttributeError(f"module 'paraloop_core' has no attribute {name!r}")
    value = getattr(importlib.import_module(_PUBLIC[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_PUBLIC])
