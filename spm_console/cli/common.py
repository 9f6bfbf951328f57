"""Shared helpers of the CLI command modules: options, parsing, output."""

from __future__ import annotations

import argparse
import contextlib
import errno
import json
import math
import os
import sys
from collections.abc import Iterator
from typing import Any

import numpy as np

from spm_console.errors import BadInputError
from spm_console.jsonutil import to_jsonable
from spm_console.profile import DEFAULT_PROFILE, Profile, load_profile


def add_common(p: argparse.ArgumentParser) -> None:
    """--profile and --json, taken by every command."""
    p.add_argument(
        "--profile", default=str(DEFAULT_PROFILE),
        help=f"profile TOML file (default {DEFAULT_PROFILE})",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def profile_of(args: argparse.Namespace) -> Profile:
    return load_profile(args.profile)


def finite3(values: list[float] | None, what: str) -> np.ndarray:
    """Validate three finite numbers given on the command line (degrees)."""
    if values is None or len(values) != 3:
        raise BadInputError(f"{what}: expected three angles in degrees")
    if not all(math.isfinite(v) for v in values):
        raise BadInputError(f"{what}: angles must be finite numbers, got {values}")
    return np.asarray(values, float)


def emit(args: argparse.Namespace, data: dict[str, Any] | list[Any], human: str) -> None:
    """JSON on stdout with --json, otherwise the human-readable text."""
    if getattr(args, "json", False):
        sys.stdout.write(json.dumps(to_jsonable(data)) + "\n")
    else:
        sys.stdout.write(human.rstrip("\n") + "\n")
    sys.stdout.flush()


def info(msg: str) -> None:
    """A diagnostic line on stderr."""
    sys.stderr.write(msg.rstrip("\n") + "\n")
    sys.stderr.flush()


def fmt_vec(v: Any, digits: int = 4) -> str:
    return "[" + ", ".join(f"{float(x):.{digits}f}" for x in np.ravel(v)) + "]"


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
