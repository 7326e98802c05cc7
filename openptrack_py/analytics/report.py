"""The HTML report of an analysis: one file a teacher or an artist opens without Python.

Sections, each with its plot (matplotlib, embedded as PNG) and its table: the people
(trajectories on the floor plan), motion areas (the paper's bounding rectangles, with
convex hulls), momentum over time, relative distances (over time for the closest pairs,
and every pair's mean), the occupancy heatmap, zones and doors, and speeds. Names from
the roster label the people when identity was on. The file needs nothing else: no
script, no network.
"""

from __future__ import annotations

import base64
import html
import io
import itertools
from collections.abc import Sequence
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from openptrack_py.analytics.analysis import Analysis
from openptrack_py.analytics.people import SPEED_BINS_MPS

__all__ = ["SECTIONS", "write_report"]

SECTIONS = (
    ("people", "People"),
    ("trajectories", "Trajectories"),
    ("areas", "Motion areas"),
    ("momentum", "Momentum"),
    ("distances", "Relative distances"),
    ("heatmap", "Where people were"),
    ("places", "Zones and doors"),
    ("speed", "Speed"),
)
"""The report's sections: ``(id, title)``."""

MAX_LEGEND = 12
MAX_DISTANCE_PAIRS = 6

_STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1100px; color: #222; }
h1 { font-size: 1.6em; } h2 { border-bottom: 1px solid #ccc; padding-bottom: .2em; }
table { border-collapse: collapse; margin: .5em 0 1.5em; font-size: .9em; }
th, td { border: 1px solid #ddd; padding: .25em .6em; text-align: right; }
th { background: #f4f4f4; } td:first-child, th:first-child { text-align: left; }
img { max-width: 100%; } nav a { margin-right: 1em; } .note { color: #666; }
"""


def _png(fig: object) -> str:
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")  # type: ignore[attr-defined]
    plt.close(fig)  # type: ignore[arg-type]
    data = base64.b64encode(buf.getvalue()).decode()
    return f'<img alt="plot" src="data:image/png;base64,{data}">'


def _table(rows: Sequence[dict[str, object]], empty: str = "nothing to show") -> str:
    if not rows:
        return f'<p class="note">{html.escape(empty)}</p>'
    columns = list(rows[0])
    head = "".join(f"<th>{html.escape(str(c))}</th>" for c in columns)
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(str(r.get(c, '')))}</td>" for c in columns) + "</tr>"
        for r in rows
    )
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _floor(ax: object, analysis: Analysis) -> None:
    for name, poly in analysis.zone_polygons.items():
        closed = np.vstack([poly, poly[:1]])
        ax.fill(closed[:, 0], closed[:, 1], alpha=0.12, color="tab:green")  # type: ignore[attr-defined]
        ax.text(*poly.mean(axis=0), name, color="tab:green", ha="center")  # type: ignore[attr-defined]
    for name, seg in analysis.door_segments.items():
        ax.plot(seg[:, 0], seg[:, 1], color="tab:red", lw=3)  # type: ignore[attr-defined]
        ax.text(*seg.mean(axis=0), name, color="tab:red")  # type: ignore[attr-defined]
    ax.set_aspect("equal")  # type: ignore[attr-defined]
    ax.set_xlabel("x (m)")  # type: ignore[attr-defined]
    ax.set_ylabel("y (m)")  # type: ignore[attr-defined]
    ax.grid(True, alpha=0.3)  # type: ignore[attr-defined]


def _people_order(analysis: Analysis) -> list[int]:
    return sorted(analysis.people, key=lambda k: -analysis.people[k].seen_s)


def _trajectories(analysis: Analysis) -> str:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 6))
    for i, key in enumerate(_people_order(analysis)):
        path = analysis.people[key].path
        label = analysis.label(key) if i < MAX_LEGEND else None
        ax.plot(path[:, 1], path[:, 2], lw=1, label=label)
    _floor(ax, analysis)
    if analysis.people:
        ax.legend(fontsize=7, loc="best")
    ax.set_title("trajectories on the floor")
    return _png(fig)


def _areas(analysis: Analysis) -> str:
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    fig, ax = plt.subplots(figsize=(8, 6))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, key in enumerate(_people_order(analysis)[:MAX_LEGEND]):
        person = analysis.people[key]
        x0, y0, x1, y1 = person.bbox
        colour = colours[i % len(colours)]
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ec=colour, lw=1.5,
                               label=analysis.label(key)))  # fmt: skip
        if len(person.hull) >= 3:
            hull = np.vstack([person.hull, person.hull[:1]])
            ax.plot(hull[:, 0], hull[:, 1], ls=":", color=colour)
    _floor(ax, analysis)
    ax.autoscale()
    if analysis.people:
        ax.legend(fontsize=7, loc="best")
    ax.set_title("motion areas: bounding rectangles (solid) and convex hulls (dotted)")
    return _png(fig)


def _momentum(analysis: Analysis) -> str:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4))
    for i, key in enumerate(_people_order(analysis)):
        series = np.array(analysis.people[key].momentum).reshape(-1, 2)
        label = analysis.label(key) if i < MAX_LEGEND else None
        ax.plot(series[:, 0] - analysis.start, series[:, 1], label=label)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("trajectory length (m)")
    ax.set_title("momentum: distance walked so far")
    ax.grid(True, alpha=0.3)
    if analysis.people:
        ax.legend(fontsize=7, loc="best")
    return _png(fig)


def _distances(analysis: Analysis) -> str:
    import matplotlib.pyplot as plt

    pairs = [p for p in analysis.pairs.values() if len(p.series)]
    pairs.sort(key=lambda p: p.mean_m)
    keys = _people_order(analysis)[:20]
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    for pair in pairs[:MAX_DISTANCE_PAIRS]:
        label = f"{analysis.label(pair.a)} - {analysis.label(pair.b)}"
        axes[0].plot(pair.series[:, 0] - analysis.start, pair.series[:, 1], label=label)
    axes[0].set_xlabel("time (s)")
    axes[0].set_ylabel("distance (m)")
    axes[0].set_title("the closest pairs over time")
    axes[0].grid(True, alpha=0.3)
    if pairs:
        axes[0].legend(fontsize=7)
    matrix = np.full((len(keys), len(keys)), np.nan)
    for i, a in enumerate(keys):
        for j, b in enumerate(keys):
            pair = analysis.pairs.get((min(a, b), max(a, b)))
            if pair is not None:
                matrix[i, j] = pair.mean_m
    image = axes[1].imshow(matrix, cmap="viridis_r")
    axes[1].set_xticks(
        range(len(keys)), [analysis.label(k) for k in keys], rotation=90, fontsize=6
    )
    axes[1].set_yticks(range(len(keys)), [analysis.label(k) for k in keys], fontsize=6)
    axes[1].set_title("mean distance between people (m)")
    fig.colorbar(image, ax=axes[1])
    return _png(fig)


def _skipped_note(analysis: Analysis) -> str:
    if not analysis.pair_frames_skipped:
        return ""
    return (
        f'<p class="note">{analysis.pair_frames_skipped} frames had too many people for '
        "pairwise distances and were left out of them.</p>"
    )


def _heatmap(analysis: Analysis) -> str:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 6))
    grid = analysis.heatmap
    if grid.size:
        x0, y0 = analysis.heatmap_origin
        extent = (
            x0,
            x0 + grid.shape[1] * analysis.cell_m,
            y0,
            y0 + grid.shape[0] * analysis.cell_m,
        )
        image = ax.imshow(grid, origin="lower", extent=extent, cmap="magma")
        fig.colorbar(image, ax=ax, label="person-seconds per cell")
    _floor(ax, analysis)
    ax.set_title(f"occupancy ({analysis.cell_m:g} m cells)")
    return _png(fig)


def _places(analysis: Analysis) -> str:
    import matplotlib.pyplot as plt

    if not analysis.zones:
        return ""
    fig, ax = plt.subplots(figsize=(8, 3.5))
    names = [z.name for z in analysis.zones]
    totals = [sum(z.dwell_s.values()) / 60.0 for z in analysis.zones]
    ax.bar(names, totals, color="tab:green")
    ax.set_ylabel("person-minutes")
    ax.set_title("time spent in each zone")
    return _png(fig)


def _speed(analysis: Analysis) -> str:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 3.5))
    edges = [f"{a:g}-{b:g}" if np.isfinite(b) else f">{a:g}"
             for a, b in itertools.pairwise(SPEED_BINS_MPS)]  # fmt: skip
    total = np.zeros(len(edges))
    for person in analysis.people.values():
        total += np.array(person.speed_histogram_s)
    share = total / total.sum() if total.sum() > 0 else total
    ax.bar(edges, 100 * share, color="tab:blue")
    ax.set_xlabel("speed (m/s)")
    ax.set_ylabel("% of time, everyone")
    ax.set_title("how fast people move")
    return _png(fig)


def write_report(
    analysis: Analysis, path: Path, *, title: str = "openptrack_py analysis", source: str = ""
) -> Path:
    """Write the report of ``analysis`` to ``path`` (HTML, self-contained); return it."""
    import matplotlib

    matplotlib.use("Agg")
    tables = analysis.tables()
    generated = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    span = f"{analysis.duration_s:.0f} s, {len(analysis.people)} people, {analysis.frames} frames"
    body = {
        "people": _table(tables["people"], "nobody was tracked"),
        "trajectories": _trajectories(analysis),
        "areas": _areas(analysis),
        "momentum": _momentum(analysis),
        "distances": _distances(analysis)
        + _table(
            sorted(tables["pairs"], key=lambda r: r["mean_m"])[:40],  # type: ignore[arg-type,return-value]
            "no two people were seen together",
        ),
        "heatmap": _heatmap(analysis),
        "places": _places(analysis)
        + _table(tables["zones"], "no zones in the network file")
        + _table(tables["doors"], "no doors in the network file"),
        "speed": _speed(analysis),
    }
    nav = " ".join(f'<a href="#{sid}">{html.escape(name)}</a>' for sid, name in SECTIONS)
    sections = "\n".join(
        f'<section id="{sid}"><h2>{html.escape(name)}</h2>\n{body[sid]}</section>'
        for sid, name in SECTIONS
    )
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>{_STYLE}</style></head>
<body><h1>{html.escape(title)}</h1>
<p class="note">{html.escape(source)} &middot; {html.escape(span)} &middot; {generated}</p>
<nav>{nav}</nav>
{sections}
</body></html>
"""
    path = Path(path)
    path.write_text(page, encoding="utf-8")
    return path
