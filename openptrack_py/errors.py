"""Exceptions raised at the boundaries of openptrack_py.

Every error the library raises on bad input derives from :class:`OptError`, so a node
can catch one type at its edge. Messages name the offending field or key, what was
allowed and what was received.
"""

from __future__ import annotations


class OptError(Exception):
    """Base class of every openptrack_py error."""


class ConfigError(OptError, ValueError):
    """A configuration file, override or live parameter update is invalid.

    The message names the key path (e.g. ``sensors.1.rate_hz``), the allowed
    values and the value received.
    """


class WireFormatError(OptError, ValueError):
    """Bytes received from the network do not decode to a valid message.

    The message names the field that failed (e.g. ``detections[3].x``).
    """


class CalibrationError(OptError):
    """A calibration file or procedure produced an unusable result."""


class SourceError(OptError):
    """A depth source cannot be opened or read.

    The message names the source (file, folder or device spec), what went wrong and,
    where it helps, what is accepted (e.g. the source kinds, or the connected devices).
    """
