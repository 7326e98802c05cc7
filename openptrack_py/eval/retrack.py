"""Re-running the tracker offline on a recording, faster than real time.

``openptrack retrack FILE`` takes a recording's detections through a tracker of the
recorded site's settings (the network file kept in the recording's metadata) changed by
``--set``, and writes the new tracks (with the recording's ground truth, if any) to a
recording of their own.

Which batches, in which order: every recorded tracks message names the batch its step
applied and the capture time the tracker used (its ``source``), so the tracker is given
exactly those batches in exactly that order (**as run**): with the same settings it
reproduces the recorded tracks to the bit, whatever the live tracker dropped or
reordered on the way. A recording without tracks messages (or whose steps name no
batch) is taken in order of arrival through the clock alignment and the reorder window,
as a live tracker would (**as arrived**).

The recording is streamed: a detection batch waits for the tracks message that names it
at most :data:`LOOKAHEAD_S` of recorded time, so memory stays flat on hour-long files.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path

from openptrack_py.config import NetworkConfig, TrackerConfig
from openptrack_py.errors import ConfigError, WireFormatError
from openptrack_py.messages.codec import (
    decode_detection_batch,
    decode_track_batch,
    encode_track_batch,
)
from openptrack_py.messages.detection import DetectionBatch
from openptrack_py.messages.track import TrackBatch
from openptrack_py.recordings import RecordedMessage, open_writer, read_recording
from openptrack_py.tracking import TrackingPipeline
from openptrack_py.tracking.factory import build_tracker

__all__ = ["LOOKAHEAD_S", "RetrackResult", "recorded_tracker_config", "retrack"]

LOOKAHEAD_S = 10.0
"""How long (recorded time) a batch is kept for the step that names it."""


@dataclass
class RetrackResult:
    """What :func:`retrack` did.

    Parameters
    ----------
    mode : {"as run", "as arrived"}
        How batches were given to the tracker (see the module).
    steps : int
        Tracker steps taken.
    identical : int or None
        As run: steps whose tracks equal the recorded ones (``None`` as arrived).
    missing : int
        As run: recorded steps whose batch is not in the recording (skipped).
    first_step : int or None
        As run: the recorded tracker's step counter at the first step in the recording
        (1 when the recording holds the tracker's whole run, the only case where
        identical tracks can be expected).
    stopped : str or None
        Where reading stopped early (a damaged recording), if it did.
    output : Path or None
        The recording written.
    truth_frames : int
        Ground-truth frames the recording holds (copied to the output).
    """

    mode: str
    steps: int = 0
    identical: int | None = None
    missing: int = 0
    first_step: int | None = None
    stopped: str | None = None
    output: Path | None = None
    truth_frames: int = 0


def recorded_tracker_config(path: Path, overrides: list[str] | None = None) -> TrackerConfig:
    """The tracker settings a recording was made with (its network), with ``overrides``.

    A recording without them (JSON lines, or recorded outside a network) gives the
    defaults.

    Raises
    ------
    ConfigError
        Naming the override that is not valid.
    """
    from openptrack_py.config import apply_overrides, validate_config

    recording = read_recording(path)
    base: dict = {}
    for _ in recording:  # metadata come first in an MCAP file
        break
    network = recording.metadata.get("network", {}).get("json")
    if network:
        try:
            base = NetworkConfig.model_validate_json(network).tracker.model_dump()
        except ValueError as exc:
            raise ConfigError(f"{path}: the recorded network is not valid ({exc})") from None
    merged = apply_overrides(base, [o.removeprefix("tracker.") for o in overrides or []])
    return validate_config(TrackerConfig, merged, "tracker")


def _has_steps(path: Path) -> bool:
    """Whether the recording's tracks messages name their batches."""
    for message in read_recording(path):
        if message.topic == "tracks":
            try:
                return decode_track_batch(message.payload).source is not None
            except WireFormatError:
                return False
    return False


