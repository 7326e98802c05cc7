"""The moving-average smoother in front of the sinks, against hand-computed oracles."""

from __future__ import annotations

import math

import pytest

from openptrack_py.messages.track import Track, TrackBatch, Visibility
from openptrack_py.output.smoothing import MovingAverageSmoother


def _track(
    ident: int, x: float, y: float, visibility: Visibility = Visibility.VISIBLE, **kw: float
) -> Track:
    fields = {"z": 0.9, "height": 1.7, "vx": 0.0, "vy": 0.0, "age": 1.0, "confidence": 0.9}
    return Track(ident, x, y, **{**fields, **kw}, visibility=visibility)


def _push(s: MovingAverageSmoother, now: float, *tracks: Track, alive: tuple = ()) -> None:
    s.push(TrackBatch(now, 0, "world", tracks, alive or tuple(t.id for t in tracks), 9), now)


def test_moving_average_of_a_constant_is_that_constant() -> None:
    s = MovingAverageSmoother(window_size=5, position_lifetime_s=10, track_lifetime_s=10)
    for i in range(12):
        _push(s, i * 0.1, _track(1, 1.1, -2.7))
        out = s.frame(i * 0.1 + 0.05)
        (t,) = out.tracks
        assert (t.x, t.y) == (pytest.approx(1.1, abs=1e-12), pytest.approx(-2.7, abs=1e-12))
    assert out.seq == 12 and out.frame_id == "world" and out.stamp == pytest.approx(1.15)


def test_only_visible_positions_enter_the_window() -> None:
    s = MovingAverageSmoother(window_size=10, position_lifetime_s=10, track_lifetime_s=10)
    _push(s, 0.0, _track(1, 1.0, 1.0, Visibility.NOT_VISIBLE))
    _push(s, 0.0, _track(2, 5.0, 5.0, Visibility.OCCLUDED))
    assert s.frame(0.1).tracks == ()  # never measured: not output at all
    _push(s, 1.0, _track(1, 2.0, 4.0))
    _push(s, 1.1, _track(1, 4.0, 8.0))
    _push(s, 1.2, _track(1, 100.0, 100.0, Visibility.NOT_VISIBLE))  # prediction: ignored
    _push(s, 1.3, _track(1, -50.0, 9.0, Visibility.OCCLUDED))  # prediction: ignored
    (t,) = s.frame(1.35).tracks
    assert (t.x, t.y) == (3.0, 6.0)
    assert t.visibility == Visibility.OCCLUDED  # the other fields are the latest ones
    _push(s, 1.4, _track(1, 6.0, 0.0))
    (t,) = s.frame(1.45).tracks
    assert (t.x, t.y) == (4.0, 4.0)


def test_a_track_leaves_exactly_track_lifetime_after_its_last_measurement() -> None:
    s = MovingAverageSmoother(window_size=5, position_lifetime_s=10, track_lifetime_s=0.5)
    _push(s, 1.0, _track(1, 1.0, 1.0))
    _push(s, 1.25, _track(1, 1.0, 1.0, Visibility.NOT_VISIBLE))  # unseen: no extension
    _push(s, 1.375, _track(1, 1.0, 1.0, Visibility.OCCLUDED))
    assert [t.id for t in s.frame(1.4375).tracks] == [1]
    assert [t.id for t in s.frame(1.5 - 2**-20).tracks] == [1]
    assert s.frame(1.5).tracks == ()  # 1.0 + 0.5, exactly
    _push(s, 1.625, _track(1, 2.0, 2.0))  # seen again later: a new window from scratch
    (t,) = s.frame(1.75).tracks
    assert (t.x, t.y) == (2.0, 2.0)


def test_old_positions_leave_the_window_but_the_newest_stays() -> None:
    s = MovingAverageSmoother(window_size=10, position_lifetime_s=0.5, track_lifetime_s=60)
    _push(s, 0.0, _track(1, 0.0, 0.0))
    _push(s, 0.25, _track(1, 1.0, 2.0))
    _push(s, 0.5, _track(1, 2.0, 4.0))
    assert s.frame(0.5).tracks[0].x == 1.0  # 0.0, 0.25 and 0.5 are all within 0.5 s
    assert s.frame(0.625).tracks[0].x == 1.5  # 0.0 is older than 0.5 s: gone
    (t,) = s.frame(0.875).tracks
    assert (t.x, t.y) == (2.0, 4.0)  # only 0.5 is left
    (t,) = s.frame(30.0).tracks  # all too old, the newest one stays
    assert (t.x, t.y) == (2.0, 4.0)


def test_window_size_bounds_the_window() -> None:
    s = MovingAverageSmoother(window_size=3, position_lifetime_s=60, track_lifetime_s=60)
    for i, x in enumerate([100.0, 1.0, 2.0, 3.0]):
        _push(s, 0.125 * i, _track(1, x, -x))
    (t,) = s.frame(0.5).tracks
    assert (t.x, t.y) == (2.0, -2.0)  # 100 fell out of the window of three
    one = MovingAverageSmoother(window_size=1, position_lifetime_s=60, track_lifetime_s=60)
    _push(one, 0.0, _track(4, 1.0, 1.0))
    _push(one, 0.1, _track(4, 5.0, 7.0))
    assert (one.frame(0.2).tracks[0].x, one.frame(0.2).tracks[0].y) == (5.0, 7.0)


def test_tracks_are_output_sorted_and_independent() -> None:
    s = MovingAverageSmoother(window_size=2, position_lifetime_s=60, track_lifetime_s=60)
    _push(s, 0.0, _track(9, 1.0, 1.0), _track(2, 10.0, 10.0))
    _push(s, 0.1, _track(9, 3.0, 3.0))
    out = s.frame(0.2)
    assert [(t.id, t.x) for t in out.tracks] == [(2, 10.0), (9, 2.0)]


def test_alive_ids_are_exactly_the_ids_published_and_max_id_never_falls() -> None:
    """Heartbeats never list an id no frame showed (a tentative one, a departed one)."""
    s = MovingAverageSmoother(track_lifetime_s=0.25)
    _push(s, 1.0, _track(5, 0.0, 0.0), alive=(5, 6))  # 6: alive in the tracker, not shown
    first = s.frame(1.0)
    assert first.alive_ids == (5,) and first.max_id == 5
    assert s.frame(1.2).alive_ids == (5,)
    gone = s.frame(1.25)  # 0.25 s after its last position: it leaves, from heartbeats too
    assert gone.tracks == () and gone.alive_ids == () and gone.max_id == 5
    _push(s, 2.0, _track(3, 1.0, 1.0))
    back = s.frame(2.0)
    assert back.alive_ids == (3,) and back.max_id == 5


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"window_size": 0}, "window_size"),
        ({"window_size": -3}, "window_size"),
        ({"position_lifetime_s": 0.0}, "position_lifetime_s"),
        ({"track_lifetime_s": -1.0}, "track_lifetime_s"),
        ({"track_lifetime_s": math.nan}, "track_lifetime_s"),
    ],
)
def test_smoother_constructor_errors_name_the_argument(kwargs: dict, name: str) -> None:
    with pytest.raises(ValueError, match=rf"MovingAverageSmoother: {name} must be"):
        MovingAverageSmoother(**kwargs)
