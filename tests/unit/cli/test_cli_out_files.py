"""Every ``--out FILE``: a name the system cannot hold is refused (exit 4, no traceback), and an
existing file is replaced only with ``--force``, both before any work."""

from __future__ import annotations

import errno
import json
from pathlib import Path

import pytest

from spm_console.cli.main import main
from spm_console.core.polytope.region import Region
from spm_console.errors import BadInputError, ExitCode
from spm_console.safe_io import NAME_MAX

START = ["127.53", "83.23", "85.25"]
GOAL = ["66.80", "155.00", "131.48"]

#: Each command that writes an --out file, with the file's suffix (``{out}`` is the file).
COMMANDS: dict[str, tuple[list[str], str]] = {
    "export": (["export", "urdf", "--out", "{out}"], ".urdf"),
    "plan mvn": (["plan", "mvn", "--start", *START, "--goal", *GOAL,
                  "--region", "{box}", "--out", "{out}"], ".json"),
    "plan mintime": (["plan", "mintime", "--start", *START, "--goal", *GOAL, "--region", "{box}",
                      "--out", "{out}"], ".json"),
    "workspace region": (["workspace", "region", "--out", "{out}"], ".json"),
    "logs export": (["logs", "export", "--mcap", "{run}", "--out", "{out}"], ".mcap"),
    "design profile": (["design", "profile", "{tmp}", "0", "--out", "{out}"], ".toml"),
    "identify": (["identify", "--experiment", "--sim", "--out", "{out}"], ".toml"),
}


def _argv(name: str, tmp_path: Path, out: Path) -> list[str]:
    box = tmp_path / "box.json"
    box.write_text(json.dumps(Region.box(65.0, 155.0).to_dict()))
    fill = {"{out}": str(out), "{box}": str(box), "{tmp}": str(tmp_path),
            "{run}": str(tmp_path / "no-run")}
    return [fill.get(a, a) for a in COMMANDS[name][0]] + ["--json"]


@pytest.mark.parametrize("name", list(COMMANDS))
@pytest.mark.parametrize("where", ["file", "folder"])
def test_a_name_longer_than_name_max_is_bad_input(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str, where: str) -> None:
    long = "n" * (NAME_MAX + 1)
    out = (tmp_path / (long + COMMANDS[name][1]) if where == "file"
           else tmp_path / long / f"x{COMMANDS[name][1]}")
    assert main(_argv(name, tmp_path, out)) == ExitCode.BAD_INPUT
    captured = capsys.readouterr()
    assert json.loads(captured.out)["ok"] is False
    assert "--out" in captured.err and "NAME_MAX" in captured.err
    assert "Traceback" not in captured.err


def test_a_name_of_name_max_bytes_is_written(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    """The temporary file beside it (renamed to it) has a name of its own that fits too."""
    out = tmp_path / ("w" * (NAME_MAX - len(".urdf")) + ".urdf")
    assert main(["export", "urdf", "--out", str(out)]) == 0, capsys.readouterr().err
    assert out.is_file() and [p.name for p in tmp_path.iterdir()] == [out.name]


@pytest.mark.parametrize("name", list(COMMANDS))
def test_an_existing_file_is_kept_without_force(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str) -> None:
    out = tmp_path / f"kept{COMMANDS[name][1]}"
    out.write_text("the operator's own file\n")
    assert main(_argv(name, tmp_path, out)) == ExitCode.BAD_INPUT
    err = capsys.readouterr().err
    assert "exists" in err and "--force" in err
    assert out.read_text() == "the operator's own file\n"


@pytest.mark.parametrize("name", ["export", "plan mvn", "workspace region"])
def test_force_replaces_it(tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str) -> None:
    out = tmp_path / f"replaced{COMMANDS[name][1]}"
    out.write_text("old\n")
    assert main([*_argv(name, tmp_path, out), "--force"]) == 0, capsys.readouterr().err
    capsys.readouterr()
    assert out.read_text() != "old\n"


@pytest.mark.parametrize(("argv", "code"), [
    (["design", "sweep", "examples/design_sweep.toml", "--out", "{long}"], ExitCode.BAD_INPUT),
    (["reproduce", "--out", "{long}"], ExitCode.BAD_INPUT),
    (["workspace", "show", "--plot", "{long}.png"], ExitCode.BAD_INPUT),
    (["logs", "--logs", "{long}"], ExitCode.BAD_INPUT),
    (["logs", "show", "{long}"], ExitCode.BAD_INPUT),
    (["workspace", "build", "--cache-dir", "{long}"], ExitCode.CACHE_ERROR),
], ids=["design sweep --out", "reproduce --out", "workspace show --plot", "logs --logs",
        "logs show RUN", "workspace build --cache-dir"])
def test_other_paths_longer_than_name_max_are_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], code: int) -> None:
    long = str(tmp_path / ("n" * (NAME_MAX + 1)))
    assert main([a.replace("{long}", long) for a in argv]) == code
    err = capsys.readouterr().err
    assert "NAME_MAX" in err and "Traceback" not in err


@pytest.mark.parametrize("name", list(COMMANDS))
def test_a_folder_this_process_cannot_write_is_refused_before_any_work(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
        name: str) -> None:
    """A read-only file system, or a folder of another user's (the tests run as root on CI,
    where permissions alone refuse nothing): no file can be made there. ``identify
    --experiment`` ran its whole experiment and then failed with a traceback (exit 1); every
    command now refuses at once, exit 4."""
    from spm_console.cli import common

    def read_only(path: object) -> tuple[int, Path]:
        raise OSError(errno.EROFS, "Read-only file system")

    monkeypatch.setattr(common, "atomic_temp", read_only)
    out = tmp_path / f"new{COMMANDS[name][1]}"
    assert main(_argv(name, tmp_path, out)) == ExitCode.BAD_INPUT
    err = capsys.readouterr().err
    assert "cannot write there: Read-only file system" in err and "Traceback" not in err
    assert not out.exists() and not (tmp_path / "logs").exists()  # nothing ran, nothing moved


def test_a_file_that_cannot_be_written_is_the_callers_error(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """write_text_atomic: a folder that refuses the temporary file, or a disk that fills while
    it is written, raise the error class the caller gave (its exit code), never OSError."""
    from spm_console import safe_io

    with pytest.raises(BadInputError, match="cannot write: Read-only file system"):
        monkeypatch.setattr(safe_io, "atomic_temp", lambda p: (_ for _ in ()).throw(
            OSError(errno.EROFS, "Read-only file system")))
        safe_io.write_text_atomic(tmp_path / "a.txt", "x", BadInputError)
    monkeypatch.undo()
    real_replace = safe_io.os.replace

    def full(src: object, dst: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(safe_io.os, "replace", full)
    with pytest.raises(BadInputError, match="cannot write: No space left on device"):
        safe_io.write_text_atomic(tmp_path / "b.txt", "x", BadInputError)
    monkeypatch.setattr(safe_io.os, "replace", real_replace)
    assert list(tmp_path.iterdir()) == []  # no temporary file left
