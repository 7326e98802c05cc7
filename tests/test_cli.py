"""The ``openptrack`` command, its subcommands, and an installed (non-editable) copy."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from openptrack_py.cli import available_nodes, build_parser
from tests.conftest import ROOT, python_env

SUBCOMMANDS = [
    "launch", "node", "status", "echo", "config", "roster", "eval", "record", "replay",
    "retrack", "analyze", "scenarios", "show-config", "record-sensor", "detect", "eval-detector",
    "calibrate", "certs",
]  # fmt: skip


def _run(*args: str, cwd: Path = ROOT, env: dict[str, str] | None = None, timeout: float = 120):
    return subprocess.run(
        [*args],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=env or python_env(),
        cwd=cwd,
    )


def _cli(*args: str, **kw: object) -> subprocess.CompletedProcess[str]:
    return _run(sys.executable, "-m", "openptrack_py.cli", *args, **kw)  # type: ignore[arg-type]


def test_every_subcommand_is_registered() -> None:
    parser = build_parser()
    choices = next(a for a in parser._actions if a.dest == "command").choices
    assert sorted(choices) == sorted(SUBCOMMANDS)


@pytest.mark.parametrize("command", [[], *([c] for c in SUBCOMMANDS)], ids=["top", *SUBCOMMANDS])
def test_help_works_for_every_subcommand(command: list[str]) -> None:
    result = _cli(*command, "--help")
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("usage: openptrack")


@pytest.mark.parametrize("node", ["sim", "record", "tracker", "output"])
def test_every_node_has_help(node: str) -> None:
    assert node in available_nodes()
    result = _cli("node", node, "--help")
    assert result.returncode == 0, result.stderr
    assert f"usage: openptrack node {node}" in result.stdout
    for flag in ("-c NETWORK", "--set KEY=VALUE", "-e ENDPOINT", "-l ENDPOINT", "--log-level"):
        assert flag in result.stdout


def test_unknown_node_lists_the_available_ones() -> None:
    result = _cli("node", "tracker-of-dreams")
    assert result.returncode == 2
    available = "board, calibration, detector, output, record, sim, tracker"
    assert f"unknown node 'tracker-of-dreams' (available: {available})" in result.stderr


def test_show_config_fills_defaults_and_applies_overrides() -> None:
    result = _cli("show-config", "demo", "--set", "sim.seed=7")
    assert result.returncode == 0, result.stderr
    assert "seed: 7" in result.stdout and "latency_jitter_s: 0.005" in result.stdout


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("sensors.0.rat=3", "sensors.0.rat: unknown key; did you mean 'rate_hz'?"),
        ("sensors.k2_b.rate_hz=-5", "sensors.1.rate_hz: must be > 0.0 (received -5)"),
        ("sim.scenario=dance", "sim.scenario: must be one of 'crowd', 'distance'"),
    ],
    ids=["misspelt", "negative-rate", "bad-scenario"],
)
def test_config_errors_name_the_key_and_exit_2(override: str, message: str) -> None:
    result = _cli("show-config", "demo", "--set", override)
    assert result.returncode == 2
    assert message in result.stderr


def test_missing_network_file_names_the_presets() -> None:
    result = _cli("show-config", "no-such-network")
    assert result.returncode == 2
    assert "no file 'no-such-network' and no preset of that name (presets: crowd, demo" in (
        result.stderr
    )


def test_scenarios_lists_every_scenario() -> None:
    result = _cli("scenarios")
    names = [line.split()[0] for line in result.stdout.splitlines()]
    assert names == [
        "crowd", "distance", "occlusions", "classroom", "installation", "stress", "reentry",
        "uniforms", "overhead", "corridor", "walk",
    ]  # fmt: skip


def test_eval_json_has_the_documented_keys() -> None:
    result = _cli(
        "eval", "--scenario", "crowd", "--seed", "3", "--duration", "6", "--tracker", "truth",
        "--format", "json",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    data = json.loads(result.stdout)
    for key in ("mota", "motp", "idf1", "id_switches", "fp", "fn", "frames", "gt_objects"):
        assert key in data
    assert data["mota"] == 1.0 and data["idf1"] == 1.0 and data["scenario"] == "crowd"
    assert data["frames"] == 181  # 6 s of ground truth at 30 Hz, both ends included


def test_eval_table_for_several_runs() -> None:
    result = _cli(
        "eval", "--scenario", "distance", "--scenario", "occlusions", "--seed", "1", "--seed",
        "2", "--duration", "4", "--tracker", "truth",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    rows = result.stdout.strip().splitlines()
    assert rows[0].split()[:4] == ["scenario", "seed", "mota", "motp"]
    assert [r.split()[:2] for r in rows[1:]] == [
        ["distance", "1"], ["distance", "2"], ["occlusions", "1"], ["occlusions", "2"],
    ]  # fmt: skip


def test_eval_rejects_an_unknown_tracker() -> None:
    result = _cli("eval", "--tracker", "magic")
    assert result.returncode == 2 and "unknown tracker 'magic' (allowed: " in result.stderr


@pytest.mark.slow
def test_installed_wheel_has_the_command_every_node_and_the_presets(tmp_path: Path) -> None:
    wheels = tmp_path / "wheels"
    built = _run(
        sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
        "-w", str(wheels), str(ROOT),
    )  # fmt: skip
    assert built.returncode == 0, built.stderr
    (wheel,) = wheels.glob("openptrack_py-*.whl")
    target = tmp_path / "site"
    installed = _run(
        sys.executable, "-m", "pip", "install", "--no-deps", "-q",
        "--target", str(target), str(wheel),
    )  # fmt: skip
    assert installed.returncode == 0, installed.stderr
    env = {**python_env(), "PYTHONPATH": str(target)}
    outside = tmp_path / "elsewhere"  # not the source tree
    outside.mkdir()
    where = _run(
        sys.executable, "-c", "import openptrack_py, openptrack_py.nodes.sim as s; "
        "print(openptrack_py.__file__); print(s.__file__)",
        cwd=outside, env=env,
    )  # fmt: skip
    assert where.returncode == 0, where.stderr
    assert all(line.startswith(str(target)) for line in where.stdout.splitlines())
    script = target / "bin" / "openptrack"
    assert script.exists()
    nodes = ("sim", "record", "tracker", "output")
    for args in (["--help"], *(["node", n, "--help"] for n in nodes)):
        result = _run(str(script), *args, cwd=outside, env=env)
        assert result.returncode == 0, result.stderr
    shown = _run(str(script), "show-config", "demo", cwd=outside, env=env)
    assert shown.returncode == 0 and "k2_c" in shown.stdout, shown.stderr
    for page in ("index.html", "view.js"):  # the web view ships inside the package
        assert (target / "openptrack_py" / "output" / "web" / page).is_file()


def test_core_tracking_never_imports_open3d() -> None:
    code = (
        "import sys, openptrack_py.cli, openptrack_py.sim, openptrack_py.eval.runner, "
        "openptrack_py.transport.zenoh_bus, openptrack_py.launch; "
        "assert 'open3d' not in sys.modules and 'cv2' not in sys.modules"
    )
    result = _run(sys.executable, "-c", code)
    assert result.returncode == 0, result.stderr
