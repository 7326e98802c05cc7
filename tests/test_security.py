"""A secured site: mutual TLS and access control between real processes.

A tracker and an output node run as real processes with ``security:`` on; the test is
the sensors, the operator and the attackers, each a Zenoh session with its own
certificate (or none). Sensor ``c`` is switched off, so a fake person put on its key
would be confirmed if it got through (it is, with access control off). The legitimate
network must run (a walking person tracked and sent over UDP) while every attack is
refused: a peer without a certificate, a peer with a certificate from another authority,
and a sensor's certificate putting another sensor's detections, tracks, or a
configuration change.
"""

from __future__ import annotations

import json
import math
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from openptrack_py.calibration.files import (
    SensorCalibration,
    entry_payload,
    parse_entry_payload,
)
from openptrack_py.config import Pose, ZenohConfig, load_network
from openptrack_py.errors import ConfigError
from openptrack_py.messages import (
    Detection,
    DetectionBatch,
    Track,
    TrackBatch,
    encode_detection_batch,
    encode_track_batch,
)
from openptrack_py.security import pki
from openptrack_py.security.policy import access_control, identities, session_settings
from openptrack_py.transport.zenoh_bus import ZenohBus
from tests.conftest import ROOT, free_port, python_env, stop_process, wait_for

NETWORK = """\
site: default
zenoh: {{hub: null, listen: ["tls/127.0.0.1:0"]}}
stats_interval_s: 0.5
security: {{certs: {certs}}}
calibration: {certs}/calibration.yaml
sensors:
  - {{id: a, source: camera, pose: {{x: 0.0, y: 0.0}}}}
  - {{id: b, source: camera, pose: {{x: 8.0, y: 0.0, yaw_deg: 180}}}}
  - {{id: c, source: camera, pose: {{x: 0.0, y: 0.0}}}}
tracker: {{reorder_window_s: 0.0}}
outputs:
  - name: output
    udp: [{{host: 127.0.0.1, port: {udp}}}]
"""

FAKE_ID = 4242
"""Id of the track an attacker puts straight on the tracks key."""


def person_at(t: float) -> tuple[float, float]:
    """The real person: a 1.5 m circle around (4, 3), once every 8 s."""
    return 4.0 + 1.5 * math.cos(t * math.pi / 4), 3.0 + 1.5 * math.sin(t * math.pi / 4)


GHOST = (2.0, -0.5)
"""Where the attackers put their fake person: in sensor a's view, 2 m from the real one."""


def _batch(sensor: str, k: int, x: float, y: float) -> bytes:
    det = Detection(x=x, y=y, z=0.9, height=1.7, confidence=0.95, distance=4.0)
    return encode_detection_batch(DetectionBatch(sensor, k, time.time(), "world", (det,)))


# ----------------------------------------------------------------------- unit level


def test_certificates_are_signed_by_the_site_and_name_their_identity(tmp_path: Path) -> None:
    pki.create_authority(tmp_path, "gallery")
    pki.issue(tmp_path, "tracker", ["master", "192.168.1.10"])
    (info,) = pki.describe(tmp_path)
    assert info.name == "tracker" and info.signed_by_site
    assert {"localhost", "127.0.0.1", "master", "192.168.1.10"} <= set(info.hosts)
    assert (tmp_path / "tracker.key").stat().st_mode & 0o077 == 0  # the key is private
    with pytest.raises(ConfigError, match="exists"):
        pki.issue(tmp_path, "tracker")
    with pytest.raises(ConfigError, match="invalidate"):
        pki.create_authority(tmp_path, "gallery")
    other = tmp_path / "other"
    pki.create_authority(other, "elsewhere")
    pki.issue(other, "tracker")
    (other / "tracker.pem").replace(tmp_path / "stranger.pem")  # sorted before tracker.pem
    assert [i.signed_by_site for i in pki.describe(tmp_path)] == [False, True]


