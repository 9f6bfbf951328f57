"""A terminating signal whose interrupt a library wraps (pydantic turns it into a SchemaError
while it builds a validator as a module loads) still ends the command as an interruption;
any other exception stays a bug, even after a signal a command's own handler took."""

from __future__ import annotations

import argparse
import json
import os
import signal

import pytest

from spm_console.cli import main as cli_main
from spm_console.errors import ExitCode
from spm_console.system.signals import forget_signals, stop_signals


class WrappedError(Exception):
    """What a library raises around the interrupt it caught."""


def _parser_interrupted(_command: str | None = None) -> argparse.ArgumentParser:
    try:  # the start-up handler, as the signal arrives while a module loads
        cli_main._interrupt(signal.SIGHUP, None)
    except KeyboardInterrupt as exc:  # the library's wrap
        raise WrappedError(f"SignalInterrupt: {exc}") from None
    raise AssertionError("the start-up handler raised nothing")


def _parser_broken(_command: str | None = None) -> argparse.ArgumentParser:
    raise WrappedError("a bug")


def _stop_then_bug(_args: argparse.Namespace) -> int:
    with stop_signals(lambda _sig: None):  # a moving command's own E-stop handling
        os.kill(os.getpid(), signal.SIGTERM)  # the operator stops the run
        raise WrappedError("a bug in the stop path")


def _parser_of_a_run(_command: str | None = None) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser()
    parser.set_defaults(func=_stop_then_bug)
    return parser


def test_a_wrapped_interrupt_is_an_interruption(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(cli_main, "build_parser", _parser_interrupted)
    try:
        code = cli_main.main(["fk", "--theta", "95", "110", "105", "--json"])
    finally:
        forget_signals()
    out, err = capsys.readouterr()
    assert code == ExitCode.INTERRUPTED
    assert "Traceback" not in err and "interrupted by SIGHUP" in err
    assert json.loads(out) == {"ok": False, "exit_code": int(ExitCode.INTERRUPTED),
                               "error": "interrupted by SIGHUP"}


def test_without_a_signal_the_error_is_a_bug(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(cli_main, "build_parser", _parser_broken)
    with pytest.raises(WrappedError):
        cli_main.main(["fk", "--theta", "95", "110", "105"])


def test_a_bug_after_a_commands_own_stop_is_still_a_bug(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(cli_main, "build_parser", _parser_of_a_run)
    try:
        with pytest.raises(WrappedError, match="stop path"):
            cli_main.main([])
    finally:
        forget_signals()
