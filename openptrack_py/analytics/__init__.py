"""Behaviour analytics over recorded tracks: trajectories, motion ranges, distances, places.

The figures the childcare tracking paper (Zhang et al., §3.2) gives nursery teachers —
each child's trajectory, momentum and motion range, the relative distance between two
people — and what an installation wants to know — time in zones, entries through doors,
where people linger — computed in one streaming pass (:func:`analyze`) and drawn in an
HTML report (:mod:`~openptrack_py.analytics.report`).
"""

from openptrack_py.analytics.analysis import Analysis, analyze
from openptrack_py.analytics.frames import PeopleFrame, frames_from_recording
from openptrack_py.zones import ZoneTracker

__all__ = ["Analysis", "PeopleFrame", "ZoneTracker", "analyze", "frames_from_recording"]
