"""The Zenoh settings of a secured site: mutual TLS and the access-control list.

Every node loads the same list, built from the network file, and Zenoh enforces it on
every message a node *receives* (the ``ingress`` flow), matching the sender by the
common name of the certificate its link was authenticated with. A message a node may
not receive is dropped by Zenoh before it reaches our code. The list:

* every identity of the site (:func:`identities`) may subscribe and watch liveliness
  under ``opt/<site>/``, and may *send* anything (the receiver decides);
* each identity may put its own stats (``stats/<name>``) and its own configuration
  answers (``config/<name>/ack``), and announce only its own liveliness token
  (``alive/<name>``), so no certificate can make a dead node look alive;
* a sensor's detector may put that sensor's detections and board reports only (the
  board node of a calibration session runs under its name), the simulator those of
  the simulated sensors and the ground truth; the tracker the tracks; an output node
  its smoothed tracks; an operator (``security.operators``) configuration requests and
  the progress of a board session;
* the calibration node may put calibration updates, declare the calibration queryable
  and reply to it; every member may ask it;
* everything else is refused (``default_permission: deny``), other queries and replies
  included, so a peer without a certificate of the site's
  authority cannot even connect, and one with a certificate can do only what its name
  allows.

Members are not hidden from each other: any certificate of the site may subscribe to
every key of the site.
"""

from __future__ import annotations

from typing import Any

from openptrack_py.config import NetworkConfig
from openptrack_py.config.network import (
    CALIBRATION,
    LAUNCHER,
    OPERATOR,
    RECORDER,
    SIM,
    TRACKER,
    detector_node_name,
)
from openptrack_py.security.pki import Identity
from openptrack_py.transport.keys import SiteKeys

MEMBER = "member"
"""Subject id of every identity of the site."""
INFRASTRUCTURE = ("declare_subscriber", "declare_liveliness_subscriber", "liveliness_query")
"""Messages every member may exchange: they read, they do not write data."""


def put_keys(network: NetworkConfig) -> dict[str, list[str]]:
    """Identity -> the keys it may put, for every node identity of the network."""
    keys = SiteKeys(network.site)
    allowed: dict[str, list[str]] = {LAUNCHER: []}
    if network.sim is not None:
        simulated = [keys.detections(s.id) for s in network.sensors if s.source == "sim"]
        if network.sim.use_scenario_sensors or not simulated:
            # the scenario's own sensors (the rule of sim.live.scenario_from_network):
            # their ids are known only to the simulator
            simulated = [keys.detections("*")]
        rendered = network.sim.sensor_model == "rgbd"
        allowed[SIM] = [keys.ground_truth, *([] if rendered else simulated)]
    for sensor in network.sensors:
        if sensor.source != "sim" or (
            network.sim is not None and network.sim.sensor_model == "rgbd"
        ):
            allowed[detector_node_name(sensor.id)] = [
                keys.detections(sensor.id),
                keys.board(sensor.id),  # the board node runs under the detector's name
            ]
    if network.tracker is not None:
        allowed[TRACKER] = [keys.tracks]
    if network.calibrated:
        allowed[CALIBRATION] = [keys.calibration("*")]
    for out in network.outputs:
        allowed[out.name] = [keys.tracks_smoothed]
    if network.recorder is not None:
        allowed[RECORDER] = []
    operators = network.security.operators if network.security is not None else [OPERATOR]
    for name in operators:
        allowed.setdefault(name, []).extend([keys.config("*"), keys.board_progress])
    for name, own in allowed.items():
        own += [keys.stats(name), keys.config_ack(name)]
    return allowed


def identities(network: NetworkConfig) -> list[str]:
    """Every identity a secured network needs a certificate for."""
    return list(put_keys(network))


def access_control(network: NetworkConfig) -> dict[str, Any]:
    """The ``access_control`` section of every node's Zenoh configuration."""
    keys = SiteKeys(network.site)
    everything = f"{keys.prefix}/**"
    allowed = put_keys(network)
    rules: list[dict[str, Any]] = [
        {
            "id": "read",
            "permission": "allow",
            "flows": ["ingress", "egress"],
            "messages": list(INFRASTRUCTURE),
            "key_exprs": [everything],
        },
        {
            "id": "send",
            "permission": "allow",
            "flows": ["egress"],
            "messages": [
                "put",
                "delete",
                "liveliness_token",
                "query",
                "declare_queryable",
                "reply",
            ],
            "key_exprs": [everything],
        },
        {
            "id": "ask-calibration",
            "permission": "allow",
            "flows": ["ingress"],
            "messages": ["query"],
            "key_exprs": [keys.calibration("*")],
        },
    ]
    subjects: list[dict[str, Any]] = [{"id": MEMBER, "cert_common_names": list(allowed)}]
    policies: list[dict[str, Any]] = [
        {"rules": ["read", "send", "ask-calibration"], "subjects": [MEMBER]}
    ]
    for index, (name, put) in enumerate(allowed.items()):
        rule, token, subject = f"put-{index}", f"alive-{index}", f"id-{index}"
        rules.append(
            {
                "id": rule,
                "permission": "allow",
                "flows": ["ingress"],
                "messages": ["put"],
                "key_exprs": put,
            }
        )
        rules.append(
            {
                "id": token,
                "permission": "allow",
                "flows": ["ingress"],
                "messages": ["liveliness_token"],
                "key_exprs": [keys.alive(name)],
            }
        )
        subjects.append({"id": subject, "cert_common_names": [name]})
        policies.append({"rules": [rule, token], "subjects": [subject]})
    if CALIBRATION in allowed:
        rules.append(
            {
                "id": "serve-calibration",
                "permission": "allow",
                "flows": ["ingress"],
                "messages": ["declare_queryable", "reply"],
                "key_exprs": [keys.calibration("*")],
            }
        )
        subjects.append({"id": "id-serve", "cert_common_names": [CALIBRATION]})
        policies.append({"rules": ["serve-calibration"], "subjects": ["id-serve"]})
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    }


def session_settings(network: NetworkConfig, identity: str) -> dict[str, Any]:
    """Zenoh configuration entries (path -> value) of a secured session for ``identity``.

    Empty when the network has no ``security`` section.

    Raises
    ------
    ConfigError
        If a certificate file of ``identity`` is missing (naming it and the command that
        makes it).
    """
    sec = network.security
    if sec is None:
        return {}
    files = Identity(sec.certs, identity)
    files.check()
    tls = {
        "root_ca_certificate": str(files.authority.resolve()),
        "listen_private_key": str(files.key.resolve()),
        "listen_certificate": str(files.certificate.resolve()),
        "connect_private_key": str(files.key.resolve()),
        "connect_certificate": str(files.certificate.resolve()),
        "enable_mtls": True,
        "verify_name_on_connect": sec.verify_names,
    }
    return {"transport/link/tls": tls, "access_control": access_control(network)}
