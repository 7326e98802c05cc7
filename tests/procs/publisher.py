"""Test process: publish detection batches (and optionally malformed bytes) over Zenoh.

Usage: python -m tests.procs.publisher --connect ENDPOINT [--count N] [--malformed]
Waits for a matching subscriber, then publishes, then exits 0 (3 if nobody subscribed).
"""

from __future__ import annotations

import argparse
import sys

import orjson

from openptrack_py.config import ZenohConfig
from openptrack_py.messages import Detection, DetectionBatch, encode_detection_batch
from openptrack_py.transport import wait_for_subscribers
from openptrack_py.transport.zenoh_bus import ZenohBus


def batch(seq: int) -> bytes:
    dets = tuple(
        Detection(x=1.0 + i, y=2.0, z=0.9, height=1.7, confidence=0.8, distance=3.0)
        for i in range(seq % 5)
    )
    return encode_detection_batch(
        DetectionBatch(
            sensor_id="k1", seq=seq, stamp=1.7e9 + seq / 30, frame_id="world", detections=dets
        )
    )


def malformed() -> list[bytes]:
    good = orjson.loads(batch(3))
    wrong_type = dict(good, seq="three")
    nan = batch(3).replace(b'"x":1.0', b'"x":NaN')
    huge = b'{"v":1,"kind":"detections","detections":[' + b"0," * (5 * 1024 * 1024) + b"0]}"
    return [batch(3)[:40], orjson.dumps(wrong_type), nan, huge]


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--connect", required=True)
    parser.add_argument("--count", type=int, default=1000)
    parser.add_argument("--malformed", action="store_true")
    args = parser.parse_args()
    cfg = ZenohConfig(hub=None, connect=[args.connect], listen=[], multicast_scouting=False)
    with ZenohBus(cfg) as bus:
        pub = bus.publisher("opt/default/detections/k1", reliable=True)
        if not wait_for_subscribers(pub, timeout_s=20):
            return 3
        if args.malformed:
            for payload in malformed():
                pub.put(payload)
        for seq in range(args.count):
            pub.put(batch(seq))
        print(f"published {args.count}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
