"""The tracker node's roster keeper: requests, the file, live reloads (no network)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from openptrack_py.config import IdentityConfig
from openptrack_py.errors import ConfigError
from openptrack_py.tracking.identity import (
    AppearanceIdentity,
    NullIdentity,
    Roster,
    RosterEntry,
    load_roster,
    save_roster,
)
from openptrack_py.tracking.roster_service import RosterKeeper, roster_request


def _identity_with_a_track(observations: float = 10.0) -> AppearanceIdentity:
    role = AppearanceIdentity(IdentityConfig(enabled=True))
    role.models.add(np.array([7]), 0.0)
    role.models.fit_dims(4, 0)
    role.models.sig[0] = [0.1, 0.2, 0.3, 0.4]
    role.models.sig_n[0] = observations
    role.models.hgt[0], role.models.hgt_n[0] = 1.7234, observations
    return role


def test_add_captures_the_tracks_looks_into_the_file(tmp_path: Path) -> None:
    path = tmp_path / "roster.yaml"
    keeper, role = RosterKeeper(path), _identity_with_a_track()
    listing = keeper.request(role, roster_request("add", "Ada", 7))
    assert [p["name"] for p in listing["roster"]] == ["Ada"]
    saved = load_roster(path)
    assert saved.names == ("Ada",) and saved.people[0].signature == (0.1, 0.2, 0.3, 0.4)
    assert saved.people[0].height == 1.723
    assert role.roster == saved
    listed = keeper.request(role, roster_request("list"))["roster"][0]
    assert (listed["observations"], listed["height"]) == (10, 1.723)
    keeper.request(role, roster_request("remove", "Ada"))
    assert load_roster(path).names == () and role.roster.names == ()


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (roster_request("add", "Ada", 99), "no track 99"),
        (roster_request("add", "", 7), "roster.name"),
        (roster_request("remove", "Nobody"), "nobody named 'Nobody'"),
        ({"roster": "rename"}, "one of add, remove, list"),
        ({"roster": "add", "roster.colour": 1}, "roster.colour: unknown"),
        (roster_request("add", "Ada", None), "roster.track"),
    ],
)
def test_bad_requests_say_what_is_wrong_and_change_nothing(
    tmp_path: Path, changes: dict, message: str
) -> None:
    path = tmp_path / "roster.yaml"
    keeper, role = RosterKeeper(path), _identity_with_a_track()
    with pytest.raises(ConfigError, match=message):
        keeper.request(role, changes)
    assert not path.exists()


@pytest.mark.parametrize("height", [0.45, 3.1, float("nan")])
def test_a_height_a_roster_would_refuse_is_not_captured(tmp_path: Path, height: float) -> None:
    """Someone seen crouching (or a wild height) is registered without a height, and the
    file still loads."""
    path = tmp_path / "roster.yaml"
    keeper, role = RosterKeeper(path), _identity_with_a_track()
    role.models.hgt[0] = height
    keeper.request(role, roster_request("add", "Ada", 7))
    assert load_roster(path).people[0].height == 0.0


def test_a_track_seen_too_little_cannot_be_registered(tmp_path: Path) -> None:
    keeper, role = RosterKeeper(tmp_path / "r.yaml"), _identity_with_a_track(observations=1)
    with pytest.raises(ConfigError, match="1 clean observations of the 3 needed"):
        keeper.request(role, roster_request("add", "Ada", 7))


def test_without_identity_or_file_requests_are_refused(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="identity is off"):
        RosterKeeper(tmp_path / "r.yaml").request(NullIdentity(), roster_request("list"))
    with pytest.raises(ConfigError, match="roster_file is not set"):
        RosterKeeper(None).request(_identity_with_a_track(), roster_request("list"))


def test_the_file_is_reloaded_when_it_changes_and_kept_when_broken(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import openptrack_py.tracking.roster_service as service

    monkeypatch.setattr(service, "RELOAD_CHECK_S", 0.0)
    path = tmp_path / "roster.yaml"
    keeper, role = RosterKeeper(path), _identity_with_a_track()
    save_roster(Roster((RosterEntry("Bo", (0.25,) * 4),)), path)
    assert keeper.reload_if_changed(role) is None
    assert role.roster.names == ("Bo",)
    path.write_text("version: 1\npeople: [{name: Bo}]\n")
    os.utime(path, ns=(1, 10**18))
    problem = keeper.reload_if_changed(role)
    assert problem is not None and "needs a signature or an embedding" in problem
    assert role.roster.names == ("Bo",)  # the roster in use is kept
