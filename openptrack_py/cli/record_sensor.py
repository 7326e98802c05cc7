"""``openptrack record-sensor``: record a depth source to a folder that replays as a source."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from openptrack_py.cli.common import EXIT_CONFIG

if TYPE_CHECKING:
    from openptrack_py.cli.common import Subparsers


def add_parser(subparsers: Subparsers) -> None:
    """Register ``record-sensor``, its arguments and :func:`run`."""
    p = subparsers.add_parser(
        "record-sensor",
        help="record a depth source (device, .bag, cloud, folder) to a folder of PNGs",
        description="Record the frames of a depth source to OUTDIR as uint16 millimetre "
        "depth PNGs (plus colour and intensity when present), frames.csv and "
        "intrinsics.json, a folder that can be replayed as a source. SOURCE is a folder "
        "(our recordings, TUM RGB-D, or depth PNGs with intrinsics.json), a .pcd/.ply "
        "cloud, a RealSense .bag, realsense[:SERIAL], azure-kinect[:N] or "
        "sim:SCENARIO[:SENSOR] (a rendered simulation: a test recording). A live device "
        "records until --frames, --seconds or Ctrl-C. Exit status 2 when the source "
        "cannot be opened or recorded.",
    )
    p.add_argument("source", help="source spec, e.g. realsense, capture.bag, ./tum_sequence")
    p.add_argument("outdir", type=Path, help="output folder (created; must be empty if it exists)")
    p.add_argument("--frames", type=int, metavar="N", help="stop after N frames")
    p.add_argument(
        "--seconds",
        type=float,
        metavar="S",
        help="stop after S seconds of recording (by the frames' timestamps)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Record until the source ends, ``--frames``, ``--seconds``, Ctrl-C or SIGTERM.

    A signal ends the recording after the frame being read: every frame written stays
    whole and listed in ``frames.csv``.
    """
    from collections.abc import Iterator

    from openptrack_py.detection.frame import Frame
    from openptrack_py.detection.sources import open_source, record_folder
    from openptrack_py.errors import SourceError
    from openptrack_py.runtime.stop import StopRequest, stop_on_signals

    def limited(frames: Iterator[Frame], stop: StopRequest) -> Iterator[Frame]:
        first = None
        for frame in frames:
            first = frame.stamp if first is None else first
            if stop.is_set() or (args.seconds is not None and frame.stamp - first >= args.seconds):
                return
            yield frame

    try:
        from openptrack_py.cli.detect import sim_source

        source = open_source(args.source, extra={"sim": sim_source})
        try:
            with stop_on_signals() as stop:
                frames = limited(source.frames(), stop)
                count = record_folder(frames, args.outdir, max_frames=args.frames)
        finally:
            source.close()
    except SourceError as exc:
        print(f"openptrack record-sensor: {exc}", file=sys.stderr)
        return EXIT_CONFIG
    print(f"recorded {count} frames to {args.outdir}")
    return 0
