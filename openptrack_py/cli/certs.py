"""``openptrack certs``: the site's certificate authority and its nodes' certificates.

::

    openptrack certs init certs/ --site gallery          # the authority: ca.pem, ca.key
    openptrack certs issue certs/ --network gallery.yaml # every identity the network needs
    openptrack certs issue certs/ operator --host laptop # one more identity
    openptrack certs list certs/                         # names, hosts, expiry
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from openptrack_py.cli.common import EXIT_CONFIG

if TYPE_CHECKING:
    from openptrack_py.cli.common import Subparsers


def add_parser(subparsers: Subparsers) -> None:
    """Register ``certs`` with its ``init``, ``issue`` and ``list`` actions."""
    p = subparsers.add_parser(
        "certs",
        help="make the site's certificate authority and its nodes' certificates",
        description="Certificates for a network with a 'security' section: the site's "
        "authority signs one certificate per identity (node name or 'operator').",
    )
    actions = p.add_subparsers(dest="action", required=True, metavar="ACTION")
    init = actions.add_parser("init", help="make the site's authority (ca.pem, ca.key)")
    init.add_argument("folder", type=Path)
    init.add_argument("--site", default="default", help="site name written in the authority")
    init.add_argument("--force", action="store_true", help="replace an existing authority")
    issue = actions.add_parser("issue", help="issue certificates signed by the authority")
    issue.add_argument("folder", type=Path)
    issue.add_argument("names", nargs="*", help="identities (node names, 'operator')")
    issue.add_argument(
        "--network", help="also every identity this network file needs (existing ones kept)"
    )
    issue.add_argument(
        "--host",
        dest="hosts",
        action="append",
        default=[],
        help="host name or address the certificate names (repeatable)",
    )
    issue.add_argument("--days", type=int, default=825, help="validity in days")
    issue.add_argument("--force", action="store_true", help="issue existing names again")
    listing = actions.add_parser("list", help="the certificates of a folder")
    listing.add_argument("folder", type=Path)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Carry out the action; a ConfigError (missing authority, existing file) ends it."""
    from openptrack_py.security import pki

    if args.action == "init":
        path = pki.create_authority(args.folder, args.site, overwrite=args.force)
        print(f"authority: {path} (keep {path.with_suffix('.key')} on this machine only)")
        return 0
    if args.action == "list":
        for info in pki.describe(args.folder):
            mark = "ok" if info.signed_by_site else "NOT SIGNED BY THIS SITE"
            hosts = ",".join(info.hosts)
            print(f"{info.name:24s} until {info.not_after:%Y-%m-%d}  {hosts}  {mark}")
        return 0
    names = list(args.names)
    if args.network:
        from openptrack_py.config import load_network
        from openptrack_py.runtime.args import resolve_config_path
        from openptrack_py.security.policy import identities

        wanted = identities(load_network(resolve_config_path(args.network)))
        missing = [
            n
            for n in wanted
            if args.force or not pki.Identity(args.folder, n).certificate.exists()
        ]
        if not missing and not names:
            print(f"every identity of {args.network} has its certificate in {args.folder}")
            return 0
        names += missing
    if not names:
        print(
            "openptrack certs issue: nothing to issue (name identities or give --network)",
            file=sys.stderr,
        )
        return EXIT_CONFIG
    for name in dict.fromkeys(names):
        identity = pki.issue(args.folder, name, args.hosts, days=args.days, overwrite=args.force)
        print(f"issued {identity.certificate} and {identity.key}")
    return 0
