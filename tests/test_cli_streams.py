"""A command's standard output carries only what it prints: native log lines go to stderr."""

from __future__ import annotations

import subprocess
import sys
import time

import orjson
import pytest

from openptrack_py.config import ZenohConfig
from openptrack_py.transport.zenoh_bus import ZenohBus
from tests.conftest import ROOT, free_port, python_env

ECHO = (sys.executable, "-m", "openptrack_py.cli", "echo", "opt/streams/**", "--raw")


def test_writes_to_descriptor_1_go_to_stderr_and_prints_to_stdout_until_restored() -> None:
    code = (
        "import os\n"
        "from openptrack_py.cli.streams import restore_native_stdout, separate_native_stdout\n"
        "print('before')\n"
        "assert separate_native_stdout()\n"
        "os.write(1, b'native\\n')\n"
        "print('python')\n"
        "assert not separate_native_stdout()  # once: sys.stdout is no longer descriptor 1\n"
        "restore_native_stdout()  # as before an exec\n"
        "os.write(1, b'after\\n')\n"
    )
    for unbuffered in ("1", ""):
        env = {**python_env(), "PYTHONUNBUFFERED": unbuffered}
        done = subprocess.run(
            [sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=ROOT
        )
        assert done.returncode == 0, done.stderr
        assert done.stdout == "before\npython\nafter\n"
        assert done.stderr == "native\n"


@pytest.mark.zenoh
def test_echo_prints_only_json_lines_while_zenoh_logs_at_debug() -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    env = {**python_env(), "RUST_LOG": "debug"}  # Zenoh writes many lines as it works
    env.pop("NO_COLOR", None)  # as a user's shell has it (this process's sessions set it)
    echo = subprocess.Popen(
        [*ECHO, "-n", "5", "-l", endpoint, "--no-multicast-scouting"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        cwd=ROOT,
    )
    bus = ZenohBus(ZenohConfig(hub=None, connect=[endpoint], listen=[], multicast_scouting=False))
    try:
        pub = bus.publisher("opt/streams/a")
        deadline = time.monotonic() + 60
        while echo.poll() is None and time.monotonic() < deadline:
            pub.put(b'{"n": 1}')
            time.sleep(0.05)
        out, err = echo.communicate(timeout=30)
    finally:
        bus.close()
        if echo.poll() is None:
            echo.kill()
    assert echo.returncode == 0, err
    lines = out.splitlines()
    assert len(lines) == 5
    assert all(orjson.loads(x)["key"] == "opt/streams/a" for x in lines)
    assert "DEBUG" in err and "zenoh" in err
    assert "\x1b[" not in err  # no colour codes when the logs do not go to a terminal
