"""``commission`` on the physical twin as built (tests/data/as_built/twin.toml: ids permuted,
a reversed servo, horn offsets up to 12°, arcs 0.4° off, the base tilted, the IMU mounted 20°
off, a payload): ``emulate --as-built --imu --jig`` in its own process, ``commission`` reading
nothing of the as-built file; the written profile reads the true joint angles."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from spm_console.cli.main import main
from spm_console.config.as_built import load_as_built
from spm_console.config.load import load_profile
from spm_console.devices.dynamixel.tick_map import joint_maps
from spm_console.devices.emulator.twin import true_wrist
from tests.support.paths import ROOT

AGILE = ROOT / "profiles" / "agile_wrist.toml"
TWIN = ROOT / "tests" / "data" / "as_built" / "twin.toml"


@pytest.fixture
def twin(tmp_path: Path) -> Iterator[dict[str, object]]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "spm_console", "emulate", "--plant", "physical", "--as-built",
         str(TWIN), "--imu", "--jig", "--link", "socket", "--truth-log",
         str(tmp_path / "truth.csv"), "--duration", "600", "--json"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=dict(os.environ))
    assert proc.stdout is not None
    head = json.loads(proc.stdout.readline())
    yield head
    proc.send_signal(2)
    proc.communicate(timeout=30)


def _errors_deg(written: Path) -> list[float]:
    """How far the written profile reads each leg's true angle, deg, over its range."""
    built = load_profile(written)
    truth = true_wrist(load_profile(AGILE), load_as_built(TWIN))
    out = []
    for m, tj in zip(joint_maps(built), truth.joints, strict=True):
        assert m.id == tj.id
        for th in np.linspace(m.min_deg + 5.0, m.max_deg - 5.0, 7):
            out.append(abs(m.to_deg(tj.present_ticks(float(th))) - float(th)))
    return out


@pytest.mark.slow  # the physical twin: the map, then 32 poses of the IMU stage
def test_commission_finds_the_twin_as_built(twin: dict[str, object], tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    assert twin["imu_port"] and twin["as_built"]
    out = tmp_path / "built.toml"
    rc = main(["commission", "--profile", str(AGILE), "--port", str(twin["port"]),
               "--imu-port", str(twin["imu_port"]), "--jig", "--payload-kg", "0.3", "--out",
               str(out), "--json"])
    d = json.loads(capsys.readouterr().out)
    assert rc == 0, d
    assert [(leg["leg"], leg["id"], leg["direction"]) for leg in d["legs"]] == [
        (1, 3, 1), (2, 1, -1), (3, 2, 1)]
    assert max(_errors_deg(out)) < 0.25  # the jig's target; the IMU stage refines within it
    assert d["imu_fit"]["held_out_gravity_max_deg"] < 0.15
    built = load_as_built(TWIN)
    # the base's tilt, as fitted, is the load model's gravity: the truth within 3σ (+0.01°)
    written_tilt = load_profile(out).plant.base_tilt_deg
    fitted = {p["name"]: p for p in d["imu_fit"]["parameters"]}
    for k, name in enumerate(("tilt_x", "tilt_y")):
        assert (abs(written_tilt[k] - built.base_tilt_deg[k])
                <= 3.0 * fitted[name]["std_deg"] + 0.01), (written_tilt, fitted[name])
    # the payload's first moment: the truth within three of the fit's standard errors (the
    # issue's 10 % is not met on every wrist, see docs/decisions/commissioning.md)
    truth = built.payload_kg * np.asarray(built.payload_com_mm, float)  # kg·mm
    payload = d["imu_fit"]["payload"]
    err = np.abs(np.asarray(payload["first_moment_kgmm"]) - truth)
    assert (err <= 3.0 * np.asarray(payload["first_moment_std_kgmm"])).all(), payload
    # the load model is written: the payload seen (m·c far above its errors), the compliance
    written = load_profile(out)
    assert written.plant.payload_moment_kgmm is not None
    np.testing.assert_allclose(written.plant.payload_moment_kgmm, payload["first_moment_kgmm"],
                               atol=0.05)
    if payload["compliance_std_deg_per_nm"] <= 0.1 * payload["compliance_deg_per_nm"]:
        assert written.servo.load_deg_per_nm == pytest.approx(
            payload["compliance_deg_per_nm"], abs=1e-4)
    else:
        assert written.servo.load_deg_per_nm is None  # the profile's own: none
    # the mass as weighed, beside m·c: the payload's centre m·c / m, written
    assert written.plant.payload_kg == 0.3 and d["payload_kg"] == 0.3
    centre = np.asarray(d["payload_centre_mm"])
    np.testing.assert_allclose(centre, np.asarray(written.plant.payload_moment_kgmm) / 0.3)
    assert (np.abs(centre - np.asarray(built.payload_com_mm))
            <= 3.0 * np.asarray(payload["first_moment_std_kgmm"]) / 0.3 + 0.2).all(), centre
    assert payload["rest_offset_deg"] is not None
    assert (written.settle.duration_s > 0) == (abs(payload["rest_offset_deg"]) >= 0.044)
