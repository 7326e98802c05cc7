"""The tracker's roles, one small interface each.

:class:`~openptrack_py.tracking.tracker.Tracker` composes one object per role and
depends only on these protocols, so a role can be swapped (a stub in a test, another
gate, another identity model) without touching the tracker:

=================  ===================================================  ==============
role               verb                                                 default
=================  ===================================================  ==============
motion             ``fx`` / ``noise``: propagate a state over ``dt``     ConstantVelocity
measurement        ``pair_measurements``: what a detection measures      PositionMeasurement
gater              ``gate``: which track-detection pairs are admissible  ChiSquareGater
associator         ``associate``: one-to-one pairs of least cost         GlobalNearestNeighbour
initiator          ``initiate`` / ``confirm``: births and confirmation   ConfidenceInitiator
deleter            ``delete``: which tracks end                          TimeDeleter
sensors            ``correct`` / ``noise_scale`` / ``covers`` / ``learn``: OnlineSensorModel
                   what is learned about each sensor
merger             ``observe`` / ``merge`` / ``reattach`` /              TrackMerger
                   ``distinct_rows``: one person, one track
identity           ``cost`` / ``observe`` / ``distinct`` / ``labels``:    NullIdentity
                   who a track is
=================  ===================================================  ==============

Per-track state lives in one of two places, both restored by the tracker's late-batch
replay (:mod:`openptrack_py.tracking.replay`): the columns of
:class:`~openptrack_py.tracking.state.TrackTable`, or a role's own state exposed through
:class:`Stateful` (``snapshot`` / ``restore``). A role that keeps state anywhere else
would silently diverge on replay; ``tests/test_tracker_roles.py`` checks that a stateful
role survives one.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np

from openptrack_py.tracking.sensor_model import SensorUpdates
from openptrack_py.tracking.state import DetectionArrays, TrackTable


class MotionModel(Protocol):
    """How a track's state ``[x, y, vx, vy]`` evolves between two steps."""

    def fx(self, sigmas: np.ndarray, dt: np.ndarray) -> np.ndarray:
        """Move sigma points ``(N, k, 4)`` forward by ``dt (N,)`` seconds."""

    def noise(self, dt: np.ndarray) -> np.ndarray:
        """Process noise ``(N, 4, 4)`` accumulated over steps ``dt (N,)``."""