def test_the_access_list_gives_each_identity_only_its_own_keys(tmp_path: Path) -> None:
    net = tmp_path / "net.yaml"
    net.write_text(NETWORK.format(certs=tmp_path, udp=21234))
    cfg = load_network(net)
    assert identities(cfg) == [
        "launcher", "detector_a", "detector_b", "detector_c", "tracker", "calibration",
        "output", "operator",
    ]  # fmt: skip
    acl = access_control(cfg)
    assert acl["enabled"] and acl["default_permission"] == "deny"
    rules = {r["id"]: r for r in acl["rules"]}
    subject_names = {s["id"]: s["cert_common_names"] for s in acl["subjects"]}
    puts: dict[str, list[str]] = {}
    for policy in acl["policies"]:
        for subject in policy["subjects"]:
            for rule in policy["rules"]:
                r = rules[rule]
                if "put" in r["messages"] and "ingress" in r["flows"]:
                    for name in subject_names[subject]:
                        puts.setdefault(name, []).extend(r["key_exprs"])
    assert "opt/default/detections/a" in puts["detector_a"]
    assert "opt/default/detections/b" not in puts["detector_a"]
    assert not any("tracks" in k or k[-8:] == "config/*" for k in puts["detector_a"])
    assert "opt/default/tracks" in puts["tracker"]
    assert "opt/default/config/*" in puts["operator"]
    assert [n for n, keys in puts.items() if "opt/default/config/*" in keys] == ["operator"]
    assert [n for n, keys in puts.items() if "opt/default/tracks" in keys] == ["tracker"]
    calibration = [n for n, keys in puts.items() if "opt/default/calibration/*" in keys]
    assert calibration == ["calibration"]
    # a calibration session: a sensor's board node reports that sensor's board only,
    # and only an operator shows the session's progress
    assert [n for n, keys in puts.items() if "opt/default/board/a" in keys] == ["detector_a"]
    progress = [n for n, keys in puts.items() if "opt/default/board_progress" in keys]
    assert progress == ["operator"]


def test_security_needs_tls_endpoints_and_the_identitys_files(tmp_path: Path) -> None:
    net = tmp_path / "net.yaml"
    net.write_text(NETWORK.format(certs=tmp_path, udp=21234).replace("tls/", "tcp/"))
    with pytest.raises(ConfigError, match=r"tls/.*zenoh\.listen\.0 \(tcp/127\.0\.0\.1:0\)"):
        load_network(net)
    net.write_text(NETWORK.format(certs=tmp_path, udp=21234))
    cfg = load_network(net)
    with pytest.raises(ConfigError, match=r"copy the site's ca\.pem"):
        session_settings(cfg, "tracker")
    pki.create_authority(tmp_path, "default")
    with pytest.raises(ConfigError, match=r"tracker\.pem.*openptrack certs issue"):
        session_settings(cfg, "tracker")


# ---------------------------------------------------------------- real processes


