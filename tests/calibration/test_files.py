"""The calibration file: validation that names the field, round trips, use by the simulator."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st

from openptrack_py.calibration.files import (
    CalibrationFile,
    CameraIntrinsics,
    SensorCalibration,
    believed_poses,
    entry_payload,
    load_calibration,
    network_calibration,
    parse_entry_payload,
    save_calibration,
)
from openptrack_py.config import NetworkConfig, Pose, PoseError, SensorConfig, SimConfig
from openptrack_py.detection.frame import Intrinsics
from openptrack_py.errors import CalibrationError, ConfigError
from openptrack_py.geometry import pose_from_transform, world_from_optical
from openptrack_py.sim.scenarios import build_scenario
from openptrack_py.sim.simulator import Simulator

TRUE = Pose(x=0.3, y=0.4, z=2.6, yaw_deg=30.0, pitch_deg=25.0, roll_deg=2.0)


def _write(path: Path, data: dict) -> Path:
    path.write_text(yaml.safe_dump(data))
    return path


def _network(tmp_path: Path, entries: dict, **sensor: object) -> NetworkConfig:
    path = _write(tmp_path / "calibration.yaml", {"version": 1, "sensors": entries})
    return NetworkConfig(
        sensors=[SensorConfig(id="k2_a", pose=TRUE, **sensor)],  # type: ignore[arg-type]
        calibration=path,
        sim=SimConfig(),
    )


@given(
    yaw=st.floats(-180, 180),
    pitch=st.floats(-60, 90),
    roll=st.floats(-40, 40),
)
def test_pose_from_transform_inverts_world_from_optical(
    yaw: float, pitch: float, roll: float
) -> None:
    transform = world_from_optical(
        Pose(x=1, y=2, z=3, yaw_deg=yaw, pitch_deg=pitch, roll_deg=roll)
    )
    back = world_from_optical(pose_from_transform(transform))
    assert np.abs(back - transform).max() < 1e-9


def test_a_saved_file_loads_back_to_the_same_poses(tmp_path: Path) -> None:
    transform = world_from_optical(TRUE)
    entry = SensorCalibration.from_transform(
        transform, method="checkerboard", clock_offset_s=0.012, residuals={"reprojection_px": 0.2}
    )
    path = tmp_path / "site" / "calibration.yaml"
    save_calibration(path, CalibrationFile(sensors={"k2_a": entry}))
    loaded = load_calibration(path)
    assert np.abs(loaded.sensors["k2_a"].world_from_optical() - transform).max() < 1e-6
    assert loaded.sensors["k2_a"].clock_offset_s == 0.012
    assert loaded.sensors["k2_a"].as_pose().yaw_deg == pytest.approx(30.0, abs=1e-5)
    assert path.read_text().startswith("# openptrack_py calibration")
    assert [p.name for p in path.parent.iterdir()] == ["calibration.yaml"]  # no temporary left


def test_a_walk_keeps_the_intrinsics_a_checkerboard_solved_and_a_checkerboard_replaces_them() -> (
    None
):
    lens = CameraIntrinsics(width=512, height=424, fx=370.0, fy=375.0, cx=260.0, cy=208.0,
                            distortion=(0.05, -0.01, 0.0, 0.0))  # fmt: skip
    board = SensorCalibration(pose=TRUE, method="checkerboard", intrinsics=lens)
    current = CalibrationFile(sensors={"k2_a": board, "k2_b": board})
    walked = SensorCalibration(pose=TRUE, method="refinement", clock_offset_s=0.01)
    after = current.replaced({"k2_a": walked})
    assert after.sensors["k2_a"].intrinsics == lens  # its detections were made through it
    assert (
        after.sensors["k2_a"].clock_offset_s == 0.01
        and after.sensors["k2_a"].method == "refinement"
    )
    assert after.sensors["k2_a"].camera() == Intrinsics(
        512, 424, 370.0, 375.0, 260.0, 208.0, 0.05, -0.01
    )
    plain = SensorCalibration(pose=TRUE, method="checkerboard")
    assert current.replaced({"k2_b": plain}).sensors["k2_b"].intrinsics is None
    assert current.sensors["k2_a"].method == "checkerboard"  # the original is unchanged


def test_a_cameras_five_factory_lens_terms_reach_the_detector() -> None:
    # a Kinect v2 infrared camera's factory terms (k1, k2, p1, p2, k3), as libfreenect2
    # reports them: k3 is not 0
    factory = (0.0905, -0.2706, 0.0012, -0.0008, 0.0967)
    lens = CameraIntrinsics(width=512, height=424, fx=365.0, fy=365.0, cx=256.0, cy=212.0,
                            distortion=factory)  # fmt: skip
    camera = SensorCalibration(pose=TRUE, intrinsics=lens).camera()
    assert camera == Intrinsics(512, 424, 365.0, 365.0, 256.0, 212.0, *factory)
    assert camera.distortion == factory
    short = lens.model_copy(update={"distortion": (0.0905, -0.2706)})  # k1, k2 only
    assert SensorCalibration(pose=TRUE, intrinsics=short).camera().distortion == (
        0.0905, -0.2706, 0.0, 0.0, 0.0
    )  # fmt: skip


def test_lens_terms_the_detector_does_not_model_are_refused_not_dropped() -> None:
    # OpenCV's rational model: k4 (the sixth term) is not 0
    rational = (0.0905, -0.2706, 0.0, 0.0, 0.0967, 0.02, 0.0, 0.0)
    lens = CameraIntrinsics(width=512, height=424, fx=365.0, fy=365.0, cx=256.0, cy=212.0,
                            distortion=rational)  # fmt: skip
    entry = SensorCalibration(pose=TRUE, intrinsics=lens)
    with pytest.raises(ConfigError, match=r"intrinsics\.distortion: the detector models k1, k2"):
        entry.camera()
    zeros_after = lens.model_copy(update={"distortion": (*rational[:5], 0.0, 0.0, 0.0)})
    assert SensorCalibration(pose=TRUE, intrinsics=zeros_after).camera().k3 == 0.0967


def test_a_hand_written_pose_is_the_same_as_its_matrix() -> None:
    by_pose = SensorCalibration(pose=TRUE)
    by_matrix = SensorCalibration.from_transform(world_from_optical(TRUE))
    assert np.allclose(by_pose.world_from_optical(), by_matrix.world_from_optical(), atol=1e-6)


@pytest.mark.parametrize(
    ("entry", "words"),
    [
        (
            {"rotation": [[1, 0, 0], [0, 1, 0], [0, 0.1, 1]], "translation": [0, 0, 2]},
            ["sensors.k2_a", "not orthonormal"],
        ),
        (
            {"rotation": [[-1, 0, 0], [0, 1, 0], [0, 0, 1]], "translation": [0, 0, 2]},
            ["sensors.k2_a", "reflection"],
        ),
        ({"rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}, ["sensors.k2_a", "translation"]),
        ({"pose": {"x": 1}, "translation": [0, 0, 1]}, ["sensors.k2_a", "not both"]),
        ({"pose": {"x": 1}, "method": "guess"}, ["sensors.k2_a.method", "checkerboard"]),
        ({"pose": {"x": 1}, "clock_offset_s": float("nan")}, ["sensors.k2_a.clock_offset_s"]),
        ({"pose": {"x": 1}, "floor": [0, 0, 0, 2]}, ["sensors.k2_a", "normal"]),
    ],
)
def test_bad_entries_are_named_in_one_message(tmp_path: Path, entry: dict, words: list) -> None:
    path = _write(tmp_path / "c.yaml", {"sensors": {"k2_a": entry}})
    with pytest.raises(CalibrationError) as info:
        load_calibration(path)
    for word in words:
        assert word in str(info.value), str(info.value)


def test_a_file_naming_an_unknown_sensor_is_refused(tmp_path: Path) -> None:
    network = _network(tmp_path, {"k2_a": {"pose": {"x": 1}}, "k9": {"pose": {"x": 2}}})
    with pytest.raises(
        CalibrationError, match=r"unknown sensor 'k9' \(the network's sensors: k2_a\)"
    ):
        network_calibration(network)


def test_a_sensor_pointing_to_a_file_without_its_entry_is_refused(tmp_path: Path) -> None:
    path = _write(tmp_path / "other.yaml", {"sensors": {}})
    network = NetworkConfig(sensors=[SensorConfig(id="k2_a", source="camera", calibration=path)])
    with pytest.raises(
        CalibrationError, match=r"sensors.k2_a.calibration: .* no entry for 'k2_a'"
    ):
        network_calibration(network)


def test_the_calibration_wins_over_the_pose(tmp_path: Path) -> None:
    moved = TRUE.model_copy(update={"x": 2.0})
    network = _network(tmp_path, {"k2_a": {"pose": moved.model_dump()}})
    assert believed_poses(network)["k2_a"][0, 3] == pytest.approx(2.0)


def test_bus_payloads_round_trip_and_garbage_is_refused() -> None:
    entry = SensorCalibration(pose=TRUE, clock_offset_s=0.01)
    sensor, back = parse_entry_payload(entry_payload("k2_a", entry))
    assert sensor == "k2_a" and back == entry
    for bad in (b"{", b"[]", b'{"sensor_id": "k2_a", "entry": {"pose": {"x": "a"}}}'):
        with pytest.raises(CalibrationError):
            parse_entry_payload(bad)


def test_a_simulated_sensor_reports_through_its_calibration(tmp_path: Path) -> None:
    """Placed with a 40 cm, 8 degree error, corrected by a calibration of its true pose."""
    sensors = [
        SensorConfig(
            id="k2_a",
            pose=Pose(x=0.5, y=3.0, z=2.6, yaw_deg=0.0, pitch_deg=20.0),
            pose_error=PoseError(dx=0.3, dy=-0.27, dyaw_deg=8.0),
            clock_offset_s=0.25,
        )
    ]
    truth = SensorCalibration(pose=sensors[0].pose, clock_offset_s=0.25)

    def errors(calibration: dict | None) -> tuple[float, float]:
        scenario = build_scenario(
            "crowd", seed=2, duration_s=3.0, sensors=sensors, calibration=calibration
        )
        sim = Simulator(scenario)
        gaps: list[float] = []
        skew = 0.0
        truth_at: dict[float, dict[int, np.ndarray]] = {}
        for event in sim.events():
            frame = getattr(event, "frame", None)
            if frame is not None and hasattr(frame, "people"):
                truth_at[frame.stamp] = {p.id: np.array([p.x, p.y]) for p in frame.people}
            if hasattr(event, "batch"):
                skew = max(skew, abs(event.batch.stamp - event.capture_time))
                for det, pid in zip(event.batch.detections, event.person_ids, strict=True):
                    if pid > 0 and truth_at:
                        stamp = min(truth_at, key=lambda s: abs(s - event.capture_time))
                        if pid in truth_at[stamp] and abs(stamp - event.capture_time) < 0.02:
                            where = np.array([det.x, det.y])
                            gaps.append(float(np.linalg.norm(where - truth_at[stamp][pid])))
        assert len(gaps) > 50
        return float(np.mean(gaps)), skew

    off, skew_off = errors(None)
    on, skew_on = errors({"k2_a": truth})
    assert off > 0.3 and skew_off == pytest.approx(0.25, abs=1e-9)
    assert on < 0.06 and skew_on < 1e-9
    assert math.isfinite(on)


def test_the_documented_example_file_is_valid() -> None:
    """The calibration file shown in ``docs/calibration.md`` passes its own validation
    (its rotation was once rounded to 3 decimals, 1.2e-3 from orthonormal)."""
    text = (Path(__file__).parents[2] / "docs" / "calibration.md").read_text(encoding="utf-8")
    example = re.search(r"```yaml\n(.*?)```", text, re.S)
    assert example is not None
    entries = CalibrationFile.model_validate(yaml.safe_load(example.group(1))).sensors
    assert entries["k2_a"].camera().distortion == (0.0905, -0.2706, 0.0, 0.0, 0.0967)
    assert entries["k2_b"].camera() is None
