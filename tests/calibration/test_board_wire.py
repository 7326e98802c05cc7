"""Board reports on the wire, and the master's collector of a live board session."""

from __future__ import annotations

import numpy as np
import orjson
import pytest

from openptrack_py.calibration.board_collector import BoardCollector
from openptrack_py.calibration.board_wire import (
    BoardReport,
    decode_board_report,
    encode_board_report,
)
from openptrack_py.calibration.observations import BoardObservation
from openptrack_py.calibration.progress import CalibrationProgress
from openptrack_py.detection.frame import Intrinsics
from openptrack_py.errors import WireFormatError

K = Intrinsics(width=512, height=424, fx=365.0, fy=365.0, cx=256.0, cy=212.0)
CORNERS = np.array([[100.5 + 20 * j, 200.25 + 20 * i] for i in range(5) for j in range(6)])
"""A 5 x 6 board's inner corners (the default board)."""


def _pose(yaw: float = 0.3) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    pose = np.eye(4)
    pose[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    pose[:3, 3] = [0.1, -0.2, 2.5]
    return pose


def _report(sensor: str = "k2_a", stamp: float = 100.0, **kw: object) -> BoardReport:
    return BoardReport(sensor, stamp, **kw)  # type: ignore[arg-type]


def test_every_field_round_trips() -> None:
    view = BoardObservation("k2_a", 99.5, CORNERS + 1, _pose())
    report = _report(corners=CORNERS, view=view, intrinsics=K, board=(5, 6, 0.12), end=True)
    back = decode_board_report(encode_board_report(report))
    assert back.sensor_id == "k2_a" and back.stamp == 100.0 and back.end
    assert back.board == (5, 6, 0.12)
    np.testing.assert_array_equal(back.corners, CORNERS)
    assert back.intrinsics == K
    assert back.view is not None and back.view.stamp == 99.5
    np.testing.assert_array_equal(back.view.corners, CORNERS + 1)
    np.testing.assert_allclose(back.view.camera_from_board, _pose())
    # a camera that reports its lens: its terms travel too (and only then)
    for lens in (
        Intrinsics(512, 424, 365.0, 365.0, 256.0, 212.0, k1=-0.12, k2=0.04),
        Intrinsics(512, 424, 365.0, 365.0, 256.0, 212.0, 0.09, -0.27, 0.001, -0.002, 0.1),
    ):
        wire = decode_board_report(encode_board_report(_report(intrinsics=lens)))
        assert wire.intrinsics == lens
    assert b"k1" not in encode_board_report(report)
    bare = decode_board_report(encode_board_report(_report()))
    assert bare.corners is None and bare.view is None and bare.intrinsics is None
    assert not bare.end


def _camera(**fields: object) -> dict:
    """A camera's intrinsics as a report carries them, with ``fields`` changed or added."""
    return {"width": 512, "height": 424, "fx": 365.0, "fy": 365.0, "cx": 0.0, "cy": 0.0,
            **fields}  # fmt: skip


def _wire(**fields: object) -> bytes:
    obj = orjson.loads(encode_board_report(_report(corners=CORNERS, board=(5, 6, 0.12))))
    obj.update(fields)
    return orjson.dumps(obj)


@pytest.mark.parametrize(
    ("fields", "named"),
    [
        ({"sensor_id": "../x"}, "sensor_id"),
        ({"stamp": float("inf")}, "stamp"),
        ({"corners": [[1.0, 2.0, 3.0]]}, "corners[0]"),
        ({"corners": [[1.0, 1e9]]}, "corners[0]"),
        ({"corners": []}, "corners"),
        ({"corners": [[0.0, 0.0]] * 1001}, "corners"),
        ({"end": 1}, "end"),
        ({"board": [5, 6]}, "board"),
        ({"board": [5, 6, -0.1]}, "board"),
        ({"board": [5.0, 6, 0.1]}, "board"),
        ({"board": [4, 5, 0.1]}, "corners"),  # 30 corners, the board has 20
        (
            {
                "view": {
                    "stamp": 100.0,
                    "corners": [[1.0, 2.0]],
                    "camera_from_board": np.eye(4).ravel().tolist(),
                }
            },
            "view.corners",
        ),
        (
            {
                "view": {
                    "stamp": 1e9,
                    "corners": [[1.0, 2.0]],
                    "camera_from_board": np.eye(4).ravel().tolist(),
                }
            },
            "view.stamp",
        ),
        ({"extra": 1}, "extra"),
        ({"intrinsics": _camera(fx=-1.0, fy=1.0)}, "intrinsics.fx"),
        ({"intrinsics": _camera(k1=1e6)}, "intrinsics.k1"),
        ({"intrinsics": _camera(p2="x")}, "intrinsics.p2"),
        (
            {
                "view": {
                    "stamp": 100.0,
                    "corners": [[1.0, 2.0]],
                    "camera_from_board": [2.0] + [0.0] * 15,
                }
            },
            "view.camera_from_board",
        ),
        (
            {"view": {"stamp": 100.0, "corners": [[1.0, 2.0]], "camera_from_board": [1.0] * 4}},
            "view.camera_from_board",
        ),
    ],
)
def test_a_wrong_field_is_named(fields: dict, named: str) -> None:
    with pytest.raises(WireFormatError, match=named.replace("[", r"\[").replace("]", r"\]")):
        decode_board_report(_wire(**fields))


def test_a_view_must_say_which_board_it_is_of() -> None:
    obj = orjson.loads(_wire())
    del obj["board"]
    obj["view"] = {"stamp": 100.0, "corners": CORNERS.tolist(),
                   "camera_from_board": np.eye(4).ravel().tolist()}  # fmt: skip
    with pytest.raises(WireFormatError, match="board: missing"):
        decode_board_report(orjson.dumps(obj))


def test_a_bad_number_never_reaches_the_wire() -> None:
    with pytest.raises(WireFormatError, match="corners"):
        encode_board_report(_report(corners=np.array([[np.nan, 1.0]])))


def test_collector_gathers_views_intrinsics_and_who_sees_the_board() -> None:
    progress = CalibrationProgress({"k2_a": (512, 424), "k2_b": (512, 424)})
    collector = BoardCollector(["k2_a", "k2_b"], progress, every_s=0.5)
    collector.add(_report("k2_a", 100.0, corners=CORNERS))
    collector.add(_report("k2_b", 100.1))  # does not see it
    assert progress.snapshot().seeing == ("k2_a",)
    view_a = BoardObservation("k2_a", 100.3, CORNERS, _pose())
    collector.add(_report("k2_a", 100.4, corners=CORNERS, view=view_a, intrinsics=K))
    # k2_b's view of the same placement, its clock 0.2 s off; then another placement
    view_b = BoardObservation("k2_b", 100.5, CORNERS, _pose())
    collector.add(_report("k2_b", 100.6, corners=CORNERS, view=view_b, intrinsics=K))
    collector.add(_report("k2_b", 103.0, corners=CORNERS,
                          view=BoardObservation("k2_b", 102.9, CORNERS, _pose())))  # fmt: skip
    snap = progress.snapshot()
    assert snap.views == {"k2_a": 1, "k2_b": 2} and snap.pair_views == {("k2_a", "k2_b"): 1}
    assert snap.seeing == ("k2_b",)  # k2_a last reported 2.6 s before
    assert len(collector.views) == 3 and collector.intrinsics == {"k2_a": K, "k2_b": K}
    assert not collector.finished
    collector.add(_report("k2_a", 104.0, end=True))
    collector.add(_report("k2_b", 104.0, end=True))
    assert collector.finished


def test_live_reports_are_timed_by_arrival() -> None:
    """Sensors replayed at different paces: who sees the board now is who said so last."""
    progress = CalibrationProgress({"k2_a": (512, 424), "k2_b": (512, 424)})
    collector = BoardCollector(["k2_a", "k2_b"], progress, every_s=0.0)
    collector.add(_report("k2_a", 10.0, corners=CORNERS), now=500.0)
    collector.add(_report("k2_b", 95.0, corners=CORNERS), now=500.1)
    assert progress.snapshot().seeing == ("k2_a", "k2_b")


def test_a_view_of_another_board_is_dropped_and_its_sensor_named() -> None:
    collector = BoardCollector(["k2_a", "k2_b"], board=(5, 6, 0.12))
    view = BoardObservation("k2_a", 100.0, CORNERS, _pose())
    collector.add(_report("k2_a", view=view, intrinsics=K, board=(5, 6, 0.10)))
    collector.add(_report("k2_b", view=view, intrinsics=K, board=(5, 6, 0.12)))
    assert collector.other_board == {"k2_a": (5, 6, 0.10)}
    assert collector.counts["other_board"] == 1 and len(collector.views) == 1
    assert collector.reporting == {"k2_a", "k2_b"}


def test_a_flood_of_views_from_one_sensor_is_capped() -> None:
    from openptrack_py.calibration.board_collector import MAX_VIEWS_PER_SENSOR

    collector = BoardCollector(["k2_a"])
    for i in range(MAX_VIEWS_PER_SENSOR + 10):
        view = BoardObservation("k2_a", float(i), CORNERS, _pose())
        collector.add(_report("k2_a", float(i), view=view, intrinsics=K))
    assert len(collector.views) == MAX_VIEWS_PER_SENSOR
    assert collector.counts["too_many_views"] == 10


def test_collector_drops_and_counts_what_it_cannot_trust() -> None:
    progress = CalibrationProgress({"k2_a": (512, 424)})
    collector = BoardCollector(["k2_a"], progress)
    good = encode_board_report(_report("k2_a", corners=CORNERS))
    collector.take("opt/default/board/k2_b", good)  # on another sensor's key
    collector.take("opt/default/board/k2_a", b"{not json")
    collector.take("opt/default/board/zz", encode_board_report(_report("zz")))  # unknown
    collector.take("opt/default/board/k2_a", good)
    assert collector.counts == {"reports": 1, "views": 0, "malformed": 1, "wrong_key": 1,
                                "unknown": 1, "other_board": 0, "too_many_views": 0}  # fmt: skip
    assert progress.snapshot().seeing == ("k2_a",) and progress.snapshot().views == {"k2_a": 0}


def _still_views(monkeypatch: pytest.MonkeyPatch, positions: list[float | None]) -> list:
    """Feed ``StillBoardViews`` 30 Hz frames whose board sits at ``positions`` (pixels
    along u; None: not seen); the views it gives, in order."""
    from types import SimpleNamespace

    import openptrack_py.calibration.capture as capture
    from openptrack_py.calibration.checkerboard import BoardView, Checkerboard

    monkeypatch.setattr(
        capture, "detect_board",
        lambda frame, board, kind: None if frame.u is None
        else BoardView(CORNERS + np.array([frame.u, 0.0]), _pose(), 0.1),
    )  # fmt: skip
    monkeypatch.setattr(capture, "average_views", lambda views, board, k: views[0])
    still = capture.StillBoardViews("k2_a", "kinect2", Checkerboard())
    reports = [
        still.report(SimpleNamespace(stamp=i / 30, intrinsics=K, u=u))
        for i, u in enumerate(positions)
    ]
    reports.append(still.end_report(len(positions) / 30))
    return [(round(r.stamp * 30), r.view) for r in reports if r.view is not None]


def test_a_board_left_still_is_given_once_without_waiting_for_it_to_move(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # held still 3 s (a live camera's last placement never ends by moving), then moved
    views = _still_views(monkeypatch, [10.0] * 90 + [50.0] * 5)
    assert [frame for frame, _ in views] == [30, 95]  # after 1 s; the short run at the end
    assert views[0][1].corners[0, 0] == pytest.approx(CORNERS[0, 0] + 10.0)
    # short still runs (a few frames each) are given when the board moves or is lost
    views = _still_views(monkeypatch, [10.0] * 5 + [20.0] * 2 + [None] + [30.0] * 4)
    assert [frame for frame, _ in views] == [5, 12]  # the 2-frame run is too short
