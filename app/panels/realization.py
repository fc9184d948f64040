"""Studio controls of the realization (paper Sec. 5.1): whether to search collision-free
bars, the search's fineness, joint spacing and bar radius (relative or in design units) and
fixed bar ends. The values live in ``Design.realization``; handlers only edit the state."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
import viser

from app.worker import FULL
from paraloop_core.design import Design

if TYPE_CHECKING:
    from app.host import StudioHost


class RealizationPanel:
    """The 'Realization' folder; ``guard`` wraps handlers (see :func:`panels.handler`)."""

    def __init__(self, gui: viser.GuiApi, studio: StudioHost,
                 guard: Callable[[Callable[[Any], None]], Callable[[Any], None]]) -> None:
        self.studio = studio
        r: dict[str, Any] = {}
        with gui.add_folder("Realization"):
            r["enabled"] = gui.add_checkbox(
                "Find collision-free bars", initial_value=True,
                hint="search bars on the loop's axes that never collide over the whole motion "
                     "(Sec. 5.1, exact for the continuous cycle)")
            r["p"] = gui.add_number(
                "Search fineness", initial_value=10.0, min=1e-3, step=0.5,
                hint="how finely bar ends are moved along the joint axes: in steps of the "
                     "loop's length divided by this number (the paper's p, Sec. 5.1)")
            r["d_fraction"] = gui.add_number(
                "Joint spacing, relative", initial_value=0.01, min=1e-6, step=0.005,
                hint="the distance between the two bar ends on one joint axis, as a share of "
                     "the loop's length (the paper's d, Sec. 5.1; used when Joint spacing "
                     "below is 0)")
            r["rho_fraction"] = gui.add_number(
                "Bar radius, relative", initial_value=0.25, min=1e-6, step=0.05,
                hint="the bar radius as a share of the joint spacing (the paper's ρ, rho, "
                     "Sec. 5.1; used when Bar radius below is 0); smaller allows thinner bars")
            r["d"] = gui.add_number("Joint spacing", initial_value=0.0, min=0.0, step=0.01,
                                    hint="the joint spacing d in design units; 0 = the "
                                         "relative value above")
            r["rho"] = gui.add_number("Bar radius", initial_value=0.0, min=0.0, step=0.01,
                                      hint="the bar radius ρ (rho) in design units; 0 = the "
                                           "relative value above")
            r["fixed"] = gui.add_text(
                "Fixed bar ends", initial_value="",
                hint="bar ends held at a given place on their joint axis, as joint=offset "
                     "pairs in design units, e.g. 0=0.1, 3=-0.2 (the paper's fixed vertices, "
                     "Sec. 5.1)")
        self.inputs = r
        for key, handle in r.items():
            handle.on_update(guard(lambda _, key=key: self._set(key)))

    def _set(self, key: str) -> None:
        h = self.inputs[key]
        if key == "fixed":
            try:
                value: Any = parse_fixed(h.value)
            except ValueError as exc:
                self.studio.notify("Fixed bar ends", str(exc), error=True)
                return
        elif key in ("d", "rho"):
            value = float(h.value) or None
        else:
            value = h.value
        self.studio.state.edit(lambda d: dataclasses.replace(
            d, realization=dataclasses.replace(d.realization, **{key: value})), key)
        self.studio.request(FULL)

    def sync(self, design: Design) -> None:
        """Show the design's settings (inside :func:`panels.writing_back`)."""
        r = design.realization
        for key, h in self.inputs.items():
            if key == "fixed":
                h.value = ", ".join(f"{k}={v:g}" for k, v in sorted(r.fixed.items()))
            elif key in ("d", "rho"):
                h.value = getattr(r, key) or 0.0
            else:
                h.value = getattr(r, key)


def parse_fixed(text: str) -> dict[int, float]:
    """``'0=0.1, 3=-0.2'`` -> ``{0: 0.1, 3: -0.2}``; raises ValueError on bad input."""
    out: dict[int, float] = {}
    for item in filter(None, (s.strip() for s in text.split(","))):
        key, sep, val = item.partition("=")
        if not sep or not key.strip().isdigit() or not 0 <= int(key) < 6:
            raise ValueError(f"'{item}': expected joint=offset with joint 0..5")
        try:
            out[int(key)] = float(val)
        except ValueError:
            raise ValueError(f"'{item}': offset is not a number") from None
        if not np.isfinite(out[int(key)]):
            raise ValueError(f"'{item}': offset must be finite")
    return out
