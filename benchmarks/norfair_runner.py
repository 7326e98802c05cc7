"""A plain norfair tracker behind a line protocol, run in norfair's own environment.

norfair pins numpy < 2 and filterpy < 2, which the project cannot share, so the sweep
(:mod:`benchmarks.sweep`) runs this file with the Python of a separate virtual
environment and talks to it over stdin/stdout, one JSON object per line:

* in: ``{"t": stamp, "dets": [[x, y, confidence], ...]}`` for each sensor batch, in the
  order the batches reach the tracker;
* out: ``{"ids": [...], "xy": [[x, y, vx, vy], ...]}``: norfair's initialised tracks
  after that batch.

Configuration, the plain use of norfair on floor points: Euclidean distance with a
0.8 m threshold, a track initialised after 3 matches (``initialization_delay``), lost
after about one second without a match (``hit_counter_max`` in updates: three 30 Hz
sensors give about 90 updates a second), detections below confidence 0.5 ignored
(``detection_threshold``), norfair's default Kalman filter. Velocity comes from the
filter's state, per unit of update: converted to metres per second with the mean time
between updates.

Usage (from the project root, with norfair's environment)::

    /path/to/norfair-env/bin/python benchmarks/norfair_runner.py
"""

from __future__ import annotations

import json
import sys

import numpy as np
from norfair import Detection, Tracker

UPDATES_PER_SECOND = 90.0
DISTANCE_THRESHOLD_M = 0.8


def main() -> int:
    """Track until stdin ends."""
    tracker = Tracker(
        distance_function="euclidean",
        distance_threshold=DISTANCE_THRESHOLD_M,
        hit_counter_max=int(UPDATES_PER_SECOND),
        initialization_delay=3,
        detection_threshold=0.5,
    )
    last_t = None
    mean_dt = 1.0 / UPDATES_PER_SECOND
    for line in sys.stdin:
        msg = json.loads(line)
        t = msg["t"]
        if last_t is not None and t > last_t:
            mean_dt = 0.98 * mean_dt + 0.02 * (t - last_t)
        last_t = t
        dets = [
            Detection(points=np.array([[x, y]]), scores=np.array([conf]))
            for x, y, conf in msg["dets"]
        ]
        objects = tracker.update(detections=dets)
        ids, rows = [], []
        for obj in objects:
            x, y = obj.estimate[0]
            vel = obj.filter.x[2:4, 0] / mean_dt if obj.filter.x.shape[0] >= 4 else (0.0, 0.0)
            ids.append(int(obj.id))
            rows.append([float(x), float(y), float(vel[0]), float(vel[1])])
        sys.stdout.write(json.dumps({"ids": ids, "xy": rows}) + "\n")
        sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
