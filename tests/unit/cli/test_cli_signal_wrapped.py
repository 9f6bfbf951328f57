"""A terminating signal whose interrupt a library wraps (pydantic turns it into a SchemaError
while it builds a validator as a module loads) still ends the command as an interruption."""

from __future__ import annotations

import argparse
import json
import signal

import pytest

from spm_console.cli import main as cli_main
from spm_console.errors import ExitCode
from spm_console.system.signals import forget_signals, note_signal


class WrappedError(Exception):
    """What a library raises around the interrupt it caught."""


def _parser_interrupted(_command: str | None = None) -> argparse.ArgumentParser:
    note_signal(signal.SIGHUP)  # what the handler records before it raises
    raise WrappedError("SignalInterrupt: SIGHUP")


def _parser_broken(_command: str | None = None) -> argparse.ArgumentParser:
    raise WrappedError("a bug")


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
