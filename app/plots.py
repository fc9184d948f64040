"""uPlot charts of the selected loop: joint angles against the driving joint, the singularity
measure over the cycle and the realized loop's clearance over the cycle."""

from __future__ import annotations

from typing import Any

import numpy as np
import viser
import viser.uplot as uplot

from paraloop_core.algebra import dq, poly
from paraloop_core.linkage import loops, singularity
from paraloop_core.realization.clearance import segment_distance

SAMPLES = 241
CLEARANCE_SAMPLES = 121  # plus the exact minimizers of the 42 pairs
_JOINT_COLORS = ("#d62728", "#2ca02c", "#1f77b4", "#bcbd22", "#9467bd")


def _series(label: str, color: str) -> uplot.Series:
    return uplot.Series(label=label, stroke=color, width=2)


def _chart(gui: Any, title: str, x_label: str, y_label: str, series: tuple, **kw: Any) -> Any:
    """A uPlot line chart with a numeric (not time) x axis and empty data."""
    return gui.add_uplot(
        tuple(np.zeros(2) for _ in series), series, title=title, aspect=1.4,
        scales={"x": uplot.Scale(time=False)},
        axes=(uplot.Axis(label=x_label), uplot.Axis(label=y_label)), **kw)


def clearance_curve(real: Any, t: np.ndarray) -> np.ndarray:
    """Smallest centre-line distance ``(T,)`` over the realization's checked edge pairs."""
    links = loops.link_poses(real.joint_factors, t)  # (T, 6, 8)
    pts = dq.transform_points(np.repeat(links, 2, axis=1), real.points)  # (T, 12, 3)
    e1, e2 = real.pairs[:, 0], real.pairs[:, 1]
    dist = segment_distance(pts[:, e1], pts[:, (e1 + 1) % 12], pts[:, e2], pts[:, (e2 + 1) % 12])
    return dist.min(axis=1)


def joint_angle_curves(joint_factors: np.ndarray, samples: int = SAMPLES) -> np.ndarray:
    """Rows: the driving angle (joint 0, degrees, uniform in (0, 360)) and joints 1..5 (degrees).

    Joint 0 turns by ``phi = 2 atan2(-|p|, t - h_0)`` (:func:`loops.joint_angles`), so the
    parameters ``t = h_0 - |p| / tan(phi / 2)`` sample its angle uniformly."""
    h = joint_factors[0]
    phi = np.linspace(-2.0 * np.pi, 0.0, samples + 2)[1:-1]
    t = h[0] - np.linalg.norm(h[1:4]) / np.tan(0.5 * phi)
    ang = np.degrees(loops.joint_angles(joint_factors, t))
    return np.concatenate([ang[:, :1] + 360.0, ang[:, 1:]], axis=1).T


class Plots:
    """The "Plots" folder; :meth:`update` redraws all charts for a solution (worker only)."""

    def __init__(self, server: viser.ViserServer) -> None:
        gui = server.gui
        with gui.add_folder("Plots"):
            self.clearance = _chart(
                gui, "Clearance of the realized loop over the cycle", "cycle position",
                "distance (design units)",
                (uplot.Series(label="u"), _series("clearance", "#1f77b4"),
                 _series("2 rho", "#7f7f7f")), visible=False)
            self.angles = _chart(
                gui, "Joint angles vs driving joint", "joint 0 (deg)", "deg",
                (uplot.Series(label="joint 0"),
                 *(_series(f"joint {k}", c) for k, c in enumerate(_JOINT_COLORS, 1))))
            self.singular = _chart(
                gui, "Singularity measure over the cycle", "cycle position", "S",
                (uplot.Series(label="u"), _series("S(t)", "#d62728")))

    def update(self, sol: Any) -> None:
        """Recompute the charts of ``sol``'s selected loop."""
        jf = sol.loop.joint_factors
        self.angles.data = tuple(joint_angle_curves(jf))
        u = np.linspace(0.0, 1.0, SAMPLES)
        t = poly.param_to_t(u)
        self.singular.data = (u, singularity.singularity_curve(jf, t))
        real = sol.realization
        self.clearance.visible = real is not None
        if real is not None:  # add the exact minimizers of the pairs so the dips show
            uc = np.unique(np.concatenate([np.linspace(0.0, 1.0, CLEARANCE_SAMPLES),
                                           poly.t_to_param(real.pair_t)]))
            self.clearance.data = (uc, clearance_curve(real, poly.param_to_t(uc)),
                                   np.full(len(uc), 2 * real.radius))