class MeasurementModel(Protocol):
    """What a detection measures of a track's state, and how noisy that is."""

    dim: int
    """Measurement dimension (the gate's degrees of freedom)."""

    def hx(self, sigmas: np.ndarray) -> np.ndarray:
        """Predicted measurements ``(N, k, dim)`` of sigma points ``(N, k, 4)``."""

    def pair_measurements(
        self, dets: DetectionArrays, table: TrackTable, t: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Measurement ``(N, M, dim)`` and noise ``(N, M, dim, dim)`` of every pair.

        A measurement may depend on the track (e.g. a velocity derived from its past),
        hence one per pair.
        """

    def position_noise(self, distance: np.ndarray) -> np.ndarray:
        """Floor-position noise ``(M, 2, 2)`` of detections at ``distance (M,)`` metres.

        Sets a new track's initial position uncertainty.
        """


class Gater(Protocol):
    """Admits track-detection pairs whose distance is plausible."""

    dof: int
    """Degrees of freedom the gate is built for (must equal the measurement's)."""
    threshold: float
    """The largest admissible squared distance."""

    def gate(self, d2: np.ndarray) -> np.ndarray:
        """Boolean mask of admissible pairs from squared Mahalanobis distances ``d2``."""


class Associator(Protocol):
    """Chooses one-to-one track-detection pairs."""

    def associate(self, cost: np.ndarray, allowed: np.ndarray) -> list[tuple[int, int]]:
        """Pairs ``(track_row, detection_column)`` among ``allowed`` ones."""


class Initiator(Protocol):
    """Decides which detections start tracks and when a track is confirmed."""

    def initiate(self, dets: DetectionArrays, assigned: np.ndarray, d2: np.ndarray) -> np.ndarray:
        """Indices of the detections that start new (tentative) tracks.

        ``d2 (n_tracks, n_detections)``: squared Mahalanobis distances of every pair.
        """

    def confirm(
        self, table: TrackTable, t: float, continuing: np.ndarray | None = None
    ) -> np.ndarray:
        """Confirmation flag of every track after the step at ``t``.

        ``continuing`` marks tracks that continue a lost confirmed track (see
        :meth:`Merger.continuations`): evidence of a person already gathered.
        """


class Deleter(Protocol):
    """Decides which tracks end."""

    def delete(self, table: TrackTable, t: float) -> np.ndarray:
        """Mask of the tracks to delete at time ``t``."""


class SensorModel(Protocol):
    """What the tracker knows and learns about each sensor."""

    def correct(self, dets: DetectionArrays) -> DetectionArrays:
        """The batch's detections with what is known of their sensor's errors removed."""

    def noise_scale(self, sensor_id: str, distance: np.ndarray) -> np.ndarray:
        """Factor on the configured covariance of a sensor's detections at ``distance``."""

    def cross_sensor_var(
        self, sensor_id: str, distance: np.ndarray, last_sensor: np.ndarray, names: list[str]
    ) -> np.ndarray | None:
        """Variance added against tracks another sensor fed, ``(n, m)``; ``None``: none.

        ``last_sensor`` indexes ``names``: the two calibrations' unlearned disagreement.
        """

    def covers(self, sensor_id: str, xy: np.ndarray) -> np.ndarray:
        """Mask of floor positions ``xy (n, 2)`` the sensor is known to see."""

    def hidden(
        self, sensor_id: str, xy: np.ndarray, seen: np.ndarray, twin_m: float
    ) -> np.ndarray:
        """Mask of floor positions ``xy (n, 2)`` hidden from it behind ``xy[seen]``.

        ``seen`` are the rows it detected now; a position within ``twin_m`` of one of
        them is not hidden (it may be that person's second track).
        """

    def clutter_density(self, sensor_id: str) -> float:
        """Detections per frame and square metre no track explains (0: unknown)."""

    def observe_frame(self, sensor_id: str, unexplained: int) -> None:
        """A frame of the sensor left ``unexplained`` detections to no track."""

    def learn(self, updates: SensorUpdates) -> None:
        """Learn from one batch's unambiguous updates of confirmed tracks."""

    def observe_tracks(self, table: TrackTable, t: float, names: list[str]) -> None:
        """Learn from the tracks after a step (``names``: the sensors, by index)."""


class Merger(Protocol):
    """Finds confirmed tracks that follow one person."""

    def observe(
        self,
        table: TrackTable,
        rows: np.ndarray,
        t: float,
        noise: np.ndarray | None = None,
        sensor: int = 0,
        apart: np.ndarray | None = None,
    ) -> None:
        """Tracks ``rows`` were all detected in one frame of ``sensor`` (its slot) at ``t``.

        ``noise`` is each row's measurement covariance ``(len(rows), 2, 2)``; ``apart``
        (a mask over ``rows``, all when ``None``) the rows whose detections prove them
        to be people other than the rest.
        """

    def merge(self, table: TrackTable, t: float) -> list[tuple[int, int]]:
        """Pairs ``(keep_row, drop_row)`` to merge at ``t``."""

    def reattach(
        self, table: TrackTable, t: float, new: np.ndarray, lost_after_s: float
    ) -> list[tuple[int, int]]:
        """Pairs ``(lost_row, new_row)``: a track confirmed now is a lost one seen again."""

    def continuations(self, table: TrackTable, t: float, lost_after_s: float) -> np.ndarray:
        """Mask of tentative tracks that may be a lost, walking person seen again."""

    def distinct_rows(self, table: TrackTable, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Row pairs ``(a, b)`` of tracks known at ``t`` to be two people."""


@runtime_checkable
class Stateful(Protocol):
    """A role that keeps state of its own (e.g. per-track appearance).

    The tracker stores ``snapshot()`` with its own state before each step and hands it
    back to ``restore`` when a late batch makes it replay from there. A snapshot must
    not share mutable objects with the live state.
    """

    def snapshot(self) -> Any:
        """An independent copy of the role's state."""

    def restore(self, state: Any) -> None:
        """Return to a state taken by :meth:`snapshot`."""


class IdentityModel(Protocol):
    """Who each track is: re-ranks candidates, keeps identities, names tracks.

    The identity role can only *re-rank* pairs the gate admitted (its cost is added to
    admissible pairs only); it never admits a pair the gate rejects.
    """

    needs_looks: bool
    """Whether the tracker must read the detections' looks (``DetectionArrays.looks``)."""

    def cost(
        self, table: TrackTable, dets: DetectionArrays, t: float, allowed: np.ndarray
    ) -> np.ndarray | None:
        """Extra cost ``(N, M)`` of the pairs ``allowed`` (others: any), ``None``: no opinion."""

    def observe(
        self,
        table: TrackTable,
        rows: np.ndarray,
        cols: np.ndarray,
        dets: DetectionArrays,
        t: float,
    ) -> None:
        """Tracks ``rows`` were updated with detections ``cols`` at time ``t``.

        ``certain`` marks the pairs motion alone made certain (each the only one in the
        other's gate): what an identity model may learn "same person" from.
        """

    def started(
        self, table: TrackTable, rows: np.ndarray, dets: DetectionArrays, t: float
    ) -> None:
        """Tracks ``rows`` were just started from detections of ``dets``."""

    def ended(
        self, table: TrackTable, rows: np.ndarray, t: float, reason: str = "deleted"
    ) -> None:
        """Tracks ``rows`` are about to be removed at time ``t``.

        ``reason``: ``"deleted"`` (lost), ``"merged"`` (folded into another track),
        ``"reattached"`` (its person continues under an older track's id) or ``"handed
        over"`` (the track goes on under a new id, following someone else).
        """

    def handed_over(self, table: TrackTable) -> np.ndarray:
        """Rows of the tracks found to follow someone else since they were lost.

        The tracker splits each: the person it had ends, the one it follows now gets a
        new track id (:meth:`ended` then :meth:`started` are called for it).
        """

    def distinct(self, table: TrackTable, rows_a: np.ndarray, rows_b: np.ndarray) -> np.ndarray:
        """Mask of the pairs of tracks ``(rows_a[k], rows_b[k])`` known to be two people.

        Such tracks are never merged.
        """

    def shares(
        self,
        table: TrackTable,
        lonely: np.ndarray,
        partner: np.ndarray,
        dets: DetectionArrays,
        cols: np.ndarray,
        t: float,
    ) -> np.ndarray:
        """Mask of the tracks ``lonely`` that may take their ``partner``'s detection at ``t``.

        ``cols``: that detection of ``dets``, per pair. They are known to be two people
        standing so close that they came out as one detection (and ``lonely`` was seen on
        its own recently enough, and the detection does not look like the partner alone).
        """

    def labels(self, ids: np.ndarray) -> tuple[list[int | None], list[str | None]]:
        """Per published track id: its ``stable_id`` and its name (``None``: none)."""
