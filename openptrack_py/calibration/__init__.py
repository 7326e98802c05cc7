"""Calibration: every sensor placed in one world frame.

Modules, one role each:

* :mod:`.files` — the calibration file (YAML): each sensor's pose, optional intrinsics,
  floor plane, residuals, date and method; validated, read by detectors (pose, clock
  offset and pinhole) and the simulator.
* :mod:`.service` — the calibration on the bus: served by the master, fetched and
  followed by the sensors' nodes.
* Checkerboard calibration (Munaro et al., OpenPTrack, §4): :mod:`.checkerboard` (the
  board, its corners and pose in one view), :mod:`.intrinsics`, :mod:`.observations`
  (views grouped by board placement), :mod:`.posegraph` (initial poses along the pair
  graph), :mod:`.bundle` (the sparse joint least squares), :mod:`.extrinsics` (the
  procedure), :mod:`.board_result` (its result and report), :mod:`.progress` (what
  the operator sees while moving the board), :mod:`.opencv` (the lazy OpenCV import).
* Calibration from one walking person, and refinement (Munaro et al., §4.3; Zhang et
  al., children behavior tracking, §2.2): :mod:`.walk` (the procedures),
  :mod:`.walk_tracks`, :mod:`.walk_pairs`, :mod:`.walk_solve`, :mod:`.walk_measure`,
  :mod:`.walk_result`, :mod:`.walk_settings`; :mod:`.plots` draws the before/after view.

The procedures run end to end on the simulator in :mod:`openptrack_py.eval.checkerboard`
and :mod:`openptrack_py.eval.walk`.
"""