def retrack(
    path: Path,
    config: TrackerConfig,
    output: Path | None = None,
    on_progress: Callable[[float], None] | None = None,
) -> RetrackResult:
    """Run a tracker of ``config`` on the recording at ``path``.

    Parameters
    ----------
    path : Path
        The recording (MCAP or JSON lines).
    config : TrackerConfig
        The tracker's settings.
    output : Path, optional
        A recording to write: the new tracks (at the recorded times) and the recorded
        ground truth.
    on_progress : callable, optional
        Called with the recorded time of each step or ground-truth frame (for a
        progress bar).

    Returns
    -------
    RetrackResult
    """
    as_run = _has_steps(path)
    result = RetrackResult("as run" if as_run else "as arrived", output=output)
    writer = open_writer(output, {"openptrack": {"retracked": str(path)}}) if output else None
    recording = read_recording(path)
    try:
        steps = _as_run(recording, config, result) if as_run else _as_arrived(recording, config)
        for received, key, out in steps:
            if isinstance(out, TrackBatch):
                result.steps += 1
                out = encode_track_batch(out)
            else:  # the recorded ground truth, passed through
                result.truth_frames += 1
            if writer is not None:
                writer.write(received, key, out)
            if on_progress is not None:
                on_progress(received)
    finally:
        if writer is not None:
            writer.close()
    result.stopped = recording.stopped
    return result


def _tracks_key(message: RecordedMessage) -> str:
    return f"opt/{message.site}/tracks"


def _as_run(
    recording: Iterator[RecordedMessage], config: TrackerConfig, result: RetrackResult
) -> Iterator[tuple[float, str, TrackBatch | bytes]]:
    """The recorded steps again, and the ground truth as recorded.

    Each step takes the batch it names, at the stamp the tracker used.
    """
    tracker = build_tracker(config)
    waiting: OrderedDict[tuple[str, int], tuple[float, DetectionBatch]] = OrderedDict()
    pending: list[tuple[RecordedMessage, TrackBatch]] = []
    result.identical = 0
    for message in recording:
        if message.topic.startswith("detections/"):
            batch = decode_detection_batch(message.payload)
            waiting[(batch.sensor_id, batch.seq)] = (message.received, batch)
        elif message.topic == "tracks":
            recorded = decode_track_batch(message.payload)
            if recorded.source is not None:
                pending.append((message, recorded))
                if result.first_step is None:
                    result.first_step = recorded.seq
        elif message.topic == "ground_truth":
            yield message.received, message.key, message.payload
        # a step whose batch has not come yet waits (the recorder may receive the
        # tracks before the batch); a batch nobody named goes after LOOKAHEAD_S
        while pending:
            step_message, recorded = pending[0]
            sensor, seq, stamp = recorded.source  # type: ignore[misc]
            found = waiting.pop((sensor, seq), None)
            if found is None and message.received - step_message.received < LOOKAHEAD_S:
                break
            pending.pop(0)
            if found is None:
                result.missing += 1
                continue
            tracker.frame_id = recorded.frame_id
            out = tracker.step(replace(found[1], stamp=stamp))
            out = replace(out, seq=recorded.seq)
            result.identical += int(out == recorded)
            yield step_message.received, _tracks_key(step_message), out
        while waiting and message.received - next(iter(waiting.values()))[0] > LOOKAHEAD_S:
            waiting.popitem(last=False)
    result.missing += len(pending)


def _as_arrived(
    recording: Iterator[RecordedMessage], config: TrackerConfig
) -> Iterator[tuple[float, str, TrackBatch | bytes]]:
    """Batches through alignment and the reorder window, and the ground truth as recorded.

    Batches go in their order of arrival, as a live tracker takes them.
    """
    pipeline = TrackingPipeline.from_config(config)
    key = None
    for message in recording:
        if message.topic == "ground_truth":
            yield message.received, message.key, message.payload
        if not message.topic.startswith("detections/"):
            continue
        key = _tracks_key(message)
        batch = decode_detection_batch(message.payload)
        for _, out in pipeline.push(batch, message.received):
            yield message.received, key, out
    for _, out in pipeline.flush():
        yield out.stamp, key or "opt/default/tracks", out
