"""The pose graph of the sensors: who is linked to whom, and the sensors' initial poses.

Steps 2 and 3 of the checkerboard calibration of Munaro et al., OpenPTrack (§4). Sensors
are nodes; an edge's weight is the number of board placements both sensors saw
(:func:`~openptrack_py.calibration.observations.pair_views`). The sensors must be
connected by edges of at least ``min_shared_views`` (:func:`connected_groups`,
:func:`check_connected`). Initial poses are chained from the reference sensor along a
maximum spanning tree (Prim's algorithm, :func:`spanning_tree`): each tree edge's
relative pose is the robust consensus (:func:`consensus_pose`) of its shared views, and
each placement's board pose the consensus of its views (:func:`board_guesses`). These
start the bundle adjustment (:mod:`openptrack_py.calibration.bundle`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from openptrack_py.calibration.observations import BoardObservation, Placement, pair_views
from openptrack_py.errors import CalibrationError
from openptrack_py.geometry import invert

__all__ = [
    "board_guesses",
    "chain_sensors",
    "check_connected",
    "connected_groups",
    "consensus_pose",
    "spanning_tree",
]


def connected_groups(
    sensor_ids: Sequence[str], counts: Mapping[tuple[str, str], int], min_shared_views: int
) -> list[list[str]]:
    """Groups of sensors linked by pairs sharing at least ``min_shared_views`` placements.

    Returns
    -------
    list of list of str
        Each group's ids in the order of ``sensor_ids``; groups in order of their first.
    """
    root = {s: s for s in sensor_ids}

    def find(s: str) -> str:
        while root[s] != s:
            root[s] = root[root[s]]
            s = root[s]
        return s

    for (a, b), n in counts.items():
        if n >= min_shared_views and a in root and b in root:
            root[find(a)] = find(b)
    groups: dict[str, list[str]] = {}
    for s in sensor_ids:
        groups.setdefault(find(s), []).append(s)
    return list(groups.values())


def spanning_tree(
    sensor_ids: Sequence[str],
    counts: Mapping[tuple[str, str], int],
    reference: str,
    min_shared_views: int = 1,
) -> list[tuple[str, str]]:
    """Maximum spanning tree of the pose graph from ``reference`` (Prim's algorithm).

    Returns
    -------
    list of (str, str)
        ``(parent, child)`` edges in the order sensors join the tree; sensors that cannot
        be reached through pairs of at least ``min_shared_views`` are left out.
    """

    def weight(a: str, b: str) -> int:
        return counts.get((min(a, b), max(a, b)), 0)

    inside = {reference}
    edges: list[tuple[str, str]] = []
    while True:
        best: tuple[int, str, str] | None = None
        for a in sensor_ids:
            if a not in inside:
                continue
            for b in sensor_ids:
                if b in inside:
                    continue
                w = weight(a, b)
                if w >= min_shared_views and (best is None or w > best[0]):
                    best = (w, a, b)
        if best is None:
            return edges
        inside.add(best[2])
        edges.append((best[1], best[2]))


def consensus_pose(poses: Sequence[np.ndarray]) -> np.ndarray:
    """A robust mean of 4x4 rigid transforms.

    The largest set of transforms agreeing with one of them (within 5 degrees, and 10 cm
    plus 5% of its distance), averaged: rotations by the chordal mean (the nearest
    rotation to the mean matrix), translations by the median.
    """
    stack = np.asarray(poses, dtype=float)
    best: np.ndarray | None = None
    for pose in stack:
        rel = np.einsum("ij,nik->njk", pose[:3, :3], stack[:, :3, :3])
        cos = np.clip((np.trace(rel, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
        tol = 0.1 + 0.05 * np.linalg.norm(pose[:3, 3])
        agree = (np.arccos(cos) < math.radians(5.0)) & (
            np.linalg.norm(stack[:, :3, 3] - pose[:3, 3], axis=1) < tol
        )
        if best is None or agree.sum() > best.sum():
            best = agree
    members = stack[best]
    u, _, vt = np.linalg.svd(members[:, :3, :3].sum(axis=0))
    rot = u @ vt
    if np.linalg.det(rot) < 0:
        rot = u @ np.diag([1.0, 1.0, -1.0]) @ vt
    out = np.eye(4)
    out[:3, :3] = rot
    out[:3, 3] = np.median(members[:, :3, 3], axis=0)
    return out


def check_connected(
    sensor_ids: Sequence[str], counts: Mapping[tuple[str, str], int], min_shared_views: int
) -> None:
    """Raise naming the groups if the sensors are not linked by enough shared views.

    Parameters
    ----------
    sensor_ids : sequence of str
        Every sensor to calibrate.
    counts : mapping of (str, str) to int
        Placements seen by both sensors of each pair (ids sorted), as
        :func:`~openptrack_py.calibration.observations.pair_views` counts them.
    min_shared_views : int
        Fewest shared placements that link two sensors.

    Raises
    ------
    CalibrationError
        Naming the groups, the minimum and the most shared across groups.
    """
    groups = connected_groups(sensor_ids, counts, min_shared_views)
    if len(groups) == 1:
        return
    where = {s: g for g, members in enumerate(groups) for s in members}
    across = [(n, a, b) for (a, b), n in counts.items() if where[a] != where[b]]
    text = " | ".join("[" + ", ".join(g) + "]" for g in groups)
    most = max(across, default=None)
    best = f"{most[1]}–{most[2]} {most[0]}" if most else "none"
    raise CalibrationError(
        "checkerboard calibration: sensors not connected by enough shared board views: "
        f"groups {text}; each link needs at least {min_shared_views} placements seen by "
        f"both sensors (most shared across groups: {best}); show the board to sensors of "
        "different groups at once"
    )


def _by_placement(
    observations: Sequence[BoardObservation], placements: Sequence[Placement]
) -> list[dict[str, BoardObservation]]:
    """Each placement's views by sensor id."""
    return [{observations[i].sensor_id: observations[i] for i in p.views} for p in placements]


def chain_sensors(
    observations: Sequence[BoardObservation],
    placements: Sequence[Placement],
    sensor_ids: Sequence[str],
    reference: str,
    min_shared_views: int,
) -> dict[str, np.ndarray]:
    """Initial ``camera_from_ref`` per sensor, chained along the maximum spanning tree.

    Each tree edge's relative pose is the :func:`consensus_pose` of its shared views'
    ``child_from_board @ board_from_parent``. Sensors the tree does not reach are left out.

    Parameters
    ----------
    observations : sequence of BoardObservation
        The board views.
    placements : sequence of Placement
        Their placements.
    sensor_ids : sequence of str
        Every sensor to calibrate.
    reference : str
        The sensor whose frame is the reference (its pose is the identity).
    min_shared_views : int
        Fewest shared placements that make an edge of the tree.

    Returns
    -------
    dict of str to ndarray
        4x4 ``camera_from_ref`` per sensor reached.
    """
    by_placement = _by_placement(observations, placements)
    counts = pair_views(observations, placements)
    cam_from_ref = {reference: np.eye(4)}
    for parent, child in spanning_tree(sensor_ids, counts, reference, min_shared_views):
        rel = [
            views[child].camera_from_board @ invert(views[parent].camera_from_board)
            for views in by_placement
            if parent in views and child in views
        ]
        cam_from_ref[child] = consensus_pose(rel) @ cam_from_ref[parent]
    return cam_from_ref


def board_guesses(
    observations: Sequence[BoardObservation],
    placements: Sequence[Placement],
    cam_from_ref: Mapping[str, np.ndarray],
) -> np.ndarray:
    """Initial ``ref_from_board`` per placement: the consensus of its views.

    Parameters
    ----------
    observations : sequence of BoardObservation
        The board views.
    placements : sequence of Placement
        Their placements (:func:`~openptrack_py.calibration.observations.group_placements`).
    cam_from_ref : mapping of str to ndarray
        Every sensor's 4x4 ``camera_from_ref`` (:func:`chain_sensors`).

    Returns
    -------
    ndarray
        ``(placements, 4, 4)`` board poses in the reference sensor's frame.
    """
    return np.stack(
        [
            consensus_pose([invert(cam_from_ref[s]) @ o.camera_from_board for s, o in v.items()])
            for v in _by_placement(observations, placements)
        ]
    )
