"""``commission``'s options that do not go together are a usage error (exit 2), said before any
port is opened (the same rules as the console's form: ``options_problem``): one device for
the bus and the IMU, nothing to zero the wrist (neither the jig nor the IMU: the profile
written would keep the old tick offsets, which a reversed servo puts out of range, after
every question was asked), a payload mass without the IMU stage."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from spm_console.cli.main import main
from spm_console.errors import ExitCode
from spm_console.services.commissioning.run import options_problem

BUS = "unix:/nonexistent/bus"


@pytest.mark.parametrize(("args", "why"), [
    (["--port", "/nonexistent/tty7", "--imu-port", "/nonexistent/tty7", "--jig"],
     "ports of their own"),
    (["--port", BUS, "--imu-port", BUS, "--jig"], "ports of their own"),
    (["--port", BUS], "nothing would zero the wrist"),
    (["--port", BUS, "--no-imu-fit"], "nothing would zero the wrist"),
    (["--port", BUS, "--jig", "--payload-kg", "0.3"], "needs the IMU stage"),
    (["--port", BUS, "--imu-port", "/nonexistent/imu", "--jig", "--no-imu-fit",
      "--payload-kg", "0.3"], "needs the IMU stage"),
])
def test_options_that_do_not_go_together_are_a_usage_error(
        capsys: pytest.CaptureFixture[str], args: list[str], why: str) -> None:
    rc = main(["commission", *args, "--json"])
    out = capsys.readouterr()
    assert rc == ExitCode.USAGE, out
    error = json.loads(out.out)["error"]
    assert why in error and "--imu-port" in error, error


def test_a_link_to_the_bus_is_the_bus(tmp_path: Path) -> None:
    bus = tmp_path / "ttyUSB0"
    bus.touch()
    link = tmp_path / "by-id-usb-FTDI"
    os.symlink(bus, link)
    assert "ports of their own" in options_problem(str(bus), str(link), True, True, None)
    assert options_problem(str(bus), str(tmp_path / "ttyUSB1"), True, True, None) == ""


@pytest.mark.parametrize(("imu", "jig", "stage", "mass", "ok"), [
    ("/dev/ttyUSB1", True, True, 0.3, True),
    ("/dev/ttyUSB1", False, True, 0.3, True),  # the IMU zeroes the wrist at rest
    (None, True, False, None, True),  # the operator answers; the jig zeroes
    (None, True, True, None, True),  # the IMU stage is skipped without the IMU
    ("/dev/ttyUSB1", False, False, None, True),
])
def test_what_goes_together(imu: str | None, jig: bool, stage: bool, mass: float | None,
                            ok: bool) -> None:
    assert (options_problem("/dev/ttyUSB0", imu, jig, stage, mass) == "") is ok
