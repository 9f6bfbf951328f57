"""Shared helpers of the CLI command modules: options, parsing, output."""

from __future__ import annotations

import argparse
import contextlib
import errno
import json
import os
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from spm_console.cli.streams import stdout_guard
from spm_console.config.load import load_profile
from spm_console.config.plant import PLANT_MODELS
from spm_console.config.schema import DEFAULT_PROFILE, Profile
from spm_console.devices.emulator.faults import FaultNumberError, parse_fault
from spm_console.errors import BadInputError
from spm_console.jsonutil import to_jsonable
from spm_console.numbers import NotANumberError, looks_numeric, parse_integer, parse_number
from spm_console.safe_io import atomic_temp, check_path_names

#: The emulated wrists ``--plant`` chooses from (``[plant] model``).
PLANTS = PLANT_MODELS
#: File names a figure may be written to.
PLOT_SUFFIXES = (".png", ".svg", ".pdf")


def fault_text(text: str) -> str:
    """The ``type`` of ``--fault``: a number in it that is no plain ASCII decimal (``drop:abc``,
    ``drop:1_0``) is a usage error naming the option (exit 2, as in a number option); the
    rest of the fault's rules (its kinds, ranges, non-finite numerals) are checked where the
    command parses it (exit 4)."""
    try:
        parse_fault(text)
    except FaultNumberError as exc:
        if not looks_numeric(exc.text):
            raise argparse.ArgumentTypeError(exc.message) from None
    except BadInputError:
        pass
    return text


def number(text: str) -> float:
    """The ``type`` of every number option: :func:`~spm_console.numbers.parse_number`'s rule,
    the one of CSV files and UDP messages. Text that is no plain ASCII decimal (``1_0``,
    ``١٠``, ``0x10``) is a usage error naming the option (exit 2, like any word where a number
    belongs); a numeral whose value is not finite (``nan``, ``1e999``) is passed on for the
    option's own check to refuse as "must be a finite number" (exit 4)."""
    try:
        return parse_number(text)
    except NotANumberError as exc:
        if looks_numeric(text):
            return float(text)
        raise argparse.ArgumentTypeError(str(exc)) from None


def integer(text: str) -> int:
    """The ``type`` of every integer option: plain ASCII digits
    (:func:`~spm_console.numbers.parse_integer`), else a usage error naming the option."""
    try:
        return parse_integer(text)
    except NotANumberError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_common(p: argparse.ArgumentParser) -> None:
    """--profile and --json, taken by every command."""
    p.add_argument(
        "--profile", default=str(DEFAULT_PROFILE),
        help=f"profile TOML file (default {DEFAULT_PROFILE})",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def add_plant(p: argparse.ArgumentParser, default: str = "the profile's [plant] model",
              when: str = "with --sim: ") -> None:
    """--plant: which emulated wrist a --sim run drives (``default`` words its default;
    ``when``: the condition it applies under, as the command has it)."""
    p.add_argument("--plant", choices=PLANTS, default=None,
                   help=f"{when}the emulated wrist, ideal servos (eq. 27 with the "
                        "profile's p) or the physical wrist (MX-106 drives on the rigid-body "
                        f"chain) (default: {default})")


def console_plant(profile: Profile, plant: str | None) -> str | None:
    """The console's emulated wrist: ``plant`` when given, the profile's ``[plant] model``
    when it names one, else the physical wrist (a lab's first day meets a servo that is not
    the planner's model, and the console says so and offers to identify it)."""
    if plant is not None or "model" in profile.plant.model_fields_set:
        return plant
    return "physical"


def with_plant(profile: Profile, plant: str | None) -> Profile:
    """``profile`` with ``[plant] model`` set to ``plant`` (unchanged for None)."""
    return profile if plant is None else profile.with_plant_model(plant)


def profile_of(args: argparse.Namespace) -> Profile:
    """The profile named by --profile, with --plant applied where the command takes it."""
    return with_plant(load_profile(args.profile), getattr(args, "plant", None))


def add_force(p: argparse.ArgumentParser) -> None:
    """--force: the command's --out may replace an existing file."""
    p.add_argument("--force", action="store_true",
                   help="replace the --out file when it exists (otherwise refused)")


def output_file(path: Path | None, what: str, suffixes: tuple[str, ...] = (),
                replace: bool = True) -> None:
    """Refuse, before any work, an output path the system cannot name, whose folder is
    missing or not writable, or whose suffix is wrong; and, unless ``replace``, one that exists
    (the command's ``--force`` replaces it)."""
    if path is None:
        return
    check_path_names(path, what, BadInputError)
    if suffixes and path.suffix.lower() not in suffixes:
        raise BadInputError(f"{what} {path}: use a {', '.join(suffixes)} file name")
    folder = path.parent
    try:
        if not folder.is_dir():
            why = "is not a folder" if folder.exists() else "does not exist"
            raise BadInputError(f"{what} {path}: the folder {folder} {why}")
        if path.is_dir():
            raise BadInputError(f"{what} {path}: is a folder; give a file name")
        if path.exists() and not path.is_file():
            raise BadInputError(f"{what} {path}: exists and is not a regular file; not replaced")
        if not replace and (path.exists() or path.is_symlink()):
            raise BadInputError(f"{what} {path}: the file exists; pass --force to replace it")
    except OSError as exc:
        raise BadInputError(f"{what} {path}: {exc.strerror or exc}") from None
    try:  # the folder writable: a file made there as the result will be, then removed
        fd, probe = atomic_temp(path)
        os.close(fd)
        probe.unlink()
    except OSError as exc:
        raise BadInputError(f"{what} {path}: cannot write there: {exc.strerror or exc}") from None


def output_folder(path: str | Path | None, what: str) -> None:
    """Refuse, before any work, an output folder the system cannot name, or that is a file or
    lies under one."""
    if path is None:
        return
    p = Path(path)
    check_path_names(p, what, BadInputError)
    anc = p
    try:
        while not anc.exists() and anc != anc.parent:
            anc = anc.parent
        if not anc.is_dir():
            raise BadInputError(f"{what} {p}: {anc} is a file, not a folder")
    except OSError as exc:
        raise BadInputError(f"{what} {p}: {exc.strerror or exc}") from None


#: Set once a command has written its result to stdout (then a later failure adds no JSON).
EMITTED = threading.Event()


def emit(args: argparse.Namespace, data: dict[str, Any] | list[Any], human: str) -> None:
    """JSON on stdout with --json, otherwise the human-readable text."""
    EMITTED.set()
    stream = stdout_guard.out()
    if getattr(args, "json", False):
        stream.write(json.dumps(to_jsonable(data)) + "\n")
    else:
        stream.write(human.rstrip("\n") + "\n")
    stream.flush()


def info(msg: str) -> None:
    """A diagnostic line on stderr."""
    sys.stderr.write(msg.rstrip("\n") + "\n")
    sys.stderr.flush()


@contextlib.contextmanager
def output_may_be_gone() -> Iterator[None]:
    """Around the last output of a command that moved the wrist: a write to a terminal that
    closed (EIO, after SIGHUP) or to a closed pipe (EPIPE) is dropped, and stdout / stderr
    point at /dev/null from then on, so the process still exits with the run's code."""
    try:
        yield
    except OSError as exc:
        if exc.errno not in (errno.EIO, errno.EPIPE):
            raise
        devnull = os.open(os.devnull, os.O_WRONLY)
        for fd in (1, 2):
            os.dup2(devnull, fd)
        os.close(devnull)
        stdout_guard.silence()
