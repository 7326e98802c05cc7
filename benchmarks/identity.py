"""Identity off and on, side by side, on the ``realistic`` simulator profile.

For each scenario and seed the same detections run through the default tracker twice,
with ``tracker.identity.enabled`` off and on, and are scored on the identity a client
sees (``stable_id`` where the tracker gives one): MOTA, IDF1, identity switches, returns
that kept their identity (:mod:`openptrack_py.eval.returns`) and the tracker's cost per
batch. ``--embeddings`` adds the simulator's stand-in identity embeddings (a face
recogniser's output: only for people facing a sensor within 5 m, with noise, dropouts
and confusions).

The roster check (``classroom``): everyone is registered from the first
:data:`REGISTRATION_S` of a run (as a teacher registers each child before a session,
the childcare tracking paper's "children registration"), then the run is tracked again
from the start with that roster, and the share of frames in which each person matched to
a track carries their own name, from 2 s after they are first in view, is counted, as
well as the share in which it carries another's name and frames in which one name is on
two tracks.

Prints one JSON line per run and a markdown table, writes ``docs/identity.json`` and
``docs/identity.png``::

    python -m benchmarks.identity                 # all scenarios, seeds 31-33
    python -m benchmarks.identity --quick         # 30 s runs, one seed, no files

The seeds (31-33) were not used while the identity role was developed.
"""

from __future__ import annotations

import argparse
import json
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

from openptrack_py.config import TrackerConfig
from openptrack_py.eval.runner import Hypotheses, TrackerFeed, evaluate
from openptrack_py.eval.trackers import tracking_feed
from openptrack_py.messages.ground_truth import GroundTruthFrame
from openptrack_py.sim.scenarios import build_scenario
from openptrack_py.tracking.identity import AppearanceIdentity, Roster, RosterEntry
from openptrack_py.tracking.identity.roster import entry_from_looks

ROOT = Path(__file__).resolve().parent.parent
SEEDS = (31, 32, 33)
SCENARIOS = ("occlusions", "installation", "classroom", "stress", "reentry", "uniforms")
PROFILE = "realistic"
REGISTRATION_S = 20.0
"""The first seconds of a classroom run, from which every person is registered."""
NAME_SETTLE_S = 2.0
"""Names are judged from this long after a person is first in view."""
MATCH_M = 0.5


def _config(identity: bool, roster_file: Path | None = None) -> TrackerConfig:
    ident: dict[str, object] = {"enabled": identity}
    if roster_file is not None:
        ident["roster_file"] = str(roster_file)
    return TrackerConfig(identity=ident)


def _scenario(name: str, seed: int, duration_s: float | None, embeddings: bool):
    options = {"embeddings": True} if embeddings else {}
    return build_scenario(
        name, seed=seed, duration_s=-1 if duration_s is None else duration_s,
        profile=PROFILE, **options,
    )  # fmt: skip


def run_one(job: tuple[str, int, bool, float | None, bool]) -> dict[str, object]:
    """One scenario, one seed, identity off or on."""
    name, seed, identity, duration_s, embeddings = job
    scenario = _scenario(name, seed, duration_s, embeddings)
    feed = tracking_feed(_config(identity))
    start = time.perf_counter()
    result = evaluate(scenario, feed)
    m = result.metrics
    return {
        "scenario": name,
        "seed": seed,
        "identity": identity,
        "embeddings": embeddings,
        "mota": round(m.mota, 4),
        "idf1": round(m.idf1, 4),
        "id_switches": m.id_switches,
        "returns": m.returns,
        "returns_kept": m.returns_kept,
        "duplicates": m.duplicates,
        "tracker_ms_per_batch": round(result.tracker_ms_per_batch or 0.0, 4),
        "wall_s": round(time.perf_counter() - start, 1),
    }


def _match(people: list, hyp: Hypotheses) -> dict[int, int]:
    """Each person's track (index of ``people`` to index of ``hyp``), within ``MATCH_M``."""
    gt = np.array([(p.x, p.y) for p in people])
    dist = np.linalg.norm(gt[:, None] - hyp.xy[None], axis=2)
    rows, cols = linear_sum_assignment(np.where(dist <= MATCH_M, dist, 1e6))
    return {
        r: c for r, c in zip(rows.tolist(), cols.tolist(), strict=True) if dist[r, c] <= MATCH_M
    }


