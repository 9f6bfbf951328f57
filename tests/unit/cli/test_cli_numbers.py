"""Numbers on the command line follow the rule of CSV files and UDP messages
(:mod:`spm_console.numbers`): plain ASCII decimals. ``float()`` and ``int()`` took ``1_0``
(ten) and Arabic-Indic digits (``١٠``) where a target file refuses them."""

from __future__ import annotations

import argparse
import re
from collections.abc import Iterator

import pytest

from spm_console.cli.common import integer, number
from spm_console.cli.design import check_scheduler
from spm_console.cli.main import build_parser, main
from spm_console.devices.emulator.faults import parse_fault
from spm_console.errors import BadInputError, ExitCode

#: Written as Python's float() and int() read them, and as no CSV cell or UDP value may be.
ODD = ["1_0", "١٠", "١.٥", "１０", "0x10"]


def _actions(parser: argparse.ArgumentParser, path: str) -> Iterator[tuple[str, argparse.Action]]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _actions(sub, f"{path} {name}")
        else:
            yield path, action


def test_no_option_of_any_command_reads_numbers_with_float_or_int() -> None:
    typed = [(path, a) for path, a in _actions(build_parser(), "spm-console") if a.type is not None]
    assert len(typed) > 20  # the walk sees the commands' options
    loose = [f"{path} {a.dest}" for path, a in typed if a.type in (float, int)]
    assert loose == []


@pytest.mark.parametrize("text", ODD)
def test_the_option_types_refuse_what_a_target_file_refuses(text: str) -> None:
    with pytest.raises(argparse.ArgumentTypeError):
        number(text)
    with pytest.raises(argparse.ArgumentTypeError):
        integer(text)


def test_the_option_types_read_plain_decimals() -> None:
    assert number(" -1.5e1 ") == -15.0 and integer("+42") == 42
    with pytest.raises(argparse.ArgumentTypeError):
        integer("1e3")


@pytest.mark.parametrize(("argv", "option"), [
    (["fk", "--theta", "1_0", "110", "105"], "--theta"),
    (["fk", "--theta", "95", "١١٠", "105"], "--theta"),
    (["ik", "--rpy", "1_0", "0", "0"], "--rpy"),
    (["plan", "mvn", "--start", "127", "83", "85", "--goal", "67", "155", "131",
      "--steps", "١٥٠"], "--steps"),
    (["workspace", "verify", "--samples", "1_000"], "--samples"),
    (["emulate", "--fault", "drop:abc", "--duration", "0.1"], "--fault"),
    (["execute", "--sim", "--fault", "stall:2@5_0", "--plan", "none.json"], "--fault"),
])
def test_a_command_line_number_in_another_notation_is_a_usage_error(
        capsys: pytest.CaptureFixture[str], argv: list[str], option: str) -> None:
    """Text that is no number is a bad command line (exit 2, as ``abc`` always was),
    naming the option and why."""
    assert main(argv) == ExitCode.USAGE
    err = capsys.readouterr().err
    assert f"argument {option}" in err and "decimal" in err and "Traceback" not in err, err


def test_a_numeral_that_is_not_finite_is_still_refused_by_the_options_bound(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["fk", "--theta", "95", "110", "1e999"]) == ExitCode.BAD_INPUT
    assert "must be a finite number" in capsys.readouterr().err
    # a fault's own rules (its kinds, ranges, non-finite numerals) stay the command's: exit 4
    for fault, why in (("drop:nan", "not a finite number"), ("delay:20", "(0, 10]"),
                       ("bogus", "unknown kind")):
        assert main(["emulate", "--fault", fault, "--duration", "0.1"]) == ExitCode.BAD_INPUT
        assert why in capsys.readouterr().err


@pytest.mark.parametrize("fault", ["stall:2@5_0", "drop:0.0_5", "hwerror:٢", "delay:٠.٠٣"])
def test_fault_numbers_follow_the_same_rule(fault: str) -> None:
    """``--fault`` and a script's ``faults`` read their numbers by the same rule."""
    with pytest.raises(BadInputError, match="not a decimal number"):
        parse_fault(fault)


@pytest.mark.parametrize(("fault", "why"), [
    ("drop:1e-310", "subnormal"), ("delay:1e-310", "subnormal"), ("stall:2@1e-310", "subnormal"),
    ("stall:1.0", "needs a joint 1, 2 or 3"), ("hwerror:1e0", "needs a joint 1, 2 or 3"),
    ("stall:+2", "needs a joint 1, 2 or 3"), ("stall:02", "needs a joint 1, 2 or 3"),
    ("drop:-0", "got 0.0"),
])
def test_fault_numbers_are_bounded_as_every_number_typed(fault: str, why: str) -> None:
    """Subnormals refused as --duration refuses them, a joint in digits only, no −0 shown."""
    with pytest.raises(BadInputError, match=re.escape(why)) as exc:
        parse_fault(fault)
    assert "-0" not in exc.value.message


def test_a_scheduler_port_is_written_in_ascii_digits() -> None:
    check_scheduler("tcp://127.0.0.1:8786")
    with pytest.raises(BadInputError):
        check_scheduler("tcp://127.0.0.1:٨٧٨٦")