@dataclass
class Site:
    """The secured network's files and processes, and the test's view of the UDP output."""

    certs: Path
    net: Path
    tracker_endpoint: str
    output_endpoint: str
    procs: list[subprocess.Popen[str]]
    udp: socket.socket
    frames: list[tuple[float, dict]] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)
    stop: threading.Event = field(default_factory=threading.Event)

    def bus(
        self,
        identity: str | None,
        endpoint: str,
        *,
        certs: Path | None = None,
        listen: tuple[str, ...] = (),
    ) -> ZenohBus:
        """A session authenticated as ``identity`` (``None``: no certificate at all)."""
        cfg = load_network(self.net)
        if identity is None:
            return ZenohBus(ZenohConfig(hub=None, connect=[endpoint], listen=[]))
        if certs is not None:
            cfg = cfg.model_copy(
                update={"security": cfg.security.model_copy(update={"certs": certs})}
            )
        zcfg = ZenohConfig(hub=None, connect=[endpoint], listen=list(listen))
        return ZenohBus(zcfg, settings=session_settings(cfg, identity))

    def receive(self) -> None:
        while not self.stop.is_set():
            try:
                data = self.udp.recv(65536)
            except TimeoutError:
                continue
            except OSError:
                return
            msg, _ = json.JSONDecoder().raw_decode(data.split(b"\0", 1)[0].decode())
            if "people_tracks" in msg:
                with self.lock:
                    self.frames.append((time.time(), msg))

    def udp_ids_since(self, since: float) -> set[int]:
        """Track ids the UDP output sent after ``since``."""
        with self.lock:
            return {p["id"] for t, m in self.frames if t >= since for p in m["people_tracks"]}

    def udp_near_since(self, since: float, x: float, y: float) -> bool:
        """Whether the UDP output sent a track within 0.6 m of ``(x, y)`` after ``since``."""
        with self.lock:
            frames = [m for t, m in self.frames if t >= since]
        return any(
            math.hypot(p["x"] - x, p["y"] - y) < 0.6 for m in frames for p in m["people_tracks"]
        )

    def configure(self, identity: str, change: str) -> subprocess.CompletedProcess[str]:
        """``openptrack config tracker CHANGE`` authenticated as ``identity``."""
        return subprocess.run(
            [sys.executable, "-m", "openptrack_py.cli", "config", "tracker", change,
             "-c", str(self.net), "-e", self.tracker_endpoint, "--identity", identity,
             "--timeout", "3"],
            capture_output=True, text=True, env=python_env(), cwd=ROOT, timeout=60,
        )  # fmt: skip


def _node(module: str, net: Path, endpoint: str, log: Path, *extra: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", module, "-c", str(net), "-l", endpoint, *extra],
        stdout=log.open("w"), stderr=subprocess.STDOUT, text=True, env=python_env(), cwd=ROOT,
    )  # fmt: skip


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Site]:
    tmp = tmp_path_factory.mktemp("secured")
    certs = tmp / "certs"
    udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    udp.bind(("127.0.0.1", 0))
    udp.settimeout(0.2)
    net = tmp / "net.yaml"
    net.write_text(NETWORK.format(certs=certs, udp=udp.getsockname()[1]))
    pki.create_authority(certs, "default")
    for name in identities(load_network(net)):
        pki.issue(certs, name)
    tracker_ep = f"tls/127.0.0.1:{free_port()}"
    output_ep = f"tls/127.0.0.1:{free_port()}"
    procs = [
        _node("openptrack_py.nodes.tracker", net, tracker_ep, tmp / "tracker.log"),
        _node("openptrack_py.nodes.output", net, output_ep, tmp / "output.log",
              "--name", "output", "-e", tracker_ep),
    ]  # fmt: skip
    s = Site(certs, net, tracker_ep, output_ep, procs, udp)
    receiver = threading.Thread(target=s.receive, daemon=True)
    receiver.start()
    sensor = s.bus("detector_a", tracker_ep)
    pub = sensor.publisher("opt/default/detections/a")

    def sense() -> None:
        k = 0
        while not s.stop.is_set():
            pub.put(_batch("a", k, *person_at(time.time())))
            k += 1
            time.sleep(1 / 30)

    feeder = threading.Thread(target=sense, daemon=True)
    feeder.start()
    try:
        now = time.time()
        wait_for(
            lambda: s.udp_near_since(now, *person_at(time.time())),
            45,
            "the real person's track over UDP (logs: "
            + (tmp / "tracker.log").read_text()[-2000:]
            + (tmp / "output.log").read_text()[-2000:]
            + ")",
        )
        yield s
    finally:
        s.stop.set()
        feeder.join(2)
        sensor.close()
        stop_process(*procs)
        udp.close()
        receiver.join(2)


def _flood(bus: ZenohBus, key: str, payload: object, seconds: float = 2.0) -> None:
    pub = bus.publisher(key)
    end = time.time() + seconds
    k = 0
    while time.time() < end:
        pub.put(payload(k) if callable(payload) else payload)  # type: ignore[arg-type]
        k += 1
        time.sleep(1 / 30)
    pub.close()


