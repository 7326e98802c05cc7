"""What the tracker publishes: the tracks a creative app should see, as messages.

A track is published while it is confirmed (or always, with ``publish_tentative``),
seen within ``publish_unseen_s`` and supported by at least ``publish_min_support`` of
its expected sensor frames. Its confidence is the evidence: the detector's confidence
in its detections, times its support, fading to 0 over ``confidence_decay_s`` unseen.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from openptrack_py.messages.track import Track, Visibility
from openptrack_py.tracking.params import TrackerParams
from openptrack_py.tracking.state import TrackTable


def published_tracks(
    tb: TrackTable,
    t: float,
    params: TrackerParams,
    labels: Callable[[np.ndarray], tuple[list[int | None], list[str | None]]],
) -> list[Track]:
    """The tracks of ``tb`` to publish at time ``t``.

    ``labels``: per published track id, its ``stable_id`` and name (the identity role's).
    """
    unseen = t - tb.last_seen
    shown = (unseen <= params.publish_unseen_s) & (tb.support >= params.publish_min_support)
    if not params.publish_tentative:
        shown &= tb.confirmed
    rows = np.flatnonzero(shown)
    fresh = np.clip(1.0 - unseen[rows] / params.confidence_decay_s, 0.0, 1.0)
    evidence = tb.confidence[rows] * tb.support[rows] * fresh
    stable, names = labels(tb.ids[rows])
    columns = zip(
        tb.ids[rows].tolist(),
        tb.x[rows].tolist(),
        tb.z[rows].tolist(),
        tb.height[rows].tolist(),
        np.maximum(t - tb.first_seen[rows], 0.0).tolist(),
        np.clip(evidence, 0.0, 1.0).tolist(),
        (unseen[rows] <= params.visibility_timeout_s).tolist(),
        tb.confirmed[rows].tolist(),
        stable,
        names,
        strict=True,
    )
    return [
        Track(
            id=ident,
            x=x[0],
            y=x[1],
            z=z,
            height=height,
            vx=x[2],
            vy=x[3],
            age=age,
            confidence=conf,
            visibility=Visibility.VISIBLE if visible else Visibility.NOT_VISIBLE,
            confirmed=confirmed,
            stable_id=stable_id,
            identity=name,
        )
        for ident, x, z, height, age, conf, visible, confirmed, stable_id, name in columns
    ]
