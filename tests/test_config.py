"""Tests for openptrack_py.config: network files, overrides, error messages."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest
import yaml
from pydantic import ValidationError

from openptrack_py.config import (
    NetworkConfig,
    SensorConfig,
    ZenohConfig,
    apply_overrides,
    load_network,
    read_yaml,
    to_yaml,
    validate_config,
)
from openptrack_py.errors import ConfigError

CONFIG_DIR = Path(__file__).resolve().parent.parent / "config"
CONFIG_FILES = sorted(CONFIG_DIR.glob("*.yaml"))
DEMO = CONFIG_DIR / "demo.yaml"  # three sim sensors k2_a, k2_b, k2_c and a sim section
MULTI_HOST = CONFIG_DIR / "multi_host.yaml"  # two camera sensors, no sim section
CROWD = CONFIG_DIR / "crowd.yaml"  # no sensors at all

SENSOR_KEYS = (
    "calibration, clock_offset_s, clutter_per_frame, frame_drop_probability, host, id, input, "
    "latency_jitter_s, latency_s, miss_probability, pose, pose_error, rate_hz, sim_lens, source, "
    "type"
)


def _error(path: Path | None, overrides: list[str]) -> str:
    with pytest.raises(ConfigError) as info:
        load_network(path, overrides)
    return str(info.value)


def _problem_lines(message: str) -> list[str]:
    """The per-problem lines of a validation error (after the 'invalid configuration' line)."""
    first, *rest = message.splitlines()
    assert first.endswith(": invalid configuration"), message
    return [line.strip() for line in rest if not line.strip().startswith("(given by --set")]


# -------------------------------------------------------------------- shipped files


def test_shipped_config_files_exist() -> None:
    assert {p.name for p in CONFIG_FILES} >= {"demo.yaml", "crowd.yaml", "multi_host.yaml"}


@pytest.mark.parametrize("path", CONFIG_FILES, ids=[p.stem for p in CONFIG_FILES])
def test_every_shipped_config_loads(path: Path) -> None:
    config = load_network(path)
    assert isinstance(config, NetworkConfig)
    if any(s.source == "sim" for s in config.sensors):
        assert config.sim is not None


def test_demo_values_are_read_not_defaulted() -> None:
    config = load_network(DEMO)
    assert [s.id for s in config.sensors] == ["k2_a", "k2_b", "k2_c"]
    assert config.sensors[1].pose is not None
    assert config.sensors[1].pose.yaw_deg == 142.0
    assert config.sim is not None
    assert config.sim.scenario == "installation"
    multi = load_network(MULTI_HOST)
    assert multi.site == "gallery"
    assert multi.zenoh.hub == "tls/192.168.1.10:7447"
    assert multi.security is not None and multi.security.operators == ["operator"]
    assert multi.sensor("south").type == "realsense"
    assert multi.sim is None


def test_no_file_gives_defaults() -> None:
    assert load_network() == NetworkConfig()
    assert load_network().site == "default"


# --------------------------------------------------------------------- unknown keys


@pytest.mark.parametrize(
    "override, line",
    [
        (
            "sensors.0.rat=5",
            f"sensors.0.rat: unknown key; did you mean 'rate_hz'? (allowed: {SENSOR_KEYS})",
        ),
        (
            "sensros=[]",
            "sensros: unknown key; did you mean 'sensors'? (allowed: calibration, detector, "
            "doors, outputs, recorder, security, sensors, sim, site, stats_interval_s, "
            "tracker, zenoh, zones)",
        ),
        (
            "sim.sceanrio=crowd",
            "sim.sceanrio: unknown key; did you mean 'scenario'? (allowed: duration_s, "
            "embeddings, ground_truth_rate_hz, host, profile, scenario, seed, sensor_model, "
            "speed, start_time, use_scenario_sensors)",
        ),
        (
            "sensors.k2_b.pose.pich_deg=10",
            "sensors.1.pose.pich_deg: unknown key; did you mean 'pitch_deg'? "
            "(allowed: pitch_deg, roll_deg, x, y, yaw_deg, z)",
        ),
        (
            "zenoh.xyzzy=1",
            "zenoh.xyzzy: unknown key (allowed: config_file, connect, hub, hub_host, listen, "
            "mode, multicast_scouting, shared_memory)",
        ),
    ],
    ids=["sensor-key", "top-level-key", "nested-sim-key", "nested-pose-key", "no-suggestion"],
)
def test_unknown_key_names_path_suggestion_and_allowed(override: str, line: str) -> None:
    assert _problem_lines(_error(DEMO, [override])) == [line]


def test_unknown_key_in_yaml_file(tmp_path: Path) -> None:
    path = tmp_path / "net.yaml"
    path.write_text("site: a\nsensors:\n  - id: s1\n    source: camera\n    rat: 15\n")
    message = _error(path, [])
    assert message.startswith(f"{path}: invalid configuration")
    assert _problem_lines(message) == [
        f"sensors.0.rat: unknown key; did you mean 'rate_hz'? (allowed: {SENSOR_KEYS})"
    ]


# -------------------------------------------------------------------- bad values


@pytest.mark.parametrize(
    "override, line",
    [
        ("sensors.0.rate_hz=-5", "sensors.0.rate_hz: must be > 0.0 (received -5)"),
        ("sensors.1.rate_hz=0", "sensors.1.rate_hz: must be > 0.0 (received 0)"),
        ("sensors.2.rate_hz=500", "sensors.2.rate_hz: must be <= 120.0 (received 500)"),
        ("sensors.0.latency_s=-1", "sensors.0.latency_s: must be >= 0.0 (received -1)"),
        (
            "sensors.0.miss_probability=2",
            "sensors.0.miss_probability: must be <= 1.0 (received 2)",
        ),
        (
            "sensors.0.pose.pitch_deg=120",
            "sensors.0.pose.pitch_deg: must be <= 90.0 (received 120)",
        ),
        ("sim.seed=-1", "sim.seed: must be >= 0 (received -1)"),
        ("stats_interval_s=0", "stats_interval_s: must be > 0.0 (received 0)"),
        (
            "sensors.0.type=kinect3",
            "sensors.0.type: must be one of 'kinect1', 'kinect2', 'realsense' or 'sr4500' "
            "(received 'kinect3')",
        ),
        (
            "zenoh.mode=router",
            "zenoh.mode: must be one of 'peer' or 'client' (received 'router')",
        ),
        (
            "sensors.0.rate_hz=fast",
            "sensors.0.rate_hz: input should be a valid number, unable to parse string as a "
            "number (received 'fast')",
        ),
        (
            "sensors.0.id=k2/a",
            r"sensors.0.id: must match ^[A-Za-z0-9_.\-]+$ (received 'k2/a')",
        ),
        (
            "site=a*",
            r"site: must match ^[A-Za-z0-9_.\-]+$ (received 'a*')",
        ),
    ],
    ids=[
        "negative-rate",
        "zero-rate",
        "rate-too-high",
        "negative-latency",
        "miss-probability-2",
        "pitch-120",
        "negative-seed",
        "zero-stats-interval",
        "bad-sensor-type",
        "bad-zenoh-mode",
        "rate-not-a-number",
        "id-with-slash",
        "site-with-star",
    ],
)
def test_bad_value_names_key_bound_and_value(override: str, line: str) -> None:
    assert _problem_lines(_error(DEMO, [override])) == [line]


@pytest.mark.parametrize(
    "override, where, received",
    [
        ("zenoh.hub=192.168.1.10:7447", "zenoh.hub", "'192.168.1.10:7447'"),
        ("zenoh.hub=smtp/host:25", "zenoh.hub", "'smtp/host:25'"),
        ("zenoh.hub=tcp/", "zenoh.hub", "'tcp/'"),
        ("zenoh.listen=[tcp/0.0.0.0:0, bogus]", "zenoh.listen", "['tcp/0.0.0.0:0', 'bogus']"),
        ("zenoh.connect=[udp]", "zenoh.connect", "['udp']"),
    ],
    ids=["no-protocol", "unknown-protocol", "no-address", "bad-listen-item", "bad-connect"],
)
def test_bad_zenoh_endpoint(override: str, where: str, received: str) -> None:
    (line,) = _problem_lines(_error(DEMO, [override]))
    assert line.startswith(f"{where}: must be a Zenoh endpoint '<protocol>/<address>'"), line
    assert "tcp, udp, tls, quic, ws, unixsock-stream" in line
    assert line.endswith(f"(received {received})"), line


@pytest.mark.parametrize(
    "override, problem",
    [
        ("zenoh.hub=tcp/127.0.0.1:99999", "port must be in 0-65535, got 99999"),
        ("zenoh.hub=tcp/127.0.0.1", "expected host:port"),
        ("zenoh.hub=tcp/host:port", "the port must be a number"),
        ("zenoh.hub=tcp/300.1.2.3:7447", "300.1.2.3 is not an IPv4 address"),
        ("zenoh.hub=tcp/[::zz]:7447", "[::zz] is not an IPv6 address"),
        ("zenoh.connect=[tcp/no_such host:7447]", "'no_such host' is not a valid host name"),
        ("zenoh.listen=[tls/-bad-.example:7447]", "'-bad-.example' is not a valid host name"),
    ],
    ids=["port-range", "no-port", "port-text", "ipv4", "ipv6", "hostname", "listen-hostname"],
)
def test_zenoh_endpoint_address_is_checked_and_the_override_named(
    override: str, problem: str
) -> None:
    message = _error(DEMO, [override])
    (line,) = _problem_lines(message)
    assert problem in line, line
    assert message.endswith(f"(given by --set {override})"), message


@pytest.mark.parametrize(
    "endpoint",
    ["tcp/[::1]:7447", "tcp/my-host.local:0", "udp/224.0.0.224:7446#iface=eth0", "tcp/x:65535"],
)
def test_good_zenoh_endpoints_pass(endpoint: str) -> None:
    assert load_network(DEMO, [f"zenoh.hub={endpoint}"]).zenoh.hub == endpoint


def test_an_empty_network_file_is_an_error(tmp_path: Path) -> None:
    empty = tmp_path / "empty.yaml"
    empty.write_text("# nothing yet\n")
    message = _error(empty, [])
    assert "the network file is empty" in message and str(empty) in message


def test_an_unresolvable_hub_is_named_before_zenoh_starts() -> None:
    from openptrack_py.transport.zenoh_bus import check_resolvable

    cfg = load_network(DEMO, ["zenoh.hub=tcp/no-such-host.invalid:7447"]).zenoh
    with pytest.raises(ConfigError, match=r"zenoh\.hub: cannot resolve the host"):
        check_resolvable(cfg)


@pytest.mark.zenoh
def test_a_listen_endpoint_another_process_holds_is_named() -> None:
    import socket

    from openptrack_py.transport.zenoh_bus import ZenohBus

    with socket.socket() as holder:
        holder.bind(("127.0.0.1", 0))
        holder.listen()
        endpoint = f"tcp/127.0.0.1:{holder.getsockname()[1]}"
        cfg = ZenohConfig(hub=None, listen=[endpoint], multicast_scouting=False)
        with pytest.raises(ConfigError, match=rf"zenoh\.listen\.0: cannot listen on {endpoint}: "
                           "the address is already in use"):  # fmt: skip
            ZenohBus(cfg)


def test_zenoh_hub_may_be_disabled() -> None:
    assert load_network(DEMO, ["zenoh.hub=null"]).zenoh.hub is None


def test_duplicate_sensor_ids() -> None:
    lines = _problem_lines(_error(DEMO, ["sensors.2.id=k2_a"]))
    assert lines == ["(top level): sensor ids must be unique; repeated: k2_a"]


def test_sim_sensor_without_sim_section() -> None:
    lines = _problem_lines(_error(MULTI_HOST, ["sensors.south.source=sim"]))
    assert lines == ["(top level): sensors south have source 'sim' but there is no 'sim' section"]
    lines = _problem_lines(_error(DEMO, ["sim=null"]))
    assert lines == [
        "(top level): sensors k2_a, k2_b, k2_c have source 'sim' but there is no 'sim' section"
    ]


def test_pose_and_calibration_together() -> None:
    camera = ["sensors.k2_c.source=camera", "sensors.k2_c.input=realsense"]
    (line,) = _problem_lines(_error(DEMO, [*camera, "sensors.k2_c.calibration=c.yaml"]))
    assert line.startswith("sensors.2: give either 'pose' or 'calibration', not both"), line
    # Calibration alone is fine; a simulated sensor takes both (placement, calibration).
    config = load_network(DEMO, ["sensors.k2_c.pose=null", "sensors.k2_c.calibration=c.yaml"])
    assert config.sensors[2].calibration == Path("c.yaml")
    config = load_network(DEMO, ["sensors.k2_c.calibration=c.yaml"])
    assert config.sensors[2].pose is not None and config.calibrated


def test_a_simulated_lens_is_named_when_wrong() -> None:
    config = load_network(
        DEMO, ["sensors.k2_b.sim_lens={distortion: [0.09, -0.27], reported: [0.1]}"]
    )
    assert config.sensors[1].sim_lens is not None
    assert config.sensors[1].sim_lens.reported == (0.1,)
    (line,) = _problem_lines(_error(DEMO, ["sensors.k2_b.sim_lens={distortion: [0.1, 3.0]}"]))
    assert line.startswith(
        "sensors.1.sim_lens: distortion: every lens term must lie within -2 and 2"
    ), line
    (line,) = _problem_lines(
        _error(DEMO, ["sensors.k2_b.sim_lens={distortion: [0, 0, 0, 0, 0, 0.1]}"])
    )
    assert line.startswith("sensors.1.sim_lens.distortion: "), line
    lines = _problem_lines(_error(DEMO, ["sensors.k2_b.sim_lens={distortion: [.nan]}"]))
    assert lines[0].startswith("sensors.1.sim_lens.distortion.0: input should be a finite"), lines
    camera = [
        "sensors.k2_c.source=camera",
        "sensors.k2_c.input=realsense",
        "sensors.k2_c.pose=null",
    ]
    (line,) = _problem_lines(_error(DEMO, [*camera, "sensors.k2_c.sim_lens={distortion: [0.1]}"]))
    assert line.startswith("sensors.2: sim_lens: only a simulated sensor has one"), line


def test_every_problem_is_reported_one_per_line(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(
        "site: a/b\n"
        "stats_interval_s: 0\n"
        "sensors:\n"
        "  - {id: s1, source: camera, rate_hz: -5}\n"
        "  - {id: s2, source: camera, type: kinect3, pose: {pitch_deg: 120}}\n"
        "  - {id: s3, source: camera, rat: 1}\n"
    )
    lines = _problem_lines(_error(path, []))
    assert len(lines) == 6, lines
    assert [line.split(":")[0] for line in lines] == [
        "site",
        "sensors.0.rate_hz",
        "sensors.1.type",
        "sensors.1.pose.pitch_deg",
        "sensors.2.rat",
        "stats_interval_s",
    ]


@pytest.mark.parametrize("value", [".nan", ".inf"], ids=["nan", "inf"])
def test_non_finite_pose_is_rejected(value: str) -> None:
    with pytest.raises(ConfigError, match=r"sensors\.0\.pose\.x"):
        load_network(DEMO, [f"sensors.0.pose.x={value}"])


def test_boolean_for_a_number_is_rejected() -> None:
    with pytest.raises(ConfigError, match=r"sensors\.0\.rate_hz"):
        load_network(DEMO, ["sensors.0.rate_hz=true"])


# ----------------------------------------------------------------------- overrides


def test_override_by_index_and_by_id() -> None:
    by_index = load_network(DEMO, ["sensors.1.rate_hz=15"])
    by_id = load_network(DEMO, ["sensors.k2_b.rate_hz=15"])
    assert by_index == by_id
    assert [s.rate_hz for s in by_id.sensors] == [None, 15.0, None]
    last = load_network(DEMO, ["sensors.-1.rate_hz=15"])
    assert [s.rate_hz for s in last.sensors] == [None, None, 15.0]


def test_override_nested_value_keeps_siblings() -> None:
    config = load_network(DEMO, ["sensors.k2_a.pose.pitch_deg=45"])
    pose = config.sensors[0].pose
    assert pose is not None
    assert (pose.x, pose.y, pose.z, pose.yaw_deg, pose.pitch_deg) == (0.3, 0.3, 2.7, 38, 45)


def test_override_creates_missing_section() -> None:
    config = load_network(MULTI_HOST, ["sim.seed=3"])
    assert config.sim is not None
    assert config.sim.seed == 3
    assert config.sim.scenario == "installation"  # other keys take their defaults
    assert load_network(MULTI_HOST).sim is None
    data = apply_overrides({}, ["a.b.c=1"])
    assert data == {"a": {"b": {"c": 1}}}


def test_override_with_list_index_on_missing_list_names_the_list() -> None:
    # crowd.yaml has no sensors: 'sensors.0' creates a mapping, which is not a list.
    (line,) = _problem_lines(_error(CROWD, ["sensors.0.rate_hz=15"]))
    assert line.startswith("sensors: input should be a valid list"), line


def test_later_override_wins() -> None:
    config = load_network(DEMO, ["sim.seed=1", "sim.seed=2"])
    assert config.sim is not None
    assert config.sim.seed == 2


@pytest.mark.parametrize(
    "text, value",
    [
        ("true", True),
        ("false", False),
        ("on", True),
        ("15", 15),
        ("-2.5", -2.5),
        ("0x10", 16),
        ("null", None),
        ("~", None),
        ("", ""),
        ("'15'", "15"),
        ("tcp/1.2.3.4:7447", "tcp/1.2.3.4:7447"),
        ("[1, 2.5, x]", [1, 2.5, "x"]),
        ("{a: 1, b: [true]}", {"a": 1, "b": [True]}),
        ("a=b", "a=b"),
        ("[unclosed", "[unclosed"),
    ],
    ids=[
        "true",
        "false",
        "yaml11-on",
        "int",
        "float",
        "hex",
        "null",
        "tilde",
        "empty",
        "quoted-number",
        "endpoint",
        "flow-list",
        "flow-map",
        "equals-in-value",
        "invalid-yaml-kept-as-text",
    ],
)
def test_override_values_are_parsed_as_yaml(text: str, value: Any) -> None:
    data = apply_overrides({"x": {"y": 0}}, [f"x.y={text}"])
    assert data == {"x": {"y": value}}
    assert type(data["x"]["y"]) is type(value)


def test_override_parsed_values_reach_the_model() -> None:
    config = load_network(
        DEMO,
        [
            "zenoh.multicast_scouting=true",
            "zenoh.connect=[tcp/10.0.0.1:7447, udp/10.0.0.2:7447]",
            "sensors.k2_a.type=realsense",
            "sim.duration_s=12.5",
        ],
    )
    assert config.zenoh.multicast_scouting is True
    assert config.zenoh.connect == ["tcp/10.0.0.1:7447", "udp/10.0.0.2:7447"]
    assert config.sensors[0].type == "realsense"
    assert config.sim is not None
    assert config.sim.duration_s == 12.5


def test_apply_overrides_by_name_key() -> None:
    data = apply_overrides({"nodes": [{"name": "tracker", "gate": 1}]}, ["nodes.tracker.gate=2"])
    assert data == {"nodes": [{"name": "tracker", "gate": 2}]}


@pytest.mark.parametrize(
    "override, pattern",
    [
        ("sensors.0.rate_hz", r"^override 'sensors\.0\.rate_hz': expected key\.path=value$"),
        ("=15", r"^override '=15': expected key\.path=value$"),
        ("  =15", r"^override '  =15': expected key\.path=value$"),
        (
            "sensors.k2_z.rate_hz=15",
            r"^sensors\.k2_z: no item with id 'k2_z' \(known: k2_a, k2_b, k2_c\)$",
        ),
        ("sensors.3.rate_hz=15", r"^sensors\.3: index out of range \(list has 3 items\)$"),
        ("sensors.-4.rate_hz=15", r"^sensors\.-4: index out of range \(list has 3 items\)$"),
        ("site.name.x=1", r"^override 'site\.name\.x=1': .* is not a mapping or list$"),
    ],
    ids=[
        "no-equals",
        "empty-path",
        "blank-path",
        "unknown-id",
        "index-out-of-range",
        "negative-index-out-of-range",
        "through-a-scalar",
    ],
)
def test_bad_override(override: str, pattern: str) -> None:
    message = _error(DEMO, [override])
    assert re.search(pattern, message), message


def test_override_through_a_scalar_names_the_scalar() -> None:
    message = _error(DEMO, ["site.name=x"])
    assert message == "override 'site.name=x': site is not a mapping or list"


def test_apply_overrides_mutates_and_returns_the_mapping() -> None:
    data: dict[str, Any] = {"sim": {"seed": 0}}
    assert apply_overrides(data, ["sim.seed=4"]) is data
    assert data == {"sim": {"seed": 4}}


# ----------------------------------------------------------------------- read_yaml


def test_read_yaml_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "nope.yaml"
    with pytest.raises(ConfigError, match=r"nope\.yaml: cannot read \(No such file"):
        read_yaml(path)
    with pytest.raises(ConfigError, match=r"nope\.yaml: cannot read"):
        load_network(path)


def test_read_yaml_directory(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"cannot read"):
        read_yaml(tmp_path)


@pytest.mark.parametrize(
    "text, where",
    [
        ("site: a\n  zenoh: 1\n", "line 2, column 8"),
        ("site: a\nsensors:\n  - id: [x\n", "line 4, column 1"),
        ("site: a\nsim: {seed: 1\n", "line 3, column 1"),
        ("site: 'a\n", "line 2, column 1"),
    ],
    ids=["bad-indentation", "unclosed-flow-list", "unclosed-flow-map", "unclosed-quote"],
)
def test_read_yaml_syntax_error_has_line_and_column(tmp_path: Path, text: str, where: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        read_yaml(path)
    message = str(info.value)
    assert message.startswith(f"{path}: {where}: not valid YAML ("), message


@pytest.mark.parametrize(
    "text, type_name",
    [("- a\n- b\n", "list"), ("just a string\n", "str"), ("42\n", "int")],
    ids=["list", "string", "number"],
)
def test_read_yaml_top_level_must_be_mapping(tmp_path: Path, text: str, type_name: str) -> None:
    path = tmp_path / "top.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        read_yaml(path)
    assert str(info.value) == f"{path}: expected a mapping at the top level, got {type_name}"


def test_read_yaml_empty_file_is_empty_mapping(tmp_path: Path) -> None:
    path = tmp_path / "empty.yaml"
    path.write_text("# nothing here\n")
    assert read_yaml(path) == {}
    assert load_network(None) == NetworkConfig()  # no file at all: the defaults


def test_read_yaml_undecodable_file(tmp_path: Path) -> None:
    path = tmp_path / "binary.yaml"
    path.write_bytes(b"site: \xff\xfe\n")
    with pytest.raises(ConfigError, match=r"binary\.yaml"):
        read_yaml(path)


def test_validate_config_top_level_must_be_mapping() -> None:
    with pytest.raises(ConfigError, match=r"^net: expected a mapping at the top level, got list$"):
        validate_config(NetworkConfig, [1, 2], source="net")
    assert validate_config(NetworkConfig, None) == NetworkConfig()


# ------------------------------------------------------------- round trip, frozen


@pytest.mark.parametrize("path", CONFIG_FILES, ids=[p.stem for p in CONFIG_FILES])
def test_to_yaml_round_trip(path: Path, tmp_path: Path) -> None:
    config = load_network(path)
    text = to_yaml(config)
    out = tmp_path / "round_trip.yaml"
    out.write_text(text)
    again = load_network(out)
    assert again == config
    assert to_yaml(again) == text
    # Defaults are written out, so the file is self-describing.
    assert set(yaml.safe_load(text)) == set(NetworkConfig.model_fields)


def test_to_yaml_round_trip_with_overrides(tmp_path: Path) -> None:
    config = load_network(
        DEMO,
        [
            "sensors.k2_c.pose=null",
            "sensors.k2_c.calibration=calib/k2_c.yaml",
            "recorder.path=out/run.jsonl",
            "zenoh.hub=null",
        ],
    )
    out = tmp_path / "rt.yaml"
    out.write_text(to_yaml(config))
    assert load_network(out) == config


@pytest.mark.parametrize(
    "target, attribute, value",
    [
        (lambda c: c, "site", "other"),
        (lambda c: c.zenoh, "mode", "client"),
        (lambda c: c.sensors[0], "rate_hz", 5.0),
        (lambda c: c.sensors[0].pose, "x", 1.0),
        (lambda c: c.sim, "seed", 9),
    ],
    ids=["network", "zenoh", "sensor", "pose", "sim"],
)
def test_models_are_frozen(target: Any, attribute: str, value: Any) -> None:
    config = load_network(DEMO)
    model = target(config)
    before = getattr(model, attribute)
    with pytest.raises(ValidationError, match="frozen"):
        setattr(model, attribute, value)
    assert getattr(model, attribute) == before


def test_sensor_lookup() -> None:
    config = load_network(DEMO)
    assert config.sensor("k2_b") is config.sensors[1]
    with pytest.raises(ConfigError, match=r"no sensor with id 'zz' \(known: k2_a, k2_b, k2_c\)"):
        config.sensor("zz")
    assert isinstance(config.sensors[0], SensorConfig)


def test_a_network_file_may_name_every_scenario_the_simulator_has() -> None:
    from typing import get_args

    from openptrack_py.config import ScenarioName
    from openptrack_py.sim import SCENARIO_NAMES

    assert list(get_args(ScenarioName)) == list(SCENARIO_NAMES)