@pytest.mark.zenoh
@pytest.mark.slow
@pytest.mark.parametrize("who", ["no certificate", "another authority's certificate"])
def test_a_peer_the_site_did_not_certify_cannot_connect(
    site: Site, who: str, tmp_path: Path
) -> None:
    if who == "no certificate":
        endpoints = [site.tracker_endpoint, site.tracker_endpoint.replace("tls/", "tcp/")]
        buses = [site.bus(None, e) for e in endpoints]
    else:
        rogue = tmp_path / "rogue"
        pki.create_authority(rogue, "default")
        pki.issue(rogue, "detector_c")  # the right name, the wrong authority
        buses = [site.bus("detector_c", site.tracker_endpoint, certs=rogue)]
    since = time.time()
    try:
        for bus in buses:
            assert bus.peers() == []
            _flood(bus, "opt/default/detections/c", lambda k: _batch("c", k, *GHOST), 2.0)
        time.sleep(1.0)
        assert not site.udp_near_since(since, *GHOST)
        assert site.udp_near_since(since, *person_at(time.time() - 0.5))
    finally:
        for bus in buses:
            bus.close()


@pytest.mark.zenoh
@pytest.mark.slow
def test_a_sensor_may_put_only_its_own_detections(site: Site) -> None:
    since = time.time()
    with site.bus("detector_b", site.tracker_endpoint) as bus:
        assert bus.peers(), "sensor b's own certificate must be accepted"
        _flood(bus, "opt/default/detections/c", lambda k: _batch("c", k, *GHOST), 3.0)
    time.sleep(0.5)
    assert not site.udp_near_since(since, *GHOST)
    assert site.udp_near_since(since, *person_at(time.time() - 0.5))


@pytest.mark.zenoh
@pytest.mark.slow
def test_a_sensor_cannot_put_tracks(site: Site) -> None:
    fake = Track(
        id=FAKE_ID, x=GHOST[0], y=GHOST[1], z=0.9, height=1.7, vx=0.0, vy=0.0, age=9.0,
        confidence=1.0,
    )  # fmt: skip

    def batch(k: int) -> bytes:
        return encode_track_batch(
            TrackBatch(time.time(), 10**6 + k, "world", (fake,), (FAKE_ID,), FAKE_ID)
        )

    since = time.time()
    with site.bus("detector_b", site.output_endpoint) as bus:
        assert bus.peers()
        _flood(bus, "opt/default/tracks", batch, 2.0)
    time.sleep(0.5)
    assert FAKE_ID not in site.udp_ids_since(since)
    assert site.udp_ids_since(since), "the real tracks must keep flowing"


@pytest.mark.zenoh
@pytest.mark.slow
def test_only_an_operator_may_change_the_configuration(site: Site) -> None:
    refused = site.configure("detector_b", "max_tracks=1")
    assert refused.returncode != 0
    assert "did not answer" in refused.stderr + refused.stdout
    accepted = site.configure("operator", "max_tracks=150")
    assert accepted.returncode == 0, accepted.stderr
    assert "applied max_tracks=150" in accepted.stdout
    since = time.time()
    wait_for(lambda: site.udp_near_since(since, *person_at(time.time() - 0.3)), 5, "tracks")


def test_certs_command_makes_what_a_network_needs(tmp_path: Path) -> None:
    def certs(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-m", "openptrack_py.cli", "certs", *args],
            capture_output=True, text=True, env=python_env(), cwd=ROOT, timeout=60,
        )  # fmt: skip

    folder = tmp_path / "certs"
    net = tmp_path / "net.yaml"
    net.write_text(NETWORK.format(certs=folder, udp=21234))
    assert certs("issue", str(folder), "tracker").returncode == 2  # no authority yet
    assert certs("init", str(folder), "--site", "default").returncode == 0
    again = certs("init", str(folder))
    assert again.returncode == 2 and "invalidate" in again.stderr
    made = certs("issue", str(folder), "--network", str(net), "--host", "master")
    assert made.returncode == 0, made.stderr
    assert made.stdout.count("issued") == len(identities(load_network(net)))
    kept = certs("issue", str(folder), "--network", str(net))
    assert kept.returncode == 0 and "every identity" in kept.stdout  # nothing new to issue
    assert certs("issue", str(folder), "../escape").returncode == 2
    listing = certs("list", str(folder)).stdout.splitlines()
    assert len(listing) == 8 and all(line.endswith("ok") for line in listing)
    assert all("master" in line for line in listing)
    for name in identities(load_network(net)):
        session_settings(load_network(net), name)  # every identity's files are there


