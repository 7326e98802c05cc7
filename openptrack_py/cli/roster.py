"""``openptrack roster``: register people by name from a running tracker.

``openptrack roster add NAME --track ID`` asks the running tracker to capture that
track's looks (its colour signature, its height and, where the sensors send them, its
identity embedding) into the roster file; ``roster list`` and ``roster remove NAME`` read and
change the same file, through the tracker, so the command works from any machine of
the site. The tracker names tracks from the roster (``face_name`` in OpenPTrack UDP
JSON, ``identity`` elsewhere) once their evidence passes its threshold.
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from openptrack_py.cli.common import EXIT_CONFIG, start_logging
from openptrack_py.runtime.args import add_common_arguments

if TYPE_CHECKING:
    from openptrack_py.cli.common import Subparsers


def add_parser(subparsers: Subparsers) -> None:
    """Register ``roster``, its actions and :func:`run`."""
    p = subparsers.add_parser(
        "roster",
        help="register named people (identity), list or remove them",
        description="Register a person seen by the running tracker under a name "
        "('openptrack roster add Ada --track 12'), list the registered people, or remove "
        "one. Needs tracker.identity.enabled and tracker.identity.roster_file. Exit "
        "status: 0 done, 2 refused, 1 no answer.",
    )
    p.add_argument("action", choices=("add", "list", "remove"))
    p.add_argument("name", nargs="?", help="the person's name (add, remove)")
    p.add_argument("--track", type=int, help="id of the person's track (add)")
    add_common_arguments(p)
    p.add_argument("--timeout", type=float, default=10.0, help="seconds to wait for the tracker")
    p.add_argument("--format", choices=("text", "json"), default="text")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Send the request to the tracker, print its answer; return the exit status."""
    import orjson

    from openptrack_py.cli.configure import ask_node
    from openptrack_py.config.network import TRACKER
    from openptrack_py.tracking.roster_service import roster_request

    start_logging(args)
    if args.action in ("add", "remove") and not args.name:
        print(f"openptrack roster {args.action}: a NAME is needed", file=sys.stderr)
        return EXIT_CONFIG
    if args.action == "add" and args.track is None:
        print("openptrack roster add: --track ID is needed", file=sys.stderr)
        return EXIT_CONFIG
    body = roster_request(args.action, args.name, args.track if args.action == "add" else None)
    ack = ask_node(args, TRACKER, body)
    if ack is None:
        return 1
    if not ack.accepted:
        print(f"openptrack roster: the tracker refused: {ack.error}", file=sys.stderr)
        return EXIT_CONFIG
    people = ack.config.get("roster", [])
    if args.format == "json":
        print(orjson.dumps(people).decode())
    elif args.action == "list":
        for person in people:
            height = f"{person['height']:.2f} m" if person.get("height") else "no height"
            seen = f"{person['observations']} observations"
            print("\t".join((person["name"], seen, height, person["added"])))
        if not people:
            print("(nobody registered)")
    else:
        print(f"roster: {args.action} {args.name}: done ({len(people)} registered)")
    return 0
