"""The calibration on the bus: served by the master, fetched and followed by sensors.

:class:`CalibrationServer` (the ``calibration`` node, on the tracker's machine) answers
queries on ``opt/<site>/calibration/<sensor>`` with that sensor's entry of the
network's calibration files, watches the files, and when one changes (a refinement
accepted, an edit) validates it and publishes each changed entry on the same key. An
invalid file is refused as a whole: the message names the field, the running
calibration stays as it was.

A sensor's node calls :func:`sensor_entry` once at start: the file when it exists on
that machine, else the master's answer. :class:`CalibrationFollower` then applies every
published update; malformed updates are counted and dropped.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

from openptrack_py.calibration.files import (
    SensorCalibration,
    entry_payload,
    network_calibration,
    parse_entry_payload,
    sensor_calibration_paths,
)
from openptrack_py.config import NetworkConfig
from openptrack_py.errors import CalibrationError
from openptrack_py.runtime.node import Node
from openptrack_py.transport.base import Bus, Closable, Sample
from openptrack_py.transport.keys import SiteKeys

POLL_S = 1.0
"""How often the server looks at its files' modification times."""


def _stamp(path: Path) -> float | None:
    try:
        return path.stat().st_mtime_ns / 1e9
    except OSError:
        return None


class CalibrationServer:
    """Serves a network's calibration and announces its changes.

    Parameters
    ----------
    node : Node
        The node (bus, keys, counters, log, stop flag).
    network : NetworkConfig
        The network: which files, which sensors.

    Raises
    ------
    CalibrationError
        If the files are unusable at start.
    """

    def __init__(self, node: Node, network: NetworkConfig) -> None:
        self.node = node
        self.network = network
        self.paths = sorted(set(sensor_calibration_paths(network).values()))
        self.entries = network_calibration(network)
        self._stamps = {p: _stamp(p) for p in self.paths}

    def answer(self, key: str, _payload: bytes | None) -> bytes | None:
        """The entry of the sensor a query names (its key's last chunk), if any."""
        self.node.counters.inc("queries")
        sensor_id = key.rsplit("/", 1)[-1]
        entry = self.entries.get(sensor_id)
        return None if entry is None else entry_payload(sensor_id, entry)

    def poll(self) -> list[str]:
        """Reload changed files; publish changed entries. Returns the sensors updated."""
        stamps = {p: _stamp(p) for p in self.paths}
        if stamps == self._stamps:
            return []
        self._stamps = stamps
        try:
            fresh = network_calibration(self.network)
        except CalibrationError as exc:
            self.node.counters.inc("calibration_rejected")
            self.node.log.error("calibration refused, keeping the running one: %s", exc)
            return []
        changed = [s for s, e in fresh.items() if self.entries.get(s) != e]
        self.entries = fresh
        for sensor_id in changed:
            payload = entry_payload(sensor_id, fresh[sensor_id])
            self.node.bus.put(self.node.keys.calibration(sensor_id), payload)
            self.node.counters.inc("calibration_updates")
        if changed:
            self.node.log.info("calibration updated", extra={"fields": {"sensors": changed}})
        return changed

    def run(self) -> None:
        """Serve until the node is stopped."""
        served = self.node.bus.serve(self.node.keys.calibration("*"), self.answer)
        files = [str(p) for p in self.paths]
        self.node.log.info(
            "serving calibration",
            extra={"fields": {"sensors": sorted(self.entries), "files": files}},
        )
        try:
            while not self.node.wait(POLL_S):
                self.poll()
        finally:
            served.close()


def fetch_entry(
    bus: Bus, keys: SiteKeys, sensor_id: str, timeout_s: float = 1.0
) -> SensorCalibration | None:
    """Ask the master for a sensor's entry; ``None`` when nobody answers with a valid one."""
    for sample in bus.query(keys.calibration(sensor_id), timeout_s=timeout_s):
        try:
            got, entry = parse_entry_payload(sample.payload)
        except CalibrationError:
            continue
        if got == sensor_id:
            return entry
    return None


def sensor_entry(
    network: NetworkConfig,
    sensor_id: str,
    bus: Bus,
    keys: SiteKeys,
    *,
    wait_s: float = 30.0,
) -> SensorCalibration | None:
    """A sensor's calibration entry at start: from its file, else from the master.

    Parameters
    ----------
    network : NetworkConfig
        The network.
    sensor_id : str
        The sensor.
    bus : Bus
        For asking the master when the file is not on this machine.
    keys : SiteKeys
        The site's keys.
    wait_s : float
        How long to keep asking the master.

    Returns
    -------
    SensorCalibration or None
        None when the sensor has no calibration file at all.

    Raises
    ------
    CalibrationError
        If the file is invalid, or is elsewhere and the master does not answer.
    """
    path = sensor_calibration_paths(network).get(sensor_id)
    if path is None:
        return None
    if path.exists():
        return network_calibration(network).get(sensor_id)
    deadline = time.monotonic() + wait_s
    while True:
        entry = fetch_entry(bus, keys, sensor_id)
        if entry is not None:
            return entry
        if time.monotonic() >= deadline:
            raise CalibrationError(
                f"sensors.{sensor_id}: {path} is not on this machine and nobody answered "
                f"on {keys.calibration(sensor_id)} within {wait_s:g} s (is the network "
                "launched on the master?)"
            )
        time.sleep(0.5)


class CalibrationFollower:
    """Applies a sensor's published calibration updates.

    Parameters
    ----------
    node : Node
        The sensor's node (bus, keys, counters).
    sensor_id : str
        The sensor.
    apply : callable
        Called with each valid new entry (from the bus's thread).
    """

    def __init__(
        self, node: Node, sensor_id: str, apply: Callable[[SensorCalibration], None]
    ) -> None:
        self.node = node
        self.sensor_id = sensor_id
        self._apply = apply
        self._subscription: Closable = node.bus.subscribe(
            node.keys.calibration(sensor_id), self._on_sample
        )

    def _on_sample(self, sample: Sample) -> None:
        try:
            got, entry = parse_entry_payload(sample.payload)
            if got != self.sensor_id:
                raise CalibrationError(f"an entry for {got!r} on {self.sensor_id!r}'s key")
        except CalibrationError as exc:
            self.node.counters.inc("calibration_malformed")
            self.node.bad_input.warning("calibration", f"calibration update dropped: {exc}")
            return
        self._apply(entry)
        self.node.counters.inc("calibration_updates")

    def close(self) -> None:
        """Stop following."""
        self._subscription.close()
