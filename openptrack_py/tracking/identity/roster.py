"""Registered people: names with reference looks, in one YAML file.

The childcare tracking paper registers every child before a session (a colour model and
a face model per name) and recognises children against that list; OpenPTrack v2 binds
registered face names one-to-one to tracks. A roster file holds one entry per person::

    version: 1
    people:
      - name: Ada
        signature: [0.01, 0.30, ...]   # colour signature, summing to 1
        embedding: [0.12, -0.05, ...]  # optional identity embedding (unit length)
        height: 1.12                   # optional height, metres (used when heights are)
        observations: 40               # clean detections the signature averages
        added: 2026-11-24T10:00:00Z

``openptrack roster add NAME --track ID`` captures a live track's looks into the file
(through the running tracker); the tracker reloads the file whenever it changes.
"""

from __future__ import annotations

import math
import os
import tempfile
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from openptrack_py.errors import ConfigError
from openptrack_py.tracking.identity.models import TrackLooks

FORMAT = 1
MAX_NAME_LEN = 64
MAX_PEOPLE = 1000
MAX_DIMS = 1024
MIN_HEIGHT_M = 0.5
"""Shortest registered height: a toddler (the childcare tracking paper's children)."""
MAX_HEIGHT_M = 2.5


@dataclass(frozen=True)
class RosterEntry:
    """One registered person.

    Parameters
    ----------
    name : str
        Unique name (1-64 printable characters).
    signature : tuple of float
        Reference colour signature (summing to 1), or empty.
    embedding : tuple of float
        Reference identity embedding (unit length), or empty.
    observations : int
        Detections the references average.
    added : str
        When the person was registered (ISO 8601).
    height : float
        Reference height in metres, as the tracker measures it (0: none). It counts
        only where the tracker compares heights (``height_weight`` > 0), and is in the
        floor frame of the calibration it was taken with.
    """

    name: str
    signature: tuple[float, ...] = ()
    embedding: tuple[float, ...] = ()
    observations: int = 0
    added: str = ""
    height: float = 0.0

    @property
    def has_reference(self) -> bool:
        """Whether the entry can recognise anyone: a signature or an embedding."""
        return bool(self.signature or self.embedding)

    def to_yaml(self) -> dict[str, Any]:
        """The entry as it is written to the file."""
        out: dict[str, Any] = {"name": self.name}
        if self.signature:
            out["signature"] = [round(v, 6) for v in self.signature]
        if self.embedding:
            out["embedding"] = [round(v, 6) for v in self.embedding]
        if self.height:
            out["height"] = round(self.height, 3)
        out["observations"] = self.observations
        if self.added:
            out["added"] = self.added
        return out


@dataclass(frozen=True)
class Roster:
    """Every registered person, with their references as arrays.

    Parameters
    ----------
    people : tuple of RosterEntry
        In file order.
    """

    people: tuple[RosterEntry, ...] = ()
    names: tuple[str, ...] = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "names", tuple(p.name for p in self.people))

    def __len__(self) -> int:
        return len(self.people)

    def references(self, kind: str, dim: int) -> tuple[np.ndarray, np.ndarray]:
        """References of one kind, and who has one.

        Returns ``(R, dim)`` references of ``kind`` ("signature" or "embedding") and a
        mask of the people who have one of length ``dim``.
        """
        out = np.zeros((len(self), dim))
        ok = np.zeros(len(self), dtype=bool)
        for k, person in enumerate(self.people):
            ref = getattr(person, kind)
            if dim and len(ref) == dim:
                out[k], ok[k] = ref, True
        return out, ok

    def heights(self) -> tuple[np.ndarray, np.ndarray]:
        """Reference heights ``(R,)`` in metres and a mask of the people who have one."""
        out = np.array([p.height for p in self.people], dtype=float)
        return out, out > 0

    def with_person(self, entry: RosterEntry) -> Roster:
        """The roster with ``entry`` added (replacing a person of the same name)."""
        kept = tuple(p for p in self.people if p.name != entry.name)
        return Roster((*kept, entry))

    def without(self, name: str) -> Roster:
        """The roster without ``name``.

        Raises
        ------
        KeyError
            If nobody of that name is registered.
        """
        if name not in self.names:
            raise KeyError(name)
        return Roster(tuple(p for p in self.people if p.name != name))


def entry_from_looks(
    name: str, looks: TrackLooks, enough: int, added: str | None = None
) -> RosterEntry:
    """A roster entry for ``name`` from a live track's ``looks``.

    Colours and height count once the track has ``enough`` clean observations of them,
    a height only where a roster accepts it (a person seen sitting or crouching, or a
    detector's wild height, leaves none rather than a file that no longer loads);
    ``added`` defaults to now.
    """
    height = round(looks.height, 3)
    if looks.height_observations < enough or not _valid_height(height):
        height = 0.0
    return RosterEntry(
        name=name,
        signature=tuple(looks.signature.tolist()) if looks.observations >= enough else (),
        embedding=tuple(looks.embedding.tolist()) if looks.embedding.any() else (),
        observations=int(looks.observations),
        added=datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ") if added is None else added,
        height=height,
    )


