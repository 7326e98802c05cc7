"""A simulated sensor's frames of a checkerboard session, as they come.

What ``openptrack node board`` reads for a simulated sensor: the network's scripted
board session (the one ``openptrack calibrate checkerboard --sim`` runs and ``--sim
--record`` writes: :func:`~openptrack_py.sim.board_session.board_session`) rendered
through that one sensor (:func:`~openptrack_py.eval.checkerboard.session_frames`), paced
as the session goes, ``speed`` times real time. Every board node of the network builds
the same session from the same seed, so their still views of one placement carry
matching stamps, as sensors with synchronised clocks would give.
"""

from __future__ import annotations

import time
from collections.abc import Iterator

import numpy as np

from openptrack_py.calibration.checkerboard import Checkerboard
from openptrack_py.config import NetworkConfig
from openptrack_py.detection.frame import Frame
from openptrack_py.errors import ConfigError
from openptrack_py.eval.checkerboard import SimSensor, sensor_rigs, session_frames
from openptrack_py.sim.board_session import BoardSession, board_session
from openptrack_py.sim.live import scenario_from_network
from openptrack_py.sim.world import Room

__all__ = ["SimBoardSource", "sim_board_session", "sim_sensors"]


def sim_sensors(network: NetworkConfig) -> list[SimSensor]:
    """The network's simulated sensors with a pose (at least two).

    Raises
    ------
    ConfigError
        With fewer than two.
    """
    simulated = [s for s in network.sensors if s.source == "sim" and s.pose is not None]
    if len(simulated) < 2:
        raise ConfigError("--sim needs at least two simulated sensors with a pose")
    return [SimSensor.from_config(s) for s in simulated]


def sim_board_session(
    network: NetworkConfig, board: Checkerboard, *, seed: int, placements: int
) -> tuple[list[SimSensor], Room, BoardSession]:
    """The network's simulated sensors, its room and its scripted board session."""
    sensors = sim_sensors(network)
    room = scenario_from_network(network, calibrated=False).room
    session = board_session(
        board, room, [s.spec() for s in sensors], np.random.default_rng(seed),
        placements=placements,
    )  # fmt: skip
    return sensors, room, session


class SimBoardSource:
    """One simulated sensor's frames of the network's board session, paced.

    Parameters
    ----------
    network : NetworkConfig
        The network (its simulated sensors and room).
    sensor_id : str
        The sensor whose frames to give.
    board : Checkerboard
        The board.
    seed : int
        Seed of the session (the same for every sensor of one session).
    placements : int
        Board placements.
    speed : float
        Times real time (0: as fast as they are rendered).

    Raises
    ------
    ConfigError
        If the sensor is not one of the network's simulated sensors with a pose.
    """

    def __init__(
        self,
        network: NetworkConfig,
        sensor_id: str,
        board: Checkerboard,
        *,
        seed: int = 0,
        placements: int = 30,
        speed: float = 1.0,
    ) -> None:
        sensors, room, self.session = sim_board_session(
            network, board, seed=seed, placements=placements
        )
        rigs = sensor_rigs(sensors, room, seed + 1, only=sensor_id)
        if not rigs:
            raise ConfigError(
                f"--sensor: {sensor_id!r} is not a simulated sensor with a pose "
                f"(those: {', '.join(s.id for s in sensors)})"
            )
        self.rig = rigs[0]
        self.name = f"simulated board session (seed {seed}, {placements} placements)"
        self.intrinsics = self.rig.renderer.reports
        self.speed = speed
        self._closed = False

    def frames(self) -> Iterator[Frame]:
        """The sensor's frames, each no earlier than its place in the session allows."""
        start = time.monotonic()
        first = None
        for frame in session_frames(self.rig, self.session):
            if self._closed:
                return
            first = frame.stamp if first is None else first
            if self.speed > 0:
                delay = start + (frame.stamp - first) / self.speed - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
            yield frame

    def close(self) -> None:
        """Stop giving frames."""
        self._closed = True
