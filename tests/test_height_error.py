"""The simulator's error of measured heights: a tilted floor per sensor, the walking gait."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from openptrack_py.errors import ConfigError
from openptrack_py.sim.height_error import STEP_HZ, WALKING_SPEED_M_S, HeightError
from openptrack_py.sim.profiles import IDEAL, REALISTIC


def _error(profile=REALISTIC, seed=0, origin=(0.0, 0.0)) -> HeightError:
    return HeightError(profile, np.array(origin), np.random.default_rng(seed))


def test_a_tilted_floor_errs_in_proportion_to_the_distance_from_the_sensor() -> None:
    err = _error(origin=(1.0, 2.0))
    low, high = (math.tan(math.radians(d)) for d in REALISTIC.floor_tilt_deg)
    assert low <= np.linalg.norm(err.gradient) <= high
    still = np.zeros((3, 2))
    at_sensor, one_m, four_m = err.sample(0.0, np.arange(3), np.array([
        [1.0, 2.0], [1.0, 2.0] + err.gradient / np.linalg.norm(err.gradient),
        [1.0, 2.0] + 4 * err.gradient / np.linalg.norm(err.gradient),
    ]), still)  # fmt: skip
    assert at_sensor == pytest.approx(0.0, abs=1e-12)
    assert four_m == pytest.approx(4 * one_m) and one_m == pytest.approx(
        np.linalg.norm(err.gradient)
    )


def test_walking_people_bob_below_their_standing_height_at_the_step_rate() -> None:
    err = _error()
    err.gradient = np.zeros(2)  # the gait alone
    t = np.arange(0.0, 10.0, 1 / 300)
    walking = np.array(
        [err.sample(s, np.array([7]), np.zeros((1, 2)), np.array([[1.3, 0.0]]))[0] for s in t]
    )
    standing = err.sample(0.0, np.array([7]), np.zeros((1, 2)), np.zeros((1, 2)))
    assert standing == pytest.approx([0.0])
    bob = REALISTIC.gait_bob_m
    assert walking.max() == pytest.approx(0.0, abs=1e-3)
    assert walking.min() == pytest.approx(-2 * bob, abs=1e-3)
    assert walking.mean() == pytest.approx(-bob, abs=1e-3)
    spectrum = np.abs(np.fft.rfft(walking - walking.mean()))
    assert np.fft.rfftfreq(len(t), 1 / 300)[spectrum.argmax()] == pytest.approx(STEP_HZ, abs=0.1)
    slow = err.sample(0.0, np.array([7]), np.zeros((1, 2)), np.array([[WALKING_SPEED_M_S / 2, 0]]))
    full = err.sample(0.0, np.array([7]), np.zeros((1, 2)), np.array([[WALKING_SPEED_M_S, 0]]))
    assert slow == pytest.approx(full / 2)


def test_each_person_bobs_in_their_own_phase_the_same_for_every_sensor() -> None:
    a, b = _error(seed=1), _error(seed=2)
    a.gradient = b.gradient = np.zeros(2)
    ids, pos, vel = np.arange(20), np.zeros((20, 2)), np.tile([1.3, 0.0], (20, 1))
    np.testing.assert_array_equal(a.sample(3.0, ids, pos, vel), b.sample(3.0, ids, pos, vel))
    assert np.ptp(a.sample(3.0, ids, pos, vel)) > REALISTIC.gait_bob_m


def test_the_ideal_profile_has_no_height_error_and_bad_values_are_named() -> None:
    assert IDEAL.floor_tilt_deg == (0.0, 0.0) and IDEAL.gait_bob_m == 0.0
    with pytest.raises(ConfigError, match="floor_tilt_deg"):
        dataclasses.replace(REALISTIC, floor_tilt_deg=(2.0, 1.0))
    with pytest.raises(ConfigError, match="gait_bob_m"):
        dataclasses.replace(REALISTIC, gait_bob_m=-0.1)
