"""Without an IMU the operator names the leg a nudge moved and which way its elbow went: the
question asked per leg, checked against finite differences of the elbow's position (it sits
on w_i, eq. 2), and the answers read on the terminal."""

from __future__ import annotations

import io
import os

import numpy as np
import pytest

from spm_console.cli.commission import ask_on_terminal
from spm_console.config.load import load_profile
from spm_console.config.models import model_of
from spm_console.errors import BadInputError
from spm_console.services.commissioning.leg_map import elbow_motions, operator_match
from tests.support.paths import ROOT


@pytest.mark.parametrize("name", ["agile_wrist", "coaxial_spm"])
def test_each_leg_is_asked_what_a_growing_angle_shows(name: str) -> None:
    profile = load_profile(ROOT / "profiles" / f"{name}.toml")
    model = model_of(profile)
    home = np.asarray(profile.home.theta_deg, float)
    for i, motion in enumerate(elbow_motions(model, home)):
        step = np.zeros(3)
        step[i] = 1e-3
        before = model.geom.w(np.radians(home))[i]
        after = model.geom.w(np.radians(home + step))[i]
        if motion.question == "up or down":
            assert motion.answers[0] == ("up" if after[2] > before[2] else "down")
        else:  # coaxial: the elbows swing about the vertical axis
            turn = np.cross(before, after)[2]
            assert motion.answers[0] == ("counter-clockwise" if turn > 0 else "clockwise")
        grows = operator_match(7, i + 1, motion.answers[0], motion, 1.8)
        shrinks = operator_match(7, i + 1, motion.answers[1], motion, 1.8)
        assert (grows.direction, shrinks.direction, grows.source) == (1, -1, "operator")


def _stdin(monkeypatch: pytest.MonkeyPatch, text: str) -> None:
    r, w = os.pipe()
    os.write(w, text.encode())
    os.close(w)
    monkeypatch.setattr("sys.stdin", io.TextIOWrapper(io.FileIO(r, "r")))


def test_answers_are_taken_by_unique_prefix_after_a_wrong_one(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    _stdin(monkeypatch, "sideways\nU\ncounter\n")
    assert ask_on_terminal("which way?", ("up", "down", "again")) == "up"
    assert ask_on_terminal("turn?", ("counter-clockwise", "clockwise")) == "counter-clockwise"
    assert "answer one of: up, down, again" in capsys.readouterr().err


def test_a_closed_stdin_or_endless_nonsense_is_bad_input(monkeypatch: pytest.MonkeyPatch) -> None:
    _stdin(monkeypatch, "")
    with pytest.raises(BadInputError, match="stdin closed"):
        ask_on_terminal("which leg?", ("1", "2", "3"))
    _stdin(monkeypatch, "x\n" * 10)
    with pytest.raises(BadInputError, match="no valid answer"):
        ask_on_terminal("which leg?", ("1", "2", "3"))
