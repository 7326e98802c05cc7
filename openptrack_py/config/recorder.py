"""The ``recorder`` section: which messages the recorder node writes, and where."""

from __future__ import annotations

from pathlib import Path

from pydantic import Field

from openptrack_py.config.base import StrictModel


class RecorderConfig(StrictModel):
    """A recorder node: writes every message on ``keys`` to an MCAP or JSON-lines file.

    Parameters
    ----------
    host : str
        Machine that runs the recorder.
    path : Path
        Output file: ``.mcap`` (what Foxglove and the ``mcap`` tools open; schemas,
        metadata, compressed) or ``.jsonl``; a timestamp is inserted before the suffix
        if it exists.
    keys : list of str
        Key expressions below ``opt/<site>/`` to record: detections, tracks, ground
        truth, calibration entries and every node's stats by default.
    """

    host: str = "localhost"
    path: Path = Path("recordings/run.mcap")
    keys: list[str] = Field(
        default_factory=lambda: [
            "detections/**", "tracks", "ground_truth", "calibration/*", "stats/*",
        ]
    )  # fmt: skip
