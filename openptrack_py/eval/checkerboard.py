"""The checkerboard calibration run end to end on simulated sensors.

What ``openptrack calibrate checkerboard --sim`` runs: a scripted board session
(:func:`openptrack_py.sim.board_session.board_session`: the board held at varying tilts where
pairs of sensors see it, then laid on the floor) is rendered through every sensor at its
true pose and real resolution (:class:`~openptrack_py.sim.render.DepthRenderer` plus
:func:`~openptrack_py.sim.boards.draw_board`, with the sensor's depth and image noise and
the person holding the board), the board's corners are detected in each frame as on a
real sensor (:func:`~openptrack_py.calibration.checkerboard.detect_board`, colour or
infrared per type), and the poses are solved
(:func:`~openptrack_py.calibration.extrinsics.calibrate_extrinsics`). The estimates are
then compared with the true poses.

The world frame is set by the floor board at its true pose, as a user who measured where
the board lay would give it, so the estimates are in the room's coordinates.

The module is long because rendering a session and solving it are separate steps (one
rendering is solved several ways by the intrinsics table and its test) beside the
recording of sessions to folders; the recording is the next thing to move into a module
of its own.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from openptrack_py.calibration.checkerboard import (
    BoardView,
    Checkerboard,
    average_views,
    board_pose,
    detect_board,
)
from openptrack_py.calibration.evidence import REFINE_LEVEL
from openptrack_py.calibration.extrinsics import ExtrinsicCalibration, calibrate_extrinsics
from openptrack_py.calibration.intrinsics import calibrate_intrinsics
from openptrack_py.calibration.observations import BoardObservation
from openptrack_py.calibration.progress import CalibrationProgress
from openptrack_py.config import Pose, SensorConfig
from openptrack_py.detection.frame import Frame, Intrinsics
from openptrack_py.errors import CalibrationError, ConfigError
from openptrack_py.geometry import world_from_optical
from openptrack_py.sensor_types import SENSOR_TYPES
from openptrack_py.sim.board_session import (
    BoardPlacement,
    BoardSession,
    board_session,
    holder_snapshot,
)
from openptrack_py.sim.boards import SIM_BOARD, draw_board
from openptrack_py.sim.render import DepthRenderer
from openptrack_py.sim.sensor_spec import SensorSpec
from openptrack_py.sim.world import Room


@dataclass(frozen=True)
class SimSensor:
    """A simulated sensor to calibrate.

    Parameters
    ----------
    id : str
        Sensor id.
    type : str
        ``kinect1``, ``kinect2``, ``realsense`` or ``sr4500``.
    pose : Pose
        True pose in the world.
    intrinsics : Intrinsics, optional
        The unit's true pinhole (and lens) when it is not its type's nominal one (the
        renderer draws with it).
    reported : Intrinsics, optional
        The camera model the unit's driver reports with its frames (a factory
        calibration: near the truth, not exact), given to the calibration as a real
        unit's frames give it. ``None``: its frames carry its pinhole without a lens (a
        driver that does not know its lens) and the calibration is given its type's
        nominal pinhole.
    """

    id: str
    type: str
    pose: Pose
    intrinsics: Intrinsics | None = None
    reported: Intrinsics | None = None

    @property
    def reports(self) -> Intrinsics:
        """The camera model its frames carry."""
        if self.reported is not None:
            return self.reported
        return (self.intrinsics or Intrinsics.for_sensor(self.type)).with_distortion(())

    @classmethod
    def from_config(cls, cfg: SensorConfig) -> SimSensor:
        """From a network file's sensor entry.

        Raises
        ------
        ConfigError
            If the entry has no pose.
        """
        if cfg.pose is None:
            raise ConfigError(f"sensors.{cfg.id}.pose: a simulated sensor needs a pose")
        if cfg.sim_lens is None:
            return cls(cfg.id, cfg.type, cfg.pose)
        spec = SensorSpec.from_config(cfg)  # the unit's lens and what it reports
        reported = None if cfg.sim_lens.reported is None else spec.reported_intrinsics
        return cls(cfg.id, cfg.type, cfg.pose, spec.intrinsics, reported)

    def with_own_pinhole(self, focal: float, focal_y: float, du: float, dv: float) -> SimSensor:
        """The sensor as a unit with its own pinhole, off its type's nominal one.

        Focal lengths scaled by ``1 + focal`` and ``1 + focal_y``, the principal point
        moved by ``(du, dv)`` pixels of a 512-pixel-wide image (scaled to the type's).
        """
        k = Intrinsics.for_sensor(self.type)
        scale = k.width / 512
        own = Intrinsics(
            k.width, k.height, k.fx * (1 + focal), k.fy * (1 + focal_y),
            k.cx + du * scale, k.cy + dv * scale,
        )  # fmt: skip
        return SimSensor(self.id, self.type, self.pose, own)

    def spec(self) -> SensorSpec:
        """The simulator's description of this sensor.

        Raises
        ------
        ConfigError
            For an unknown sensor type.
        """
        if self.type not in SENSOR_TYPES:
            raise ConfigError(
                f"sensors.{self.id}.type: unknown {self.type!r} "
                f"(allowed: {', '.join(SENSOR_TYPES)})"
            )
        kind = SENSOR_TYPES[self.type]
        return SensorSpec(id=self.id, type=kind, pose=self.pose, rate_hz=kind.rate_hz)


ACCEPTANCE_ROOM = Room(6.0, 5.0)
"""The room of the checkerboard acceptance figure: 6 x 5 m, empty."""
ACCEPTANCE_SENSORS = (
    SimSensor("k2a", "kinect2", Pose(x=0.2, y=0.2, z=2.6, yaw_deg=40, pitch_deg=25)),
    SimSensor("k2b", "kinect2", Pose(x=5.8, y=0.2, z=2.6, yaw_deg=140, pitch_deg=25)),
    SimSensor("k2c", "kinect2", Pose(x=5.8, y=4.8, z=2.6, yaw_deg=-140, pitch_deg=25)),
    SimSensor("sr", "sr4500", Pose(x=0.2, y=4.8, z=2.4, yaw_deg=-40, pitch_deg=30)),
)
"""Three Kinect v2 in three corners of :data:`ACCEPTANCE_ROOM`, an SR4500 in the fourth
(lower, steeper): the issue's "3 Kinect v2 + 1 SR4500 in a room"."""


@dataclass(frozen=True)
class PoseError:
    """How far an estimated pose is from the true one.

    Parameters
    ----------
    translation_cm : float
        Distance between the estimated and true optical centres, centimetres.
    rotation_deg : float
        Angle of the rotation between the estimated and true orientations, degrees.
    """

    translation_cm: float
    rotation_deg: float


def pose_error(estimate: np.ndarray, truth: np.ndarray) -> PoseError:
    """Translation and rotation error of a 4x4 ``world_from_optical`` estimate."""
    rel = estimate[:3, :3].T @ truth[:3, :3]
    cos = float(np.clip((np.trace(rel) - 1.0) / 2.0, -1.0, 1.0))
    return PoseError(
        translation_cm=100.0 * float(np.linalg.norm(estimate[:3, 3] - truth[:3, 3])),
        rotation_deg=math.degrees(math.acos(cos)),
    )


@dataclass(frozen=True, eq=False)
class SimCalibration:
    """A simulated checkerboard calibration and how close it came.

    Parameters
    ----------
    calibration : ExtrinsicCalibration
        The estimated poses and the solver's report.
    truth : dict
        Per sensor id: the true 4x4 ``world_from_optical``.
    errors : dict
        Per sensor id: the estimate's :class:`PoseError`.
    session : BoardSession
        The scripted board placements.
    detections : dict
        Per sensor id: placements in which its detector found the board.
    """

    calibration: ExtrinsicCalibration
    truth: dict[str, np.ndarray]
    errors: dict[str, PoseError]
    session: BoardSession
    detections: dict[str, int]

    def to_dict(self) -> dict:
        """JSON-ready summary: per sensor the estimated pose, its error and views; the report."""
        poses = self.calibration.poses()
        return {
            "sensors": {
                sid: {
                    "pose": poses[sid].model_dump(),
                    "translation_error_cm": err.translation_cm,
                    "rotation_error_deg": err.rotation_deg,
                    "views": self.detections[sid],
                }
                for sid, err in self.errors.items()
            },
            "placements": len(self.session.placements),
            "report": self.calibration.report.to_dict(),
        }


def render_observations(
    sensors: Sequence[SimSensor],
    room: Room,
    session: BoardSession,
    *,
    seed: int = 0,
    floor_frames: int = 5,
    progress: CalibrationProgress | None = None,
) -> list[BoardObservation]:
    """Render the session through every sensor and detect the board in each frame.

    Each sensor captures a placement at its stamp plus a per-sensor phase within one
    frame period (sensors are not synchronised). A sensor sees the floor board when it
    finds it in at least half of its frames.

    Parameters
    ----------
    sensors : sequence of SimSensor
        The sensors, at their true poses.
    room : Room
        The room.
    session : BoardSession
        The placements.
    seed : int
        Seed of the image and depth noise.
    floor_frames : int
        Frames captured of the board lying on the floor; their corners are averaged
        (:func:`~openptrack_py.calibration.checkerboard.average_views`). A held board
        moves, so one frame is taken of each held placement.
    progress : CalibrationProgress, optional
        Updated after every placement.

    Returns
    -------
    list of BoardObservation
        One per frame where the board was found.
    """
    rigs = sensor_rigs(sensors, room, seed)
    out: list[BoardObservation] = []
    for seq, placement in enumerate(session.placements):
        found: dict[str, np.ndarray | None] = {}
        frames = floor_frames if placement.on_floor else 1
        for rig in rigs:
            view = _capture(rig, session.board, placement, seq, frames)
            found[rig.sensor.id] = None if view is None else view.corners
            if view is not None:
                stamp = placement.stamp + rig.phase
                out.append(
                    BoardObservation(rig.sensor.id, stamp, view.corners, view.camera_from_board)
                )
        if progress is not None:
            progress.update(placement.stamp, found)
    return out


@dataclass(frozen=True, eq=False)
class SensorRig:
    """One simulated sensor as it captures the session."""

    sensor: SimSensor
    renderer: DepthRenderer  # with the sensor's noise
    truth: DepthRenderer  # noise-free, for the board's occlusion
    rng: np.random.Generator  # the sensor's noise source
    phase: float  # capture delay after each placement's stamp (sensors are not in sync)


def sensor_rigs(
    sensors: Sequence[SimSensor], room: Room, seed: int, only: str | None = None
) -> list[SensorRig]:
    """Each sensor's renderers, noise source and capture phase, seeded from ``seed``.

    With ``only``, that sensor's rig alone (the same as among all of them: each sensor
    has its own spawned seed).
    """
    seeds = np.random.SeedSequence(seed).spawn(len(sensors))
    rigs = []
    for sensor, ss in zip(sensors, seeds, strict=True):
        if only is not None and sensor.id != only:
            continue
        spec = sensor.spec()
        rng = np.random.default_rng(ss)
        rigs.append(
            SensorRig(
                sensor,
                DepthRenderer(
                    spec, room, rng, intrinsics=sensor.intrinsics, reports=sensor.reports
                ),
                DepthRenderer(spec, room, rng, noise=False, intrinsics=sensor.intrinsics),
                rng,
                float(rng.uniform(0.0, 1.0 / spec.rate_hz)),
            )
        )
    return rigs


def _capture(
    rig: SensorRig, board: Checkerboard, placement: BoardPlacement, seq: int, frames: int
) -> BoardView | None:
    """One sensor's view of one placement: its frames' corners averaged.

    None unless the board is found in at least half of the ``frames`` frames.
    """
    views = []
    for frame in placement_frames(rig, board, placement, seq, frames):
        view = detect_board(frame, board, rig.sensor.type)
        if view is not None:
            views.append(view)
    if 2 * len(views) < frames or not views:
        return None
    return average_views(views, board, rig.renderer.reports)


def placement_frames(
    rig: SensorRig, board: Checkerboard, placement: BoardPlacement, seq: int, frames: int
) -> Iterator[Frame]:
    """One sensor's ``frames`` consecutive frames of one placement, the board drawn in.

    The frames carry the camera model the unit reports (:attr:`SimSensor.reports`): a
    unit whose driver does not know its lens gives its corners raw, for the calibration
    to solve the lens; one that reports a lens has them undistorted by it.
    """
    renderer = rig.renderer
    period = 1.0 / rig.sensor.spec().rate_hz
    stamp = placement.stamp + rig.phase
    snap = holder_snapshot(placement, stamp)
    scene = rig.truth.render(snap, stamp, seq).frame.depth
    for i in range(frames):
        yield draw_board(
            renderer.render(snap, stamp + i * period, seq),
            board,
            placement.world_from_board,
            renderer.world_from_camera,
            renderer.intrinsics,
            sensor_type=rig.sensor.type,
            rng=rig.rng,
            scene_depth=scene,
        ).frame


def record_board_session(
    sensors: Sequence[SimSensor],
    room: Room,
    session: BoardSession,
    out_dir: Path,
    *,
    seed: int = 0,
    held_frames: int = 4,
    floor_frames: int = 8,
) -> dict[str, Path]:
    """Write a session as each sensor would record it (``openptrack record-sensor``).

    One folder per sensor, ``out_dir/<sensor id>``: ``held_frames`` consecutive frames
    of each held placement (the board still), ``floor_frames`` of the board on the
    floor, nothing while it is carried between placements; each sensor at its own
    phase (unsynchronised). What ``openptrack calibrate checkerboard --recordings`` reads.

    Returns
    -------
    dict of str to Path
        Each sensor's folder.
    """
    from openptrack_py.detection.sources import record_folder

    out: dict[str, Path] = {}
    for rig in sensor_rigs(sensors, room, seed):
        folder = out_dir / rig.sensor.id
        record_folder(session_frames(rig, session, held_frames, floor_frames), folder)
        out[rig.sensor.id] = folder
    return out


def session_frames(
    rig: SensorRig, session: BoardSession, held_frames: int = 4, floor_frames: int = 8
) -> Iterator[Frame]:
    """One sensor's frames of a session, in order.

    ``held_frames`` of each held placement (the board still), ``floor_frames`` of the
    board on the floor, none while it is carried between placements.
    """
    for seq, placement in enumerate(session.placements):
        frames = floor_frames if placement.on_floor else held_frames
        yield from placement_frames(rig, session.board, placement, seq, frames)


def refit_intrinsics(
    observations: Sequence[BoardObservation], sensors: Sequence[SimSensor], board: Checkerboard
) -> tuple[dict[str, Intrinsics], list[BoardObservation]]:
    """Each sensor's pinhole from its own views (``calibrateCamera``), and views re-posed.

    Distortion is not estimated (the simulated sensors have none).

    Raises
    ------
    CalibrationError
        Naming a sensor with fewer than three views.
    """
    fitted: dict[str, Intrinsics] = {}
    for sensor in sensors:
        kind = SENSOR_TYPES[sensor.type]
        corners = [o.corners for o in observations if o.sensor_id == sensor.id]
        try:
            fit = calibrate_intrinsics(
                corners, board, kind.width, kind.height,
                initial=Intrinsics.for_sensor(sensor.type), distortion=False,
            )  # fmt: skip
        except CalibrationError as exc:
            raise CalibrationError(f"sensor {sensor.id!r}: {exc}") from None
        fitted[sensor.id] = fit.intrinsics
    reposed = []
    for o in observations:
        pose = board_pose(o.corners, board, fitted[o.sensor_id]).camera_from_board
        reposed.append(BoardObservation(o.sensor_id, o.stamp, o.corners, pose))
    return fitted, reposed


def render_board_session(
    sensors: Sequence[SimSensor],
    room: Room,
    *,
    board: Checkerboard = SIM_BOARD,
    placements: int = 30,
    seed: int = 0,
    progress: CalibrationProgress | None = None,
) -> tuple[BoardSession, list[BoardObservation]]:
    """Script a board session (seed ``seed``) and render it through every sensor.

    Returns the session and the board observations found in the rendered frames (the
    sensors' noise drawn from ``seed + 1``); see :func:`simulate_checkerboard_calibration`.
    """
    rng = np.random.default_rng(seed)
    session = board_session(board, room, [s.spec() for s in sensors], rng, placements=placements)
    observations = render_observations(sensors, room, session, seed=seed + 1, progress=progress)
    return session, observations


def solve_board_session(
    sensors: Sequence[SimSensor],
    session: BoardSession,
    observations: list[BoardObservation],
    *,
    board: Checkerboard = SIM_BOARD,
    reference: str | None = None,
    min_shared_views: int = 3,
    estimate_intrinsics: bool = False,
    refine_intrinsics: bool = False,
    lens: str = "radial",
    refine_level: float | None = REFINE_LEVEL,
) -> SimCalibration:
    """Solve a rendered session's poses and compare them with the true ones.

    See :func:`simulate_checkerboard_calibration`; one rendering can be solved several
    ways.
    """
    floor = session.floor
    # what each unit reports, or its type's nominal pinhole
    intrinsics = {s.id: s.reported or Intrinsics.for_sensor(s.type) for s in sensors}
    if estimate_intrinsics:
        intrinsics, observations = refit_intrinsics(observations, sensors, board)
    calibration = calibrate_extrinsics(
        observations,
        intrinsics,
        board.object_points(),
        reference=reference,
        floor_stamp=None if floor is None else floor.stamp,
        world_from_floor_board=None if floor is None else floor.world_from_board,
        min_shared_views=min_shared_views,
        refine_intrinsics=refine_intrinsics,
        lens=lens,
        refine_level=refine_level,
    )
    truth = {s.id: world_from_optical(s.pose) for s in sensors}
    errors = {s.id: pose_error(calibration.world_from_optical[s.id], truth[s.id]) for s in sensors}
    counts = {s.id: sum(o.sensor_id == s.id for o in observations) for s in sensors}
    return SimCalibration(calibration, truth, errors, session, counts)


def simulate_checkerboard_calibration(
    sensors: Sequence[SimSensor],
    room: Room,
    *,
    board: Checkerboard = SIM_BOARD,
    placements: int = 30,
    seed: int = 0,
    reference: str | None = None,
    min_shared_views: int = 3,
    estimate_intrinsics: bool = False,
    refine_intrinsics: bool = False,
    lens: str = "radial",
    refine_level: float | None = REFINE_LEVEL,
    progress: CalibrationProgress | None = None,
) -> SimCalibration:
    """Run the whole checkerboard calibration on simulated sensors.

    Parameters
    ----------
    sensors : sequence of SimSensor
        The sensors to calibrate, at their true poses.
    room : Room
        The room they are in.
    board : Checkerboard
        The board moved around (OpenPTrack's 5 x 6 corners of 0.12 m by default).
    placements : int
        Held board placements (the floor placement comes on top).
    seed : int
        Seed of the session script and of the sensors' noise.
    reference : str, optional
        The sensor held fixed in the solve; the first by default.
    min_shared_views : int
        Fewest placements two sensors must share to link them.
    estimate_intrinsics : bool
        Estimate each sensor's pinhole from its views (:func:`refit_intrinsics`) rather
        than use its type's nominal one (which the renderer uses).
    refine_intrinsics : bool
        Solve every sensor's pinhole and lens distortion with the poses, from its
        type's nominal one (:func:`~openptrack_py.calibration.extrinsics.calibrate_extrinsics`).
    lens : {"radial", "full"}
        The lens terms ``refine_intrinsics`` solves.
    refine_level : float, optional
        A sensor's refinement is kept only where its views show its given intrinsics
        wrong, at this chance of refining right ones; ``None``: always.
    progress : CalibrationProgress, optional
        Updated after every placement, as a live capture loop would.

    Returns
    -------
    SimCalibration
        Estimates, truth and per-sensor pose errors.

    Raises
    ------
    CalibrationError
        When the calibration itself fails (a sensor never saw the board, sensors not
        connected by enough shared views, ...).
    """
    session, observations = render_board_session(
        sensors, room, board=board, placements=placements, seed=seed, progress=progress
    )
    return solve_board_session(
        sensors, session, observations, board=board, reference=reference,
        min_shared_views=min_shared_views, estimate_intrinsics=estimate_intrinsics,
        refine_intrinsics=refine_intrinsics, lens=lens, refine_level=refine_level,
    )  # fmt: skip
