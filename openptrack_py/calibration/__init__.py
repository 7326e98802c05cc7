"""Calibration: every sensor placed in one world frame.

Modules, one role each:

* :mod:`.files` — the calibration file (YAML): each sensor's pose, optional intrinsics,
  floor plane, residuals, date and method; validated, read by detectors and the simulator.
"""
