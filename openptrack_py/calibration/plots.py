"""Pictures of a walk calibration: the walker's trajectories before and after, from above.

:func:`plot_walk` draws two top views side by side: every sensor's detections of the
walk mapped to the world with the starting poses (left) and with the calibrated ones
(right), one colour per sensor, each sensor's position as a dot with a stroke along its
heading, and the disagreement figures in the titles. When the sensors agree, their
trajectories lie on top of each other.

Matplotlib is imported inside the function (Agg canvas, no display, no global backend
change): importing this module needs neither matplotlib nor a screen.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from openptrack_py.calibration.walk import Pose2D, WalkCalibration, WalkTrack
from openptrack_py.errors import CalibrationError

_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2")


def _panel(
    ax: Any,
    tracks: Sequence[WalkTrack],
    poses: Mapping[str, Pose2D],
    title: str,
    max_points: int,
) -> None:
    """One top view: each sensor's detections through ``poses``, and the sensors."""
    for k, track in enumerate(tracks):
        colour = _COLOURS[k % len(_COLOURS)]
        pose = poses[track.sensor_id]
        xy = pose.apply(track.xy)
        if len(xy) > max_points:
            xy = xy[:: math.ceil(len(xy) / max_points)]
        ax.scatter(xy[:, 0], xy[:, 1], s=2, color=colour, alpha=0.5, label=track.sensor_id)
        heading = np.array([math.cos(pose.yaw), math.sin(pose.yaw)])
        ax.scatter([pose.x], [pose.y], marker="o", s=60, color=colour, edgecolor="black")
        ax.plot(
            [pose.x, pose.x + 0.8 * heading[0]], [pose.y, pose.y + 0.8 * heading[1]], color=colour
        )
    ax.set_title(title, fontsize=9)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=7, markerscale=4)


def plot_walk(
    path: str | Path,
    tracks: Sequence[WalkTrack],
    before: Mapping[str, Pose2D],
    result: WalkCalibration,
    *,
    max_points: int = 4000,
) -> Path:
    """Write a before/after top view of the walk as each sensor reports it, as a PNG.

    Parameters
    ----------
    path : str or Path
        The PNG to write (its folder must exist).
    tracks : sequence of WalkTrack
        Each sensor's detections in its own floor frame (as given to
        :func:`~openptrack_py.calibration.walk.calibrate_walk`; for a refinement of
        world-frame tracks, map them back with the current poses' inverses).
    before : Mapping of str to Pose2D
        The starting poses (the current calibration, or the rough guess).
    result : WalkCalibration
        The calibration; its solved poses are drawn, accepted or not.
    max_points : int
        Largest number of detections drawn per sensor (thinned evenly).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    CalibrationError
        If matplotlib is missing or a sensor has no pose.
    """
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError:  # pragma: no cover - depends on the installed packages
        raise CalibrationError("walk plot: needs matplotlib (pip install matplotlib)") from None
    after = dict(result.solved_poses) or dict(result.poses)
    missing = [
        t.sensor_id for t in tracks if t.sensor_id not in before or t.sensor_id not in after
    ]
    if missing:
        raise CalibrationError(f"walk plot: no pose for sensor {', '.join(missing)}")
    fig = Figure(figsize=(12, 6), dpi=100)
    FigureCanvasAgg(fig)
    left, right = fig.subplots(1, 2)
    b, a = result.before, result.after
    _panel(
        left,
        tracks,
        before,
        f"before: disagreement {100 * b.binned_m:.1f} cm (per frame {100 * b.raw_m:.1f} cm)",
        max_points,
    )
    verdict = "accepted" if result.accepted else "refused"
    _panel(
        right,
        tracks,
        after,
        f"after ({result.method}, {verdict}): disagreement {100 * a.binned_m:.1f} cm "
        f"(per frame {100 * a.raw_m:.1f} cm)",
        max_points,
    )
    fig.suptitle(
        f"walk calibration: disagreement {100 * b.binned_m:.1f} -> {100 * a.binned_m:.1f} cm "
        f"({result.improvement:.1f}x)",
        fontsize=11,
    )
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, format="png")
    return out
