"""``spm-console emulate`` as a real process, ``servo ping|read|torque`` against it."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from spm_console.cli.main import main
from spm_console.config.schema import Profile
from spm_console.devices.emulator.bus import start_emulator
from spm_console.errors import ExitCode

pytestmark = pytest.mark.realtime  # an emulated bus on the wall clock (see tests/conftest.py)


@pytest.fixture(scope="module")
def relaxed(tmp_path_factory: pytest.TempPathFactory, root: Path) -> str:
    """The Agile Wrist profile with a 30 ms reply timeout (a loaded 2-core test machine can
    delay the emulator by more than the real 4 ms; these tests are not about timing)."""
    text = (root / "profiles" / "agile_wrist.toml").read_text()
    assert "timeout_s = 0.004" in text
    path = tmp_path_factory.mktemp("prof") / "agile_relaxed.toml"
    path.write_text(text.replace("timeout_s = 0.004", "timeout_s = 0.03"))
    return str(path)


@pytest.fixture
def port(agile: Profile) -> Iterator[str]:
    with start_emulator(agile) as em:
        yield em.port


Run = Callable[..., tuple[int, str, str]]


@pytest.fixture
def cli(capsys: pytest.CaptureFixture[str], relaxed: str) -> Run:
    """main(argv) in-process -> (exit code, stdout, stderr); servo commands get ``relaxed``."""

    def run(*argv: str) -> tuple[int, str, str]:
        if argv[0] == "servo":
            argv = (*argv, "--profile", relaxed)
        code = main(list(argv))
        out, err = capsys.readouterr()
        return code, out, err

    return run


# the socket variant in the slow set (make test-slow): make test stays within 8 minutes
@pytest.mark.parametrize("link", ["pty", pytest.param("socket", marks=pytest.mark.slow)])
def test_emulate_process_serves_until_sigterm(relaxed: str, link: str) -> None:
    """The default pty, a serial device; or the socket, port unix:PATH, which ``--port`` opens
    and which is gone with the emulator."""
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen([sys.executable, "-m", "spm_console", "emulate", "--json",
                             "--fault", "stall:1@100", *(["--link", link] if link != "pty" else [])],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        assert proc.stdout is not None
        head = json.loads(proc.stdout.readline())
        assert head["ids"] == [1, 2, 3] and head["model_number"] == 321
        assert head["protocol"] == "2.0" and head["faults"] == ["stall:1@100"]
        assert head["link"] == link
        path = head["port"].removeprefix("unix:") if link == "socket" else head["port"]
        assert head["port"].startswith("unix:" if link == "socket" else "/dev/")
        assert os.path.exists(path)
        ping = subprocess.run([sys.executable, "-m", "spm_console", "servo", "ping", "--json",
                               "--port", head["port"], "--profile", relaxed],
                              capture_output=True, text=True, timeout=60)
        assert ping.returncode == 0, ping.stderr
        servos = json.loads(ping.stdout)["servos"]
        assert [(s["id"], s["model_number"]) for s in servos] == [(1, 321), (2, 321), (3, 321)]
        proc.send_signal(signal.SIGTERM)
        out, _ = proc.communicate(timeout=10)
        assert proc.returncode == 0
        summary = json.loads(out.strip().splitlines()[-1])
        assert summary["stopped"] and summary["instructions"] >= 3
        if link == "socket":
            assert not os.path.exists(path)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_emulate_refuses_bad_fault(cli: Run) -> None:
    code, out, err = cli("emulate", "--fault", "melt:3")
    assert code == ExitCode.BAD_INPUT and "unknown kind 'melt'" in err and out == ""


def test_servo_ping_lists_ids_and_models(cli: Run, port: str) -> None:
    code, out, _ = cli("servo", "ping", "--port", port)
    assert code == 0
    assert out.splitlines() == [f"id   {i}  model 321  firmware 45" for i in (1, 2, 3)]


def test_servo_ping_missing_id_is_bus_error(cli: Run, port: str) -> None:
    code, out, err = cli("servo", "ping", "--json", "--port", port, "--ids", "2", "8")
    assert code == ExitCode.BUS_ERROR
    data = json.loads(out)
    assert [s["id"] for s in data["servos"]] == [2]
    assert "no status packet from servo id 8" in err


def test_servo_read_and_torque(cli: Run, port: str) -> None:
    code, out, _ = cli("servo", "read", "--json", "--port", port)
    assert code == 0
    data = json.loads(out)
    assert data["theta_deg"] == [135.0, 135.0, 135.0]
    assert [j["torque"] for j in data["joints"]] == [False] * 3
    assert cli("servo", "torque", "on", "--port", port)[0] == 0
    code, out, _ = cli("servo", "read", "--port", port, "--register", "torque_enable",
                       "--json")
    assert code == 0 and json.loads(out)["values"] == {"1": 1, "2": 1, "3": 1}
    assert cli("servo", "torque", "off", "--port", port)[0] == 0


def test_servo_errors(cli: Run, port: str) -> None:
    code, _, err = cli("servo", "read", "--port", port, "--register", "warp_drive")
    assert code == ExitCode.BAD_INPUT and "unknown register 'warp_drive'" in err
    code, _, err = cli("servo", "ping")  # profile port is empty
    assert code == ExitCode.BUS_ERROR and "--port" in err
    code, _, err = cli("servo", "ping", "--port", "/dev/no-such-tty")
    assert code == ExitCode.BUS_ERROR and "cannot open serial port" in err
