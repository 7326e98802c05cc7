"""The tracker's identity role: who each track is.

:class:`NullIdentity` (the default) has no opinion; :class:`AppearanceIdentity`
re-ranks association by appearance, re-identifies people after a loss and names
registered people (``tracker.identity.enabled: true``).
"""

from openptrack_py.tracking.identity.appearance import AppearanceIdentity
from openptrack_py.tracking.identity.null import NullIdentity
from openptrack_py.tracking.identity.roster import Roster, RosterEntry, load_roster, save_roster

__all__ = [
    "AppearanceIdentity",
    "NullIdentity",
    "Roster",
    "RosterEntry",
    "load_roster",
    "save_roster",
]
