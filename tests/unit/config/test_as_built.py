"""As-built files: strict, bounded, neutral by default; a broken one names file, key and value."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from spm_console.config.as_built import (
    MAX_AS_BUILT_BYTES,
    AsBuilt,
    AsBuiltError,
    load_as_built,
    parse_as_built_text,
)
from spm_console.errors import ExitCode
from tests.support.paths import ROOT

DATA = ROOT / "tests" / "data" / "as_built"


def test_an_empty_file_is_the_profiles_wrist() -> None:
    ab = parse_as_built_text("", "empty.toml")
    assert ab == AsBuilt() and ab.neutral and ab.ids == ()
    assert parse_as_built_text("[as_built]\n", "x").neutral


def test_every_key_is_read() -> None:
    ab = load_as_built(DATA / "twin.toml")
    assert ab.ids == (3, 1, 2) and ab.direction == (1, -1, 1)
    assert ab.horn_offset_deg == (4.0, -7.5, 12.25)
    assert ab.alpha1_error_deg == (-0.4, 0.25, 0.1) and ab.alpha2_error_deg == (0.2, -0.35, 0.3)
    assert ab.base_tilt_deg == (3.0, -2.0) and ab.imu_mount_rpy_deg == (5.0, -3.0, 20.0)
    assert ab.payload_kg == 0.3 and ab.payload_com_mm == (10.0, -5.0, 120.0)
    assert not ab.neutral


@pytest.mark.parametrize(("name", "words"), [
    ("horn_offset_too_far.toml", ["as_built.horn_offset_deg[1]", "31", "-30 ≤", "≤ 30"]),
    ("duplicate_ids.toml", ["ids = [1, 2, 1]", "distinct"]),
    ("payload_bool.toml", ["as_built.payload_kg", "boolean", "0 ≤ payload_kg ≤ 2"]),
    ("unknown_key.toml", ["as_built.wobble", "unknown key"]),
    ("bad_toml.toml", ["not valid TOML"]),
])
def test_a_broken_file_names_file_key_and_value(name: str, words: list[str]) -> None:
    with pytest.raises(AsBuiltError) as err:
        load_as_built(DATA / name)
    assert err.value.exit_code == ExitCode.BAD_INPUT
    assert str(DATA / name) in err.value.message
    for w in words:
        assert w in err.value.message, err.value.message


@pytest.mark.parametrize(("text", "key"), [
    ("ids = [1, 2, 253]", "ids[2]"),
    ("ids = [1, 2]", "ids"),
    ("direction = [1, 0, 1]", "direction[1]"),
    ("direction = [1, -1.0, 1]", "direction[1]"),
    ("alpha1_error_deg = [0, 2.5, 0]", "alpha1_error_deg[1]"),
    ("alpha2_error_deg = [-2.01, 0, 0]", "alpha2_error_deg[0]"),
    ("base_tilt_deg = [0, 10.5]", "base_tilt_deg[1]"),
    ("base_tilt_deg = [0, 0, 0]", "base_tilt_deg"),
    ("imu_mount_rpy_deg = [0, 0, -31]", "imu_mount_rpy_deg[2]"),
    ("payload_kg = -0.1", "payload_kg"),
    ("payload_kg = 2.5", "payload_kg"),
    ("payload_kg = \"1\"", "payload_kg"),
    ("payload_com_mm = [0, 0, 250]", "payload_com_mm[2]"),
    ("payload_com_mm = [0, 0, inf]", "payload_com_mm[2]"),
    ("horn_offset_deg = [nan, 0, 0]", "horn_offset_deg[0]"),
])
def test_each_bound_holds(text: str, key: str) -> None:
    with pytest.raises(AsBuiltError) as err:
        parse_as_built_text(f"[as_built]\n{text}\n", "ab.toml")
    assert err.value.message.startswith("ab.toml: key 'as_built"), err.value.message
    assert key in err.value.message


def test_the_edges_of_each_range_are_allowed() -> None:
    ab = parse_as_built_text(
        "[as_built]\nids = [0, 252, 7]\nhorn_offset_deg = [-30, 30, 0]\n"
        "alpha1_error_deg = [-2, 2, 0]\nbase_tilt_deg = [-10, 10]\n"
        "imu_mount_rpy_deg = [-30, 30, 0]\npayload_kg = 2\npayload_com_mm = [-200, 200, 0]\n", "x")
    assert ab.ids == (0, 252, 7) and ab.payload_kg == 2.0


def test_a_large_file_or_a_fifo_is_refused_unread(tmp_path: Path) -> None:
    big = tmp_path / "big.toml"
    big.write_text("# " + "x" * MAX_AS_BUILT_BYTES + "\n")
    with pytest.raises(AsBuiltError, match="larger than"):
        load_as_built(big)
    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)
    with pytest.raises(AsBuiltError, match="not a regular file"):
        load_as_built(fifo)
    with pytest.raises(AsBuiltError, match="cannot read"):
        load_as_built(tmp_path / "missing.toml")


@pytest.mark.parametrize(("text", "words"), [
    ("as_built = 5", ["key 'as_built' = 5", "must be a table"]),
    ("[as_built]\nids = 3", ["as_built.ids", "must be an array"]),
    ("[as_built]\nbase_tilt_deg = [0, 0, 0, 0]", ["base_tilt_deg", "at most 2 items, got 4"]),
    ("[as_built]\nhorn_offset_deg = [1]",
     ["key 'as_built.horn_offset_deg' = [1]: must have 3 items, got 1"]),
    ("[as_built]\nids = [" + ", ".join(["1"] * 30000) + "]", ["(30000 given)", "distinct"]),
])
def test_a_wrong_shape_is_said_in_the_files_words_and_briefly(text: str, words: list[str]) -> None:
    """Tables, arrays and their lengths in TOML's words, not the validator's ("Input should be
    a valid dictionary or instance of AsBuilt"); a huge array is not echoed whole (90 kB)."""
    with pytest.raises(AsBuiltError) as err:
        parse_as_built_text(text + "\n", "ab.toml")
    msg = err.value.message
    assert "missing key" not in msg and msg.count("\n") == 0, msg  # one line, not one per item
    assert "Input should" not in msg and "after validation" not in msg and len(msg) < 500, msg
    for w in words:
        assert w in msg, msg
