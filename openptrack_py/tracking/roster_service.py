"""The tracker node's roster: requests from ``openptrack roster`` and live reloads.

Roster requests travel on the tracker's configuration channel (so a secured site's
access control already says who may send them): a
:class:`~openptrack_py.messages.config_update.ConfigUpdate` whose ``set`` is
``{"roster": "add", "roster.name": NAME, "roster.track": ID}`` (or ``"remove"`` with a
name, or ``"list"``; plain values, as every configuration request). The tracker
captures the track's looks from its identity role, writes the roster file atomically,
names that track at once (it is the person just registered) and answers with the
roster's people in the ack's ``config``
(``{"roster": [{"name", "observations", "height", "added"}, ...]}``).

The file is also watched: an edit by hand (or by another tool) is loaded at most
:data:`RELOAD_CHECK_S` later; a file that does not parse is reported and the roster in
use is kept.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from openptrack_py.errors import ConfigError
from openptrack_py.tracking.identity import (
    AppearanceIdentity,
    Roster,
    RosterEntry,
    load_roster,
    save_roster,
)
from openptrack_py.tracking.identity.roster import check_name, entry_from_looks

ROSTER_KEY = "roster"
"""The ``set`` key of a roster request."""
RELOAD_CHECK_S = 1.0
"""How often the roster file's modification time is checked, seconds."""
ACTIONS = ("add", "remove", "list")


def roster_request(action: str, name: str | None = None, track: int | None = None) -> dict:
    """The ``set`` of a roster request."""
    body: dict[str, object] = {ROSTER_KEY: action}
    if name is not None:
        body[f"{ROSTER_KEY}.name"] = name
    if track is not None:
        body[f"{ROSTER_KEY}.track"] = track
    return body


def roster_listing(roster: Roster) -> dict[str, Any]:
    """What a roster request's answer carries."""
    return {
        ROSTER_KEY: [
            {"name": p.name, "observations": p.observations, "height": p.height, "added": p.added}
            for p in roster.people
        ]
    }


class RosterKeeper:
    """Applies roster requests to a tracker's identity role and keeps the file in sync.

    Parameters
    ----------
    path : Path or None
        The roster file (``tracker.identity.roster_file``); ``None``: no roster.
    """

    def __init__(self, path: Path | None) -> None:
        self.path = path
        self._mtime: float | None = self._stat()
        self._checked = time.monotonic()

    def _stat(self) -> float | None:
        if self.path is None:
            return None
        try:
            return self.path.stat().st_mtime_ns / 1e9
        except FileNotFoundError:
            return None

    def request(self, identity: object, changes: dict[str, Any]) -> dict[str, Any]:
        """Apply one request (a configuration update's ``set``); return the listing.

        Raises
        ------
        ConfigError
            Saying what is wrong: identity off, no roster file, an unknown action or
            track, a track not seen long enough, an unknown name.
        """
        if not isinstance(identity, AppearanceIdentity):
            raise ConfigError("roster: identity is off (set tracker.identity.enabled=true)")
        if self.path is None:
            raise ConfigError("roster: tracker.identity.roster_file is not set")
        body = {k.removeprefix(f"{ROSTER_KEY}."): v for k, v in changes.items()}
        action = body.pop(ROSTER_KEY, None)
        unknown = sorted(set(body) - {"name", "track"})
        if unknown:
            raise ConfigError(f"roster.{unknown[0]}: unknown (a roster request has name, track)")
        if action not in ACTIONS:
            raise ConfigError(f"roster: expected an action, one of {', '.join(ACTIONS)}")
        roster = identity.roster
        added = None
        if action == "add":
            added = self._capture(identity, body)
            roster = roster.with_person(added)
        elif action == "remove":
            name = check_name(body.get("name"), "roster.name")
            try:
                roster = roster.without(name)
            except KeyError:
                raise ConfigError(f"roster: nobody named {name!r} is registered") from None
        if action != "list":
            save_roster(roster, self.path)
            self._mtime = self._stat()
            identity.set_roster(roster)
        if added is not None:  # the person of that track is the one just named
            identity.name_track(body["track"], added.name)
        return roster_listing(roster)

    def _capture(self, identity: AppearanceIdentity, body: dict) -> RosterEntry:
        name = check_name(body.get("name"), "roster.name")
        track = body.get("track")
        if isinstance(track, bool) or not isinstance(track, int):
            raise ConfigError(f"roster.track: expected a track id, got {track!r}")
        looks = identity.looks_of(track)
        if looks is None:
            raise ConfigError(f"roster: no track {track} (is the person in view?)")
        enough = identity.cfg.min_observations
        entry = entry_from_looks(name, looks, enough)
        if not entry.has_reference:
            raise ConfigError(
                f"roster: track {track} has {int(looks.observations)} clean observations "
                f"of the {enough} needed; let the person stand in view a little longer"
            )
        return entry

    def reload_if_changed(self, identity: object) -> str | None:
        """Load the file again if it changed; return an error message if it is invalid."""
        if not isinstance(identity, AppearanceIdentity) or self.path is None:
            return None
        now = time.monotonic()
        if now - self._checked < RELOAD_CHECK_S:
            return None
        self._checked = now
        mtime = self._stat()
        if mtime == self._mtime:
            return None
        self._mtime = mtime
        try:
            identity.set_roster(load_roster(self.path))
        except ConfigError as exc:
            return str(exc)
        return None
