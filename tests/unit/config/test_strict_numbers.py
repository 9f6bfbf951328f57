"""Numbers from text and JSON mean what an operator wrote: plain finite decimals only.

The probe's inputs: a 400-digit integer in a UDP target (it killed the live source), a BOM
or a typo that turned the first CSV row into a "header", ``1_25`` and non-ASCII digits that
``float()`` takes, a target time of 1e9 s.
"""

from __future__ import annotations

import socket
import threading
from pathlib import Path

import numpy as np
import pytest

from spm_console.cli.follow_source import UdpTargets
from spm_console.cli.main import main
from spm_console.config.schema import Profile
from spm_console.core.planning.follow.timed import MAX_TARGET_TIME_S
from spm_console.errors import BadInputError, ExitCode
from spm_console.motion.follow.target_feed import TargetFeed
from spm_console.numbers import NotANumberError, json_loads, json_number, parse_number
from spm_console.store.target_file import read_target_csv

BIG = "9" * 400


@pytest.mark.parametrize(("text", "value"), [
    ("12", 12.0), ("-0.5", -0.5), ("1e-3", 1e-3), (".5", 0.5), ("+3.", 3.0), (" 7 ", 7.0),
    ("1.5E+2", 150.0),
])
def test_plain_decimals_are_numbers(text: str, value: float) -> None:
    assert parse_number(text) == value


@pytest.mark.parametrize("text", [
    "1_25", "١٢٥", "１２", "nan", "-inf", "Infinity", "1e999", "0x10", "", "1 2", "12x", "--1",
    "1" * 65, "true",
])
def test_what_float_takes_but_an_operator_does_not_mean_is_refused(text: str) -> None:
    with pytest.raises(NotANumberError):
        parse_number(text)


@pytest.mark.parametrize("value", [True, False, None, "1", 10**400, -(10**400), [1]])
def test_json_values_that_are_not_finite_numbers_are_refused(value: object) -> None:
    with pytest.raises(NotANumberError):
        json_number(value)


def test_json_decoding_refuses_nan_and_integers_beyond_a_float() -> None:
    assert json_number(json_loads("[1, 2.5]")[0]) == 1.0  # type: ignore[index]
    for text in ('{"a": NaN}', '{"a": -Infinity}', f'{{"a": {BIG}}}'):
        with pytest.raises(NotANumberError):
            json_loads(text)


class _FakeSession:
    """What the UDP source drives: targets and the end of the following (its ``following``
    part is itself)."""

    def __init__(self) -> None:
        self.following = self
        self.moving = threading.Event()
        self.moving.set()
        self.targets: list[np.ndarray] = []
        self.ended = threading.Event()

    def set_target(self, theta: np.ndarray) -> None:
        self.targets.append(theta)

    def end_follow(self) -> None:
        self.ended.set()
        self.moving.clear()


@pytest.mark.parametrize("key", ["theta_deg", "rpy_deg"])
def test_a_giant_integer_in_a_udp_target_is_dropped_and_the_source_lives_on(
        agile: Profile, key: str) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    session = _FakeSession()
    with UdpTargets(agile, port) as src:
        pump = threading.Thread(target=src.pump, args=(session,), daemon=True)
        pump.start()
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as c:
            c.sendto(f'{{"{key}": [{BIG}, 0, 0]}}'.encode(), ("127.0.0.1", port))
            c.sendto(b'{"theta_deg": [true, 135, 135]}', ("127.0.0.1", port))
            c.sendto(b'{"theta_deg": [130, 131, 132]}', ("127.0.0.1", port))
            c.sendto(b'{"end": true}', ("127.0.0.1", port))
        assert session.ended.wait(10.0), src.counts()
        pump.join(5.0)
    assert src.dropped == 2 and src.received == 2
    assert "finite numbers" in src.last_error
    np.testing.assert_array_equal(session.targets[0], [130.0, 131.0, 132.0])


def test_a_live_target_beyond_one_turn_is_refused() -> None:
    feed = TargetFeed(None, [130.0, 130.0, 130.0], 0.5)
    with pytest.raises(BadInputError, match="within ±360°"):
        feed.set([1e12, 130.0, 130.0])


def _csv(tmp_path: Path, data: bytes) -> Path:
    p = tmp_path / "targets.csv"
    p.write_bytes(data)
    return p


def test_a_byte_order_mark_does_not_hide_the_first_target(tmp_path: Path, agile: Profile) -> None:
    t = read_target_csv(agile, _csv(tmp_path, "\ufeff0,130,130,130\n1,131,131,131\n".encode()),
                        False)
    np.testing.assert_array_equal(t.t_s, [0.0, 1.0])
    np.testing.assert_array_equal(t.theta_deg[0], [130.0, 130.0, 130.0])


@pytest.mark.parametrize(("text", "why"), [
    ("13x,130,130,130\n1,131,131,131\n", ":1: four numbers expected"),  # a typo, not a header
    ("1_0,1_00,1_20,1_10\n3,100,120,110\n", ":1: four numbers expected"),  # all odd: no header
    ("٠,١٠٠,١٢٠,١١٠\n3,100,120,110\n", ":1: four numbers expected"),
    ('"0","100","120","110"\n5,127,83,85\n', ":1: four numbers expected"),
    (",,,\n5,127,83,85\n", ":1: four numbers expected"),
    ("t,a,b,c\n0,1_30,130,130\n", ":2: four numbers expected"),
    ("t,a,b,c\n0,١٣٠,130,130\n", ":2: four numbers expected"),
    ("t,a,b,c\n0,130,130,130\n1e9,131,131,131\n", f"end by t = {MAX_TARGET_TIME_S:g} s"),
    ("t,a,b,c\n0,1e12,130,130\n", "within ±360°"),  # its projection used to be the centre
])
def test_target_rows_are_strict(tmp_path: Path, agile: Profile, text: str, why: str) -> None:
    with pytest.raises(BadInputError, match=why):
        read_target_csv(agile, _csv(tmp_path, text.encode()), False)


def test_a_typo_in_the_first_theta_row_is_an_error_not_a_header(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "thetas.csv"
    f.write_text("9x,110,105\n95,110,105\n")
    assert main(["fk", "--theta-file", str(f)]) == ExitCode.BAD_INPUT
    assert f"{f}:1: three numbers expected" in capsys.readouterr().err
