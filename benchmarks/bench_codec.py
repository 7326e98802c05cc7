"""Codec cost per DetectionBatch of 20 detections, against stdlib json as the baseline.

Prints one JSON line: encode/decode microseconds for our orjson codec (with full
validation on decode) and for ``json.dumps``/``json.loads`` of the same dict (no
validation), and the payload size.

Run from the repository root::

    python -m benchmarks.bench_codec
"""

from __future__ import annotations

import json

from benchmarks.common import emit, per_call_us
from openptrack_py.messages import (
    Detection,
    DetectionBatch,
    decode_detection_batch,
    encode_detection_batch,
)


def batch(n: int = 20, extras: bool = False) -> DetectionBatch:
    dets = tuple(
        Detection(
            x=1.0 + 0.37 * i,
            y=2.0 - 0.11 * i,
            z=0.93,
            height=1.71,
            confidence=0.87,
            distance=3.2 + 0.1 * i,
            bbox=(10 * i, 20, 40, 120) if extras else None,
            appearance=tuple(range(16)) if extras else None,
        )
        for i in range(n)
    )
    return DetectionBatch("k2_a", 1234, 1_767_225_600.123, "world", dets)


def main() -> dict[str, object]:
    figures: dict[str, object] = {}
    for label, extras in (("plain", False), ("with_bbox_appearance", True)):
        b = batch(20, extras)
        wire = encode_detection_batch(b)
        as_dict = json.loads(wire)
        ours_enc = per_call_us(lambda b=b: encode_detection_batch(b))
        ours_dec = per_call_us(lambda w=wire: decode_detection_batch(w))
        std_enc = per_call_us(lambda d=as_dict: json.dumps(d, separators=(",", ":")))
        std_dec = per_call_us(lambda w=wire: json.loads(w))
        figures[label] = {
            "bytes": len(wire),
            "encode_us": ours_enc,
            "decode_validate_us": ours_dec,
            "stdlib_json_dumps_us": std_enc,
            "stdlib_json_loads_us": std_dec,
            "encode_speedup_vs_stdlib": round(std_enc / ours_enc, 2),
            "decode_ratio_vs_stdlib_unvalidated": round(ours_dec / std_dec, 2),
        }
    return emit("codec_detection_batch_20", figures)


if __name__ == "__main__":
    main()
