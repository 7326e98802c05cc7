"""Board views and placements: which views of different sensors show one board pose.

Step 1 of the checkerboard calibration of Munaro et al., OpenPTrack (§4): the board is
moved through the space and held still at each placement while the sensors capture it.
Views whose stamps are within a tolerance of a placement's first view are views of that
placement (:func:`group_placements`); :func:`pair_views` counts the placements each pair
of sensors saw together, the weights of the pose graph
(:mod:`openptrack_py.calibration.posegraph`); :func:`check_observations` names what is
missing before any of it (the board never seen, a sensor that never saw it).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from itertools import combinations

import numpy as np

from openptrack_py.detection.frame import Intrinsics
from openptrack_py.errors import CalibrationError

__all__ = [
    "BoardObservation",
    "Placement",
    "check_observations",
    "group_placements",
    "pair_views",
]


@dataclass(frozen=True, eq=False)
class BoardObservation:
    """One sensor's view of the board.

    Parameters
    ----------
    sensor_id : str
        Which sensor.
    stamp : float
        Capture time, seconds.
    corners : ndarray
        ``(rows*cols, 2)`` undistorted pixel positions of the inner corners, in the
        board's order.
    camera_from_board : ndarray
        4x4 initial guess of the board's pose in the camera (``solvePnP``).
    """

    sensor_id: str
    stamp: float
    corners: np.ndarray
    camera_from_board: np.ndarray


@dataclass(frozen=True)
class Placement:
    """Views of one physical placement of the board.

    Parameters
    ----------
    stamp : float
        Stamp of the placement's first view.
    views : tuple of int
        Indices of its observations, one per sensor.
    """

    stamp: float
    views: tuple[int, ...]


def group_placements(
    observations: Sequence[BoardObservation], tolerance_s: float
) -> list[Placement]:
    """Group views into board placements by stamp.

    A placement starts at the earliest view not yet grouped and takes every view within
    ``tolerance_s`` after it (the board is held still meanwhile); chains of views do not
    extend it. Of several views of one sensor in a placement, the first is kept.

    Parameters
    ----------
    observations : sequence of BoardObservation
        Views of any sensors in any order.
    tolerance_s : float
        Largest spread of stamps within a placement, seconds.

    Returns
    -------
    list of Placement
        In time order.
    """
    order = sorted(range(len(observations)), key=lambda i: observations[i].stamp)
    out: list[Placement] = []
    start = 0
    while start < len(order):
        first = observations[order[start]].stamp
        end = start
        seen: dict[str, int] = {}
        while end < len(order) and observations[order[end]].stamp - first <= tolerance_s:
            seen.setdefault(observations[order[end]].sensor_id, order[end])
            end += 1
        out.append(Placement(first, tuple(seen.values())))
        start = end
    return out


def pair_views(
    observations: Sequence[BoardObservation], placements: Sequence[Placement]
) -> dict[tuple[str, str], int]:
    """Placements seen by both sensors of each pair (ids sorted in the key)."""
    counts: dict[tuple[str, str], int] = {}
    for placement in placements:
        ids = sorted(observations[i].sensor_id for i in placement.views)
        for pair in combinations(ids, 2):
            counts[pair] = counts.get(pair, 0) + 1
    return counts


def check_observations(
    observations: Sequence[BoardObservation], intrinsics: Mapping[str, Intrinsics], n: int
) -> None:
    """Raise if the board was never seen, a view is malformed or a sensor saw nothing.

    Parameters
    ----------
    observations : sequence of BoardObservation
        The board views of all sensors.
    intrinsics : mapping of str to Intrinsics
        Every sensor to calibrate.
    n : int
        Corners per view.

    Raises
    ------
    CalibrationError
        Naming the sensors that never saw the board, or the malformed view.
    """
    if not observations:
        raise CalibrationError(
            "checkerboard calibration: the board was never found by any sensor "
            f"({', '.join(intrinsics)}); check its size (rows x cols of inner corners), "
            "that it is fully in view and lit (or, for time-of-flight sensors, not saturated)"
        )
    for obs in observations:
        if obs.sensor_id not in intrinsics:
            raise CalibrationError(
                f"checkerboard calibration: a view of unknown sensor {obs.sensor_id!r} "
                f"(sensors: {', '.join(intrinsics)})"
            )
        if np.shape(obs.corners) != (n, 2):
            raise CalibrationError(
                f"checkerboard calibration: view of {obs.sensor_id!r} at {obs.stamp:.3f} s has "
                f"corners of shape {np.shape(obs.corners)}, expected ({n}, 2)"
            )
    seen = {o.sensor_id for o in observations}
    blind = [s for s in intrinsics if s not in seen]
    if blind:
        names = ", ".join(repr(s) for s in blind)
        which = "sensor" if len(blind) == 1 else "sensors"
        raise CalibrationError(
            f"checkerboard calibration: {which} {names} never saw the board; hold it "
            "where each such sensor sees it whole, together with at least one other sensor"
        )
