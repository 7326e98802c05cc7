"""The sensor-type table is whole and agrees with every table keyed by type name."""

from __future__ import annotations

import dataclasses
import math
import typing

import pytest

from openptrack_py.config import DetectorConfig, SensorConfig
from openptrack_py.detection.frame import Intrinsics
from openptrack_py.sensor_types import (
    AZURE_KINECT,
    SENSOR_TYPE_NAMES,
    SENSOR_TYPES,
    SensorType,
)
from openptrack_py.sim.render import DEPTH_NOISE
from openptrack_py.sim.sensors import SENSOR_NOISE, SensorNoise

KINDS = list(SENSOR_TYPE_NAMES)


def test_the_table_holds_exactly_the_named_types_in_order() -> None:
    assert list(SENSOR_TYPES) == KINDS
    assert all(SENSOR_TYPES[name].name == name for name in KINDS)


def test_the_config_accepts_exactly_the_table_s_types() -> None:
    annotation = SensorConfig.model_fields["type"].annotation
    assert typing.get_args(annotation) == SENSOR_TYPE_NAMES


@pytest.mark.parametrize("kind", KINDS)
def test_every_type_has_every_fact(kind: str) -> None:
    facts = SENSOR_TYPES[kind]
    for f in dataclasses.fields(SensorType):
        value = getattr(facts, f.name)
        if f.name == "live_input":
            assert value is None or (isinstance(value, str) and value)
        elif isinstance(value, bool):
            continue
        elif isinstance(value, (int, float)):
            assert math.isfinite(value) and value > 0, f.name
    assert 0 < facts.min_range_m < facts.reliable_range_m <= facts.max_range_m
    assert facts.detector_max_distance_m <= facts.max_range_m
    assert 0 < facts.hfov_deg < 180 and 0 < facts.vfov_deg < 180


@pytest.mark.parametrize("kind", KINDS)
def test_intrinsics_match_the_field_of_view(kind: str) -> None:
    facts = SENSOR_TYPES[kind]
    fx, fy, cx, cy = facts.intrinsics
    assert math.degrees(2 * math.atan(facts.width / 2 / fx)) == pytest.approx(facts.hfov_deg)
    assert math.degrees(2 * math.atan(facts.height / 2 / fy)) == pytest.approx(facts.vfov_deg)
    assert (cx, cy) == ((facts.width - 1) / 2, (facts.height - 1) / 2)
    k = Intrinsics.for_sensor(kind)
    assert (k.width, k.height) == (facts.width, facts.height)
    assert (k.fx, k.fy, k.cx, k.cy) == facts.intrinsics


def test_the_simulator_s_noise_tables_cover_exactly_the_same_types() -> None:
    assert list(SENSOR_NOISE) == KINDS
    assert list(DEPTH_NOISE) == KINDS
    assert all(isinstance(n, SensorNoise) for n in SENSOR_NOISE.values())


@pytest.mark.parametrize("kind", KINDS)
def test_only_time_of_flight_types_render_flying_pixels(kind: str) -> None:
    assert (DEPTH_NOISE[kind].edge_jump_m > 0) == SENSOR_TYPES[kind].time_of_flight


@pytest.mark.parametrize("kind", KINDS)
def test_the_detector_defaults_come_from_the_table(kind: str) -> None:
    facts = SENSOR_TYPES[kind]
    cfg = DetectorConfig()
    assert cfg.max_distance_for(kind) == facts.detector_max_distance_m
    assert cfg.min_points_for(kind) == facts.detector_min_points
    assert cfg.sampling_for(kind, facts.width) == facts.detector_sampling_factor


def test_unknown_types_fall_back_to_generic_detector_defaults() -> None:
    cfg = DetectorConfig()
    assert (cfg.max_distance_for(None), cfg.min_points_for("lidar")) == (10.0, 20)
    assert (cfg.sampling_for(None, 320), cfg.sampling_for(None, 640)) == (1, 2)


def test_azure_kinect_intrinsics_follow_its_field_of_view() -> None:
    fx, fy, cx, cy = AZURE_KINECT.intrinsics_at(1280, 720)
    assert fx == fy == pytest.approx(640.0)  # 90 degrees across
    assert (cx, cy) == (639.5, 359.5)
