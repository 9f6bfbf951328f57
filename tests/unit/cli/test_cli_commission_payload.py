"""``commission --payload-kg``: a weighed mass in (0, 2] kg (anything else is refused, exit 4,
before any port is opened); the options it needs: ``test_cli_commission_options.py``."""

from __future__ import annotations

import json

import pytest

from spm_console.cli.main import main
from spm_console.errors import ExitCode


@pytest.mark.parametrize(("value", "extra", "why"), [
    ("0", [], "--payload-kg must be in (0, 2] kg"),
    ("-1", [], "--payload-kg must be in (0, 2] kg"),
    ("2.5", [], "--payload-kg must be in (0, 2] kg"),
    ("nan", [], "--payload-kg"),
    ("1e-320", [], "subnormal"),  # the profile would refuse it after the whole run
])
def test_a_bad_payload_mass_is_refused_before_anything_opens(
        capsys: pytest.CaptureFixture[str], value: str, extra: list[str], why: str) -> None:
    rc = main(["commission", "--port", "unix:/nonexistent/bus", "--imu-port", "/nonexistent/imu",
               "--payload-kg", value, *extra, "--json"])
    out = capsys.readouterr()
    assert rc == ExitCode.BAD_INPUT, out
    assert why in json.loads(out.out)["error"]