class _NameLog:
    """Per scored frame: is each person's matched track named after them, or another?"""

    def __init__(self, feed: TrackerFeed) -> None:
        self.feed = feed
        self.first_seen: dict[int, float] = {}
        self.right = self.wrong = self.judged = self.doubled = 0

    def __call__(self, t: float, truth: GroundTruthFrame, hyp: Hypotheses | None) -> None:
        latest = self.feed._latest
        if hyp is None or latest is None:
            return
        names = {
            (tr.stable_id if tr.stable_id is not None else tr.id): tr.identity
            for tr in latest.tracks
        }
        given = [n for n in names.values() if n]
        self.doubled += len(given) != len(set(given))
        people = [p for p in truth.people if p.covered]
        for p in people:
            self.first_seen.setdefault(p.id, t)
        if not people or not len(hyp.ids):
            self.judged += sum(t - self.first_seen[p.id] >= NAME_SETTLE_S for p in people)
            return
        match = _match(people, hyp)
        for k, p in enumerate(people):
            if t - self.first_seen[p.id] < NAME_SETTLE_S:
                continue
            self.judged += 1
            c = match.get(k)
            name = names.get(int(hyp.ids[c])) if c is not None else None
            self.right += name == f"p{p.id}"
            self.wrong += bool(name) and name != f"p{p.id}"


def _register(seed: int, embeddings: bool) -> Roster:
    """Every person's looks from the first seconds of the run, named ``p<id>``.

    Each is registered from the track matched to them the last time one was, with looks
    enough to register (as a teacher registers each child while the child is in view):
    someone out of view at the end of the window is still registered.
    """
    scenario = _scenario("classroom", seed, REGISTRATION_S, embeddings)
    feed = tracking_feed(_config(True))
    identity = feed.pipeline.tracker.identity
    assert isinstance(identity, AppearanceIdentity)
    enough = identity.cfg.min_observations
    entries: dict[int, RosterEntry] = {}

    def keep(t: float, truth: GroundTruthFrame, hyp: Hypotheses | None) -> None:
        latest = feed._latest
        people = [p for p in truth.people if p.covered]  # type: ignore[attr-defined]
        if hyp is None or latest is None or not people or not len(hyp.ids):
            return
        by_stable = {(tr.stable_id or tr.id): tr.id for tr in latest.tracks}
        for r, c in _match(people, hyp).items():
            looks = identity.looks_of(by_stable.get(int(hyp.ids[c]), -1))
            if looks is None:
                continue
            entry = entry_from_looks(f"p{people[r].id}", looks, enough, "")
            if entry.has_reference:
                entries[people[r].id] = entry

    evaluate(scenario, feed, on_frame=keep)
    return Roster(tuple(entries[k] for k in sorted(entries)))


def run_roster(job: tuple[int, float | None, bool]) -> dict[str, object]:
    """Classroom with everyone registered: right names, and names on two tracks."""
    seed, duration_s, embeddings = job
    roster = _register(seed, embeddings)
    feed = tracking_feed(_config(True))
    feed.pipeline.tracker.identity.set_roster(roster)  # type: ignore[attr-defined]
    log = _NameLog(feed)
    evaluate(_scenario("classroom", seed, duration_s, embeddings), feed, on_frame=log)
    return {
        "scenario": "classroom-roster",
        "seed": seed,
        "embeddings": embeddings,
        "registered": len(roster),
        "right_name": round(log.right / max(log.judged, 1), 4),
        "wrong_name": round(log.wrong / max(log.judged, 1), 4),
        "frames_with_a_name_twice": log.doubled,
    }


def _mean(rows: list[dict[str, object]], key: str) -> float:
    return float(np.mean([float(r[key]) for r in rows]))  # type: ignore[arg-type]


def _total(rows: list[dict[str, object]], key: str) -> int:
    return int(sum(int(r[key]) for r in rows))  # type: ignore[call-overload]


