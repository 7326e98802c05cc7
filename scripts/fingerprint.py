"""Output fingerprints: proof that a change which should not change behaviour did not.

Hashes, per item, of everything the system computes from fixed inputs:

* ``tracks/<scenario>``: every TrackBatch the default tracker publishes on a scenario
  (seed 0, detection-level sensor model), encoded with the internal codec;
* ``rgbd/<scenario>``: the same through rendered depth and the real detector;
* ``detector/<scenario>/<type>``: ``evaluate_detector``'s figures (every error, count
  and per-sensor figure, timings left out);
* ``wire/*``: the bytes of fixed messages in every wire format (internal codec,
  OpenPTrack UDP JSON v1/v2, OSC).

Run it before and after a change and compare::

    python scripts/fingerprint.py > before.json
    ...change...
    python scripts/fingerprint.py > after.json && diff before.json after.json

``--profile`` selects the simulator noise profile where the code has one.
"""

from __future__ import annotations

import argparse
import hashlib
import importlib
import json
import sys
from dataclasses import dataclass, field

SCENARIOS = {
    "crowd": 40.0,
    "distance": 40.0,
    "occlusions": 40.0,
    "classroom": 40.0,
    "installation": 40.0,
    "stress": 8.0,
}
RGBD = {"installation": 8.0, "crowd": 6.0}
DETECTOR = (("crowd", "kinect2"), ("classroom", "kinect1"), ("installation", "sr4500"))


@dataclass
class _Recording:
    """A pipeline wrapper that hashes every tracks message it produces."""

    pipeline: object
    digest: object = field(default_factory=hashlib.sha256)
    steps: int = 0

    def _take(self, results: list) -> list:
        from openptrack_py.messages.codec import encode_track_batch

        for _batch, tracks in results:
            self.digest.update(encode_track_batch(tracks))
            self.steps += 1
        return results

    def push(self, batch, arrival):
        return self._take(self.pipeline.push(batch, arrival))

    def poll(self, now):
        return self._take(self.pipeline.poll(now))


def _tracks(name: str, duration_s: float, sensor_model: str, extra: dict) -> str:
    from openptrack_py.config import TrackerConfig
    from openptrack_py.eval.runner import TrackerFeed, evaluate
    from openptrack_py.sim.scenarios import build_scenario
    from openptrack_py.tracking import TrackingPipeline

    scenario = build_scenario(name, seed=0, duration_s=duration_s, **extra)
    rec = _Recording(TrackingPipeline.from_config(TrackerConfig()))
    result = evaluate(scenario, TrackerFeed(rec), sensor_model=sensor_model)
    metrics = result.to_dict()
    summary = {k: metrics[k] for k in ("mota", "idf1", "id_switches", "fp", "fn")}
    return f"{rec.digest.hexdigest()[:16]} steps={rec.steps} {json.dumps(summary)}"


def _detector(name: str, sensor_type: str) -> str:
    from openptrack_py.eval.detector import evaluate_detector

    out = evaluate_detector(name, seed=0, sensor_type=sensor_type, duration_s=6.0)

    def strip(d: dict) -> dict:
        return {k: v for k, v in d.items() if not k.startswith("detector_ms")}

    out = strip(out)
    out["sensors"] = {k: strip(v) for k, v in out["sensors"].items()}
    text = json.dumps(out, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _first(module: str, *names: str):
    mod = importlib.import_module(module)
    for name in names:
        if hasattr(mod, name):
            return getattr(mod, name)
    raise AttributeError(f"{module} has none of {names}")


def _wire() -> dict[str, str]:
    from openptrack_py.messages.detection import Detection, DetectionBatch
    from openptrack_py.messages.track import Heartbeat, Track, TrackBatch, Visibility
    from openptrack_py.output import opt_json, osc

    codec = "openptrack_py.messages.codec"
    dets = DetectionBatch(
        sensor_id="k2_a",
        seq=7,
        stamp=1_767_225_600.123456,
        frame_id="world",
        detections=(
            Detection(x=1.25, y=-0.5, z=0.9, height=1.71, confidence=0.875, distance=3.2),
            Detection(x=0.1, y=2.0, z=0.6, height=1.2, confidence=0.5, distance=4.0),
        ),
    )
    tracks = (
        Track(1, 1.0, 2.0, 0.9, 1.7, 0.3, -0.1, 4.5, 0.9),
        Track(12, -3.25, 0.5, 0.8, 1.1, 0.0, 0.0, 0.25, 0.6, Visibility.NOT_VISIBLE, True,
              10012, "Ada"),
    )  # fmt: skip
    batch = TrackBatch(1_767_225_600.5, 42, "world", tracks, (1, 12, 13), 13)
    heartbeat_zenoh = _first(codec, "encode_heartbeat", "encode_alive_heartbeat")
    heartbeat_udp = _first(
        "openptrack_py.output.opt_json", "encode_opt_heartbeat", "encode_heartbeat"
    )
    parts = {
        "codec.detections": _first(codec, "encode_detection_batch")(dets),
        "codec.tracks": _first(codec, "encode_track_batch")(batch),
        "codec.heartbeat": heartbeat_zenoh(Heartbeat(1_767_225_600.25, 3, (1, 12), 12)),
        "udp.v2": b"|".join(opt_json.encode_tracks(tracks, seq=42, stamp=batch.stamp)),
        "udp.v1": b"|".join(
            opt_json.encode_tracks(tracks, seq=42, stamp=batch.stamp, fmt="opt-v1")
        ),
        "udp.heartbeat": heartbeat_udp([1, 12], 13, seq=5, stamp=batch.stamp),
        "osc.bundle": osc.build_bundle(batch, 42),
    }
    return {f"wire/{k}": hashlib.sha256(v).hexdigest()[:16] for k, v in parts.items()}


def main(argv: list[str] | None = None) -> int:
    """Print the fingerprints as JSON, one key per item."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="tracks and wire only")
    parser.add_argument("--profile", default=None, help="simulator noise profile")
    args = parser.parse_args(argv)
    extra = {} if args.profile is None else {"profile": args.profile}
    out: dict[str, str] = {}
    for name, duration in SCENARIOS.items():
        out[f"tracks/{name}"] = _tracks(name, duration, "detections", extra)
        print(f"tracks/{name} done", file=sys.stderr)
    out.update(_wire())
    if not args.quick:
        for name, duration in RGBD.items():
            out[f"rgbd/{name}"] = _tracks(name, duration, "rgbd", extra)
            print(f"rgbd/{name} done", file=sys.stderr)
        for name, kind in DETECTOR:
            out[f"detector/{name}/{kind}"] = _detector(name, kind)
            print(f"detector/{name}/{kind} done", file=sys.stderr)
    json.dump(out, sys.stdout, indent=1, sort_keys=True)
    print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
