"""What the checkerboard calibration returns: every sensor's pose, and its report.

The results of :func:`~openptrack_py.calibration.extrinsics.calibrate_extrinsics`
(Munaro et al., OpenPTrack, §4): :class:`ExtrinsicCalibration` holds every sensor's
refined pose in the world (and its refined pinhole and distortion when they were solved
too) and writes the calibration file's entries; :class:`CalibrationReport` says how the
solve went (residuals per sensor, counts, solver figures, rejected views).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime, timezone

import numpy as np

from openptrack_py.calibration.evidence import IntrinsicsEvidence
from openptrack_py.calibration.files import CameraIntrinsics, SensorCalibration
from openptrack_py.config import Pose
from openptrack_py.detection.frame import Intrinsics
from openptrack_py.detection.lens import LENS_TERMS
from openptrack_py.geometry import pose_from_transform

__all__ = ["FOCAL_SD_WARN", "CalibrationReport", "ExtrinsicCalibration"]

FOCAL_SD_WARN = 0.005
"""A refined focal length less certain than this (a fraction) is reported as poorly
determined: at 3 m, 0.5 % of focal length is 1.5 cm of board distance."""


@dataclass(frozen=True)
class CalibrationReport:
    """How the checkerboard calibration went.

    Parameters
    ----------
    reference : str
        The sensor whose pose anchored the solve.
    rms_px : dict
        Per sensor: reprojection RMS of its kept views, pixels.
    views : dict
        Per sensor: board views used.
    pair_views : dict
        Per pair of sensors (ids sorted): placements both saw.
    placements : int
        Board placements used.
    iterations : int
        Jacobian evaluations (iterations) of the final refinement.
    initial_cost, final_cost : float
        ``least_squares`` cost (half the sum of robust squared residuals, px², the
        intrinsics' prior included when they are refined) before and after the final
        refinement.
    rounds : int
        Refinements run: one, and one more after each round of outlier rejection.
    total_iterations : int
        Jacobian evaluations of all of them.
    world_frame : str
        ``"floor board"`` or ``"reference pose"``.
    rejected_views : tuple of (str, float)
        ``(sensor, stamp)`` of views rejected as outliers.
    rejected_corners : int
        Corners of the kept views rejected as outliers.
    intrinsics_refined : bool
        Whether every sensor's intrinsics were solved with the poses.
    intrinsics_sd : dict
        Per sensor, when refined: standard deviations of ``fx, fy, cx, cy`` (pixels) and
        of the lens terms solved (``k1, k2``, then ``p1, p2, k3``). A few views, or
        views all at one distance, leave the focal length and the centre poorly
        determined, and the poses with them.
    distortion_px : dict
        Per sensor, when refined: how far its distortion moves a corner it saw, at most,
        pixels.
    intrinsics_evidence : dict
        Per sensor, when refined and tested: what its views say of its given intrinsics
        (:class:`~openptrack_py.calibration.evidence.IntrinsicsEvidence`: the rise of
        the corners' squared error with them held as given, in noise variances, and the
        threshold it had to exceed for the refinement to be kept).
    """

    reference: str
    rms_px: dict[str, float]
    views: dict[str, int]
    pair_views: dict[tuple[str, str], int]
    placements: int
    iterations: int
    initial_cost: float
    final_cost: float
    world_frame: str
    rejected_views: tuple[tuple[str, float], ...] = ()
    rejected_corners: int = 0
    rounds: int = 1
    total_iterations: int = 0
    intrinsics_refined: bool = False
    intrinsics_sd: dict[str, tuple[float, ...]] = field(default_factory=dict)
    distortion_px: dict[str, float] = field(default_factory=dict)
    intrinsics_evidence: dict[str, IntrinsicsEvidence] = field(default_factory=dict)

    @property
    def intrinsics_kept(self) -> list[str]:
        """Sensors whose given intrinsics were kept: their views did not show them wrong."""
        return [s for s, e in self.intrinsics_evidence.items() if not e.refined]

    def to_dict(self) -> dict:
        """JSON-ready dict (pairs as ``"a|b"`` keys)."""
        return {
            "reference": self.reference,
            "rms_px": dict(self.rms_px),
            "views": dict(self.views),
            "pair_views": {f"{a}|{b}": n for (a, b), n in self.pair_views.items()},
            "placements": self.placements,
            "iterations": self.iterations,
            "rounds": self.rounds,
            "total_iterations": self.total_iterations,
            "initial_cost": self.initial_cost,
            "final_cost": self.final_cost,
            "world_frame": self.world_frame,
            "rejected_views": [list(v) for v in self.rejected_views],
            "rejected_corners": self.rejected_corners,
            "intrinsics_refined": self.intrinsics_refined,
            "intrinsics_sd": {s: list(v) for s, v in self.intrinsics_sd.items()},
            "distortion_px": dict(self.distortion_px),
            "intrinsics_evidence": {
                s: {"statistic": e.statistic, "threshold": e.threshold, "refined": e.refined}
                for s, e in self.intrinsics_evidence.items()
            },
        }


@dataclass(frozen=True, eq=False)
class ExtrinsicCalibration:
    """Every sensor's pose in the world, and how well the views agree with it.

    Parameters
    ----------
    world_from_optical : dict
        Per sensor id: 4x4 transform from its optical frame to the world.
    world_from_board : dict
        Per placement stamp: 4x4 pose of the board in the world.
    report : CalibrationReport
        Residuals, counts and solver figures.
    intrinsics : dict
        Per sensor id, its refined camera model, pinhole and lens distortion (empty
        unless ``refine_intrinsics``).
    """

    world_from_optical: dict[str, np.ndarray]
    world_from_board: dict[float, np.ndarray]
    report: CalibrationReport
    intrinsics: dict[str, Intrinsics] = field(default_factory=dict)

    @property
    def distortion(self) -> dict[str, tuple[float, ...]]:
        """OpenCV distortion coefficients ``(k1, k2, p1, p2, k3)`` per refined sensor.

        As the calibration file writes them.
        """
        return {s: k.distortion for s, k in self.intrinsics.items()}

    def poses(self) -> dict[str, Pose]:
        """Every sensor's pose as a network file writes it."""
        return {s: pose_from_transform(m) for s, m in self.world_from_optical.items()}

    def entries(self) -> dict[str, SensorCalibration]:
        """Calibration-file entries: pose, method ``checkerboard``, residuals, date.

        Residuals per sensor: ``reprojection_px`` (RMS) and ``views``; the refined
        intrinsics and distortion when they were solved.
        """
        now = datetime.now(timezone.utc)
        return {
            s: SensorCalibration.from_transform(
                m,
                method="checkerboard",
                residuals={
                    "reprojection_px": self.report.rms_px[s],
                    "views": float(self.report.views[s]),
                },
                intrinsics=self._camera(s),
                date=now,
            )
            for s, m in self.world_from_optical.items()
        }

    def intrinsics_warnings(self, focal_sd: float = FOCAL_SD_WARN) -> list[str]:
        """What a user should know of the refined intrinsics, one line per sensor.

        A focal length whose standard deviation exceeds ``focal_sd`` (a fraction) is
        poorly determined by the views, and the poses with it; a lens whose fitted
        distortion cannot be inverted out to the image's corners leaves the detector
        blind there (strong radial terms fitted from views near the centre). A sensor
        whose views did not show its given intrinsics wrong kept them.
        """
        out = [
            f"{sid}: intrinsics kept as given: refining them lowered the corners' squared "
            f"error by {e.statistic:.1f} noise variances, {e.threshold:.1f} would show them "
            "wrong (--always-refine refines them anyway)"
            for sid, e in self.report.intrinsics_evidence.items()
            if not e.refined
        ]
        for sid, k in self.intrinsics.items():
            sd = self.report.intrinsics_sd.get(sid)
            if sd is not None and max(sd[0] / k.fx, sd[1] / k.fy) > focal_sd:
                out.append(
                    f"{sid}: focal length poorly determined (±{100 * sd[0] / k.fx:.1f} %): "
                    "add placements nearer and farther, and towards the image's edges"
                )
            corners_x, _ = k.rays(
                np.array([0.0, k.width - 1.0] * 2), np.repeat([0.0, k.height - 1.0], 2)
            )
            if not np.isfinite(corners_x).all():
                out.append(
                    f"{sid}: the fitted lens distortion ({_terms(k)}) cannot be "
                    "inverted at the image's corners, where the detector will see nothing: "
                    "add placements towards the image's edges"
                )
        return out

    def _camera(self, sensor_id: str) -> CameraIntrinsics | None:
        """The file's intrinsics of a sensor, if they were refined."""
        k = self.intrinsics.get(sensor_id)
        if k is None:
            return None
        return CameraIntrinsics(
            width=k.width, height=k.height, fx=k.fx, fy=k.fy, cx=k.cx, cy=k.cy,
            distortion=k.distortion,
        )  # fmt: skip


def _terms(k: Intrinsics) -> str:
    """The lens terms of ``k`` that are not 0, for a message."""
    terms = zip(LENS_TERMS, k.distortion, strict=True)
    return ", ".join(f"{name} {value:.3f}" for name, value in terms if value)