def _valid_height(height: float) -> bool:
    """Whether a height in metres is one a roster stores (0 stands for none)."""
    return math.isfinite(height) and MIN_HEIGHT_M <= height <= MAX_HEIGHT_M


def check_name(name: Any, where: str = "name") -> str:
    """``name`` if it is a valid roster name.

    Raises
    ------
    ConfigError
        Naming ``where`` and what is allowed.
    """
    if (
        not isinstance(name, str)
        or not 0 < len(name) <= MAX_NAME_LEN
        or not name.isprintable()
        or name != name.strip()
    ):
        raise ConfigError(
            f"{where}: expected a name of 1-{MAX_NAME_LEN} printable characters without "
            f"leading or trailing spaces, got {name!r}"
        )
    return name


def _finite(value: Any) -> bool:
    """Whether ``value`` is a finite number (a YAML ``true`` is not)."""
    return not isinstance(value, bool) and isinstance(value, int | float) and math.isfinite(value)


def _vector(value: Any, where: str) -> tuple[float, ...]:
    if value is None:
        return ()
    if not isinstance(value, list) or len(value) > MAX_DIMS:
        raise ConfigError(f"{where}: expected a list of at most {MAX_DIMS} numbers")
    for v in value:
        if not _finite(v):
            raise ConfigError(f"{where}: expected finite numbers, got {v!r}")
    return tuple(float(v) for v in value)


def _entry(item: Any, k: int) -> RosterEntry:
    where = f"people[{k}]"
    if not isinstance(item, dict):
        raise ConfigError(f"{where}: expected a mapping")
    unknown = set(item) - {"name", "signature", "embedding", "height", "observations", "added"}
    if unknown:
        raise ConfigError(
            f"{where}: unknown key {sorted(unknown)[0]!r} (allowed: name, signature, "
            "embedding, height, observations, added)"
        )
    height = item.get("height")
    height = 0.0 if height is None else height
    if not _finite(height) or not (height == 0 or _valid_height(height)):
        raise ConfigError(
            f"{where}.height: expected metres from {MIN_HEIGHT_M} to {MAX_HEIGHT_M} "
            f"(or 0: none), got {height!r}"
        )
    obs = item.get("observations", 0)
    if isinstance(obs, bool) or not isinstance(obs, int) or obs < 0:
        raise ConfigError(f"{where}.observations: expected an integer >= 0, got {obs!r}")
    entry = RosterEntry(
        name=check_name(item.get("name"), f"{where}.name"),
        signature=_vector(item.get("signature"), f"{where}.signature"),
        embedding=_vector(item.get("embedding"), f"{where}.embedding"),
        observations=obs,
        added=str(item.get("added", "")),
        height=float(height),
    )
    if not entry.has_reference:
        raise ConfigError(f"{where}: needs a signature or an embedding")
    return entry


def parse_roster(data: Any, source: str = "roster") -> Roster:
    """A :class:`Roster` from a parsed YAML document.

    Raises
    ------
    ConfigError
        Naming the first field that is wrong.
    """
    if data is None:
        return Roster()
    if not isinstance(data, dict) or data.get("version") != FORMAT:
        raise ConfigError(f"{source}: expected a mapping with 'version: {FORMAT}'")
    people = data.get("people") or []
    if not isinstance(people, list) or len(people) > MAX_PEOPLE:
        raise ConfigError(f"{source}.people: expected a list of at most {MAX_PEOPLE} people")
    entries = [_entry(item, k) for k, item in enumerate(people)]
    names = [e.name for e in entries]
    dup = next((n for n in names if names.count(n) > 1), None)
    if dup is not None:
        raise ConfigError(f"{source}.people: name {dup!r} registered twice")
    return Roster(tuple(entries))


def load_roster(path: Path) -> Roster:
    """The roster in ``path`` (empty when the file does not exist).

    Raises
    ------
    ConfigError
        If the file is not valid YAML or not a valid roster.
    """
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return Roster()
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML ({exc})") from exc
    return parse_roster(data, str(path))


def save_roster(roster: Roster, path: Path) -> None:
    """Write ``roster`` to ``path`` atomically (a reader never sees half a file)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    doc = {"version": FORMAT, "people": [p.to_yaml() for p in roster.people]}
    fd, tmp = tempfile.mkstemp(prefix=".roster-", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write("# openptrack roster: registered people (openptrack roster --help)\n")
            yaml.safe_dump(doc, fh, sort_keys=False, allow_unicode=True)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
