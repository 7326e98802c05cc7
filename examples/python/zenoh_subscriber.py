#!/usr/bin/env python3
"""Print the smoothed tracks an openptrack_py output node republishes on Zenoh.

Subscribes to ``opt/<site>/tracks/smoothed`` (the output node's fixed-rate frames, with
every field of a track: position, velocity, height, age, confidence, visibility,
identity) and prints one line per frame. Needs openptrack_py installed, or at least on
``PYTHONPATH``::

    python zenoh_subscriber.py                           # the demo hub, tcp/127.0.0.1:7447
    python zenoh_subscriber.py -e tcp/192.168.1.10:7447 --site lab --count 100 --json
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
from typing import Any

from openptrack_py.cli.streams import separate_native_stdout
from openptrack_py.config import ZenohConfig
from openptrack_py.errors import OptError
from openptrack_py.messages import TrackBatch, decode_track_batch
from openptrack_py.transport.keys import SiteKeys
from openptrack_py.transport.zenoh_bus import ZenohBus


def as_record(batch: TrackBatch) -> dict[str, Any]:
    """A frame as plain JSON-ready data."""
    return {
        "seq": batch.seq,
        "stamp": batch.stamp,
        "frame_id": batch.frame_id,
        "tracks": [
            {
                "id": t.id,
                "x": t.x,
                "y": t.y,
                "z": t.z,
                "height": t.height,
                "vx": t.vx,
                "vy": t.vy,
                "age": t.age,
                "confidence": t.confidence,
                "visibility": int(t.visibility),
                "stable_id": t.stable_id,
                "identity": t.identity,
            }
            for t in batch.tracks
        ],
        "alive_ids": list(batch.alive_ids),
        "max_id": batch.max_id,
    }


def describe(batch: TrackBatch) -> str:
    """One human-readable line for a frame."""
    people = " | ".join(f"{t.id} ({t.x:.2f}, {t.y:.2f}) h={t.height:.2f}" for t in batch.tracks)
    line = f"seq={batch.seq} tracks={len(batch.tracks)} alive={len(batch.alive_ids)}"
    return f"{line} | {people}" if people else line


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "-e",
        "--connect",
        action="append",
        metavar="ENDPOINT",
        help="Zenoh endpoint to connect to (repeatable; default tcp/127.0.0.1:7447)",
    )
    parser.add_argument("--site", default="default", help="site name (default 'default')")
    parser.add_argument("--count", type=int, default=0, help="exit after N frames (0: never)")
    parser.add_argument("--json", action="store_true", help="print each frame as a JSON line")
    parser.add_argument(
        "--multicast-scouting", action="store_true", help="also discover peers by UDP multicast"
    )
    args = parser.parse_args(argv)

    key = SiteKeys(args.site).tracks_smoothed
    cfg = ZenohConfig(
        hub=None,
        connect=args.connect or ["tcp/127.0.0.1:7447"],
        listen=[],
        multicast_scouting=args.multicast_scouting,
    )
    done = threading.Event()
    lock = threading.Lock()
    state = {"frames": 0, "bad": 0}

    def on_sample(sample: Any) -> None:  # runs on Zenoh's thread
        try:
            batch = decode_track_batch(sample.payload)
        except OptError as exc:
            with lock:
                state["bad"] += 1
                if state["bad"] == 1 or state["bad"] % 100 == 0:
                    print(f"zenoh_subscriber: bad message ({exc})", file=sys.stderr, flush=True)
            return
        with lock:
            if done.is_set():
                return
            text = json.dumps(as_record(batch)) if args.json else describe(batch)
            print(text, flush=True)
            state["frames"] += 1
            if 0 < args.count <= state["frames"]:
                done.set()

    try:
        bus = ZenohBus(cfg)
    except OptError as exc:
        print(f"zenoh_subscriber: {exc}", file=sys.stderr)
        return 2
    try:
        bus.subscribe(key, on_sample)
        print(f"subscribed to {key} via {', '.join(cfg.connect)}", file=sys.stderr, flush=True)
        while not done.wait(0.2):
            pass
    except KeyboardInterrupt:
        pass
    finally:
        bus.close()
    return 0


if __name__ == "__main__":
    # Zenoh writes its own log lines to descriptor 1; as in the openptrack command, they
    # go to stderr so they never break the JSON lines a reader parses.
    separate_native_stdout()
    sys.exit(main())