def table(rows: list[dict[str, object]]) -> str:
    """Markdown: per scenario, identity off and on (means over seeds, worst seed)."""
    out = [
        "| scenario | MOTA off | MOTA on | IDF1 off | IDF1 on (worst) | switches off/on "
        "| returns kept off / on | ms/batch off/on |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name in dict.fromkeys(str(r["scenario"]) for r in rows if "mota" in r):
        off = [r for r in rows if r["scenario"] == name and r.get("identity") is False]
        on = [r for r in rows if r["scenario"] == name and r.get("identity") is True]
        if not off or not on:
            continue
        worst = min(float(r["idf1"]) for r in on)  # type: ignore[arg-type]
        kept = [f"{_total(x, 'returns_kept')}/{_total(x, 'returns')}" for x in (off, on)]
        cost = [_mean(x, "tracker_ms_per_batch") for x in (off, on)]
        out.append(
            f"| {name} | {_mean(off, 'mota'):.3f} | {_mean(on, 'mota'):.3f} "
            f"| {_mean(off, 'idf1'):.3f} | {_mean(on, 'idf1'):.3f} ({worst:.3f}) "
            f"| {_total(off, 'id_switches')}/{_total(on, 'id_switches')} "
            f"| {kept[0]} / {kept[1]} | {cost[0]:.2f}/{cost[1]:.2f} |"
        )
    return "\n".join(out)


def plot(rows: list[dict[str, object]], path: Path) -> None:
    """IDF1 off and on per scenario, one dot per seed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(dict.fromkeys(str(r["scenario"]) for r in rows if "idf1" in r))
    fig, ax = plt.subplots(figsize=(8, 4))
    for k, name in enumerate(names):
        for on, colour, dx in ((False, "#999999", -0.15), (True, "#1f77b4", 0.15)):
            vals = [
                float(r["idf1"]) for r in rows if r["scenario"] == name and r.get("identity") == on
            ]  # type: ignore[arg-type]
            if vals:
                ax.bar(
                    k + dx,
                    np.mean(vals),
                    0.3,
                    color=colour,
                    label=None if k else ("identity on" if on else "identity off"),
                )
                ax.plot([k + dx] * len(vals), vals, "k.", ms=4)
    ax.set_xticks(range(len(names)), names)
    ax.set_ylabel("IDF1 (on stable_id)")
    ax.set_ylim(0, 1)
    ax.legend(loc="lower left")
    ax.set_title(f"Identity off and on, {PROFILE} profile, seeds {min(SEEDS)}-{max(SEEDS)}")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv: list[str] | None = None) -> None:
    """Run every scenario and seed with identity off and on; print and write the results."""
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--quick", action="store_true", help="30 s runs, one seed, no files")
    p.add_argument("--scenario", action="append", help="scenario (repeatable; default all)")
    p.add_argument("--seed", type=int, action="append", help="seed (repeatable)")
    p.add_argument("--embeddings", action="store_true", help="sensors send identity embeddings")
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--out", type=Path, default=ROOT / "docs" / "identity.json")
    args = p.parse_args(argv)
    seeds = tuple(args.seed or (SEEDS[:1] if args.quick else SEEDS))
    names = tuple(args.scenario or SCENARIOS)
    duration = 30.0 if args.quick else None
    jobs = [
        (n, s, on, duration, args.embeddings) for n in names for s in seeds for on in (False, True)
    ]
    rows: list[dict[str, object]] = []
    started = time.perf_counter()
    with ProcessPoolExecutor(args.jobs) as pool:
        futures = [pool.submit(run_one, j) for j in jobs]
        if "classroom" in names:
            futures += [pool.submit(run_roster, (s, duration, args.embeddings)) for s in seeds]
        for k, fut in enumerate(futures, 1):
            row = fut.result()
            rows.append(row)
            print(json.dumps(row), flush=True)
            print(f"[{k}/{len(futures)}] {time.perf_counter() - started:.0f} s", flush=True)
    print(table(rows))
    for r in rows:
        if r["scenario"] == "classroom-roster":
            print(f"roster seed {r['seed']}: right name {r['right_name']:.3f}, "
                  f"another's name {r['wrong_name']:.3f}, "
                  f"frames with a name twice {r['frames_with_a_name_twice']}")  # fmt: skip
    if not args.quick:
        args.out.write_text(
            json.dumps({"profile": PROFILE, "seeds": seeds, "rows": rows}, indent=1)
        )
        plot(rows, args.out.with_suffix(".png"))


if __name__ == "__main__":
    main()