def test_client_mode_and_borrowed_node_names_are_refused(tmp_path: Path) -> None:
    text = NETWORK.format(certs=tmp_path, udp=21234)
    net = tmp_path / "net.yaml"
    net.write_text(text.replace("zenoh: {hub: null,", "zenoh: {mode: client, hub: null,"))
    with pytest.raises(ConfigError, match=r"zenoh\.mode must be 'peer'"):
        load_network(net)
    for name in ("tracker", "detector_a"):  # an output's certificate would get their rights
        net.write_text(text.replace("- name: output", f"- name: {name}"))
        with pytest.raises(ConfigError, match="other nodes' names"):
            load_network(net)


@pytest.mark.zenoh
@pytest.mark.slow
def test_a_node_announces_only_its_own_liveliness(site: Site) -> None:
    sensor_endpoint = f"tls/127.0.0.1:{free_port()}"
    with site.bus("detector_b", site.tracker_endpoint, listen=(sensor_endpoint,)) as sensor:
        fake = sensor.declare_token("opt/default/alive/sim")  # no simulator runs here
        own = sensor.declare_token("opt/default/alive/detector_b")
        # the operator links to the sensor directly (peers do not route for each other)
        with site.bus("operator", sensor_endpoint) as operator:
            seen = operator.alive("opt/default/alive/*", timeout_s=1.5)
        fake.close()
        own.close()
    assert "opt/default/alive/tracker" in seen  # the real nodes are seen alive (gossip)
    assert "opt/default/alive/detector_b" in seen  # and the sensor's own token
    assert "opt/default/alive/sim" not in seen


def _calibration_xs(bus: ZenohBus) -> set[float]:
    """The x of every valid entry for sensor a that answers a calibration query."""
    xs = set()
    for sample in bus.query("opt/default/calibration/a", timeout_s=1.0):
        _, entry = parse_entry_payload(sample.payload)
        xs.add(entry.as_pose().x)
    return xs


@pytest.mark.zenoh
@pytest.mark.slow
def test_only_the_calibration_node_may_answer_or_update_the_calibration(site: Site) -> None:
    """A sensor's certificate can neither answer calibration queries nor publish updates."""
    true = entry_payload("a", SensorCalibration(pose=Pose(x=1.0)))
    forged = entry_payload("a", SensorCalibration(pose=Pose(x=9.0)))
    impostor_ep, server_ep = (f"tls/127.0.0.1:{free_port()}" for _ in range(2))
    updates: list[bytes] = []
    with site.bus("detector_b", site.tracker_endpoint, listen=(impostor_ep,)) as impostor:
        impostor.serve("opt/default/calibration/*", lambda _key, _payload: forged)
        with site.bus("detector_a", impostor_ep) as asker:
            asker.subscribe("opt/default/calibration/a", lambda s: updates.append(s.payload))
            assert asker.peers(), "sensor a's own certificate must be accepted"
            time.sleep(1.0)
            assert _calibration_xs(asker) == set()  # the forged answer never arrives
            _flood(impostor, "opt/default/calibration/a", forged, 1.0)
            assert updates == []
    with site.bus("calibration", site.tracker_endpoint, listen=(server_ep,)) as server:
        server.serve("opt/default/calibration/*", lambda _key, _payload: true)
        with site.bus("detector_a", server_ep) as asker:
            asker.subscribe("opt/default/calibration/a", lambda s: updates.append(s.payload))
            wait_for(lambda: _calibration_xs(asker) == {1.0}, 15, "the calibration node's answer")
            _flood(server, "opt/default/calibration/a", true, 1.0)
            assert updates and set(updates) == {true}
