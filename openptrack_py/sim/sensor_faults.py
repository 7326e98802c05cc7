"""The per-sensor figures a noise profile implies, drawn once per scenario from its seed.

Calibration error (a believed pose off the true one), clock offset, latency jitter,
frame drops and the base miss probability of each simulated sensor, written into its
:class:`~openptrack_py.sim.sensor_spec.SensorSpec` by
:func:`~openptrack_py.sim.scenarios.build_scenario`, so that the simulator and the
sensor models apply them like a network file's own figures.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from openptrack_py.config import PoseError, SensorConfig
from openptrack_py.sim.profiles import NoiseProfile
from openptrack_py.sim.sensor_spec import SensorSpec


def draw_sensor_faults(
    profile: NoiseProfile,
    specs: Sequence[SensorSpec],
    configs: Sequence[SensorConfig],
    seed: int,
) -> tuple[SensorSpec, ...]:
    """Each sensor's figures under ``profile``, drawn from the scenario ``seed``.

    Calibration error (networks of two or more sensors), clock offset, latency jitter,
    frame drops and the base miss probability; what a sensor's network entry sets
    itself (a non-zero ``pose_error`` or ``clock_offset_s``, a ``miss_probability``)
    is kept. Returns ``specs`` unchanged for a profile without these faults.

    Parameters
    ----------
    profile : NoiseProfile
        The profile.
    specs : sequence of SensorSpec
        The sensors as their network entries describe them.
    configs : sequence of SensorConfig
        Their network entries, in the same order.
    seed : int
        The scenario seed.
    """
    if not profile.sensor_faults:
        return tuple(specs)
    rng = np.random.default_rng([seed, 59])
    networked = len(specs) >= 2
    out = []
    for spec, cfg in zip(specs, configs, strict=True):
        # always the same draws per sensor, whichever apply
        offset = float(rng.uniform(*profile.calibration_offset_m))
        direction = float(rng.uniform(0.0, 2 * math.pi))
        yaw = float(rng.uniform(*profile.calibration_yaw_deg))
        yaw = yaw if rng.random() < 0.5 else -yaw
        clock = float(rng.uniform(-profile.clock_offset_s, profile.clock_offset_s))
        changes: dict[str, object] = {
            "latency_jitter_s": max(spec.latency_jitter_s, profile.latency_jitter_s),
            "frame_drop_probability": max(
                spec.frame_drop_probability, profile.frame_drop_probability
            ),
        }
        if cfg.miss_probability is None:
            changes["miss_probability"] = profile.miss_probability_for(spec.type.name)
        if networked and spec.pose_error == PoseError():
            changes["pose_error"] = PoseError(
                dx=offset * math.cos(direction), dy=offset * math.sin(direction), dyaw_deg=yaw
            )
        if spec.clock_offset_s == 0.0:
            changes["clock_offset_s"] = clock
        out.append(dataclasses.replace(spec, **changes))
    return tuple(out)
