"""A run folder is a ROS 2 bag: read with rosbags (an independent rosbag2 reader, which
validates metadata.yaml and matches every topic of it to an MCAP channel with the same type and
QoS), its topics, counts, QoS and time span are the run's, and its joint states are the CSV's
(read here with the csv module)."""

from __future__ import annotations

import csv
import datetime as dt
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.interfaces import QosDurability, QosReliability
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

from spm_console.cli.main import main
from spm_console.config.schema import Profile
from spm_console.motion.logs import mcap_log
from tests.unit.motion.test_mcap_log import _run

RAD = math.pi / 180.0
TYPES = {"/robot_description": "std_msgs/msg/String", "/spm/events": "std_msgs/msg/String",
         "/joint_states": "sensor_msgs/msg/JointState", "/spm/reference": "sensor_msgs/msg/JointState",
         "/spm/model": "sensor_msgs/msg/JointState", "/spm/measured": "sensor_msgs/msg/JointState",
         "/spm/error": "sensor_msgs/msg/JointState",
         "/spm/platform": "geometry_msgs/msg/QuaternionStamped", "/tf": "tf2_msgs/msg/TFMessage"}
STORE = get_typestore(Stores.ROS2_HUMBLE)


def _csv(run: Path) -> dict[str, list[str]]:
    with (run / "samples.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    return {k: [r[k] for r in rows] for k in rows[0]}


def _deg(cells: list[str]) -> np.ndarray:
    """A CSV column in rad (NaN where the cell is empty: the read failed)."""
    return np.array([float(c) * RAD if c else math.nan for c in cells])


def _messages(path: Path) -> dict[str, list[tuple[int, Any]]]:
    """A bag's (or an MCAP file's) messages per topic: (time, decoded message)."""
    topics: dict[str, list[tuple[int, Any]]] = {}
    with Reader(path) as reader:
        for conn, t, raw in reader.messages():
            topics.setdefault(conn.topic, []).append((t, STORE.deserialize_cdr(raw, conn.msgtype)))
    return topics


def _check_qos(reader: Reader) -> None:
    """Every topic offered reliable, transient-local for the URDF (sent once), else volatile."""
    for c in reader.connections:
        (qos,) = c.ext.offered_qos_profiles
        assert qos.reliability == QosReliability.RELIABLE, c.topic
        latched = c.topic == "/robot_description"
        assert qos.durability == (QosDurability.TRANSIENT_LOCAL if latched
                                  else QosDurability.VOLATILE), c.topic


def _check_bag(run: Path, agile: Profile) -> None:
    cells = _csv(run)
    rows = len(cells["t"])
    read = [k for k in range(rows) if cells["meas1"][k]]  # rows whose read succeeded
    events = (run / "events.jsonl").read_text().splitlines()
    want = {"/robot_description": 1, "/spm/reference": rows, "/spm/model": rows,
            "/spm/events": len(events)} | {t: len(read) for t in (
                "/spm/measured", "/spm/error", "/joint_states", "/spm/platform", "/tf")}
    with Reader(run) as reader:
        assert {c.topic: c.msgtype for c in reader.connections} == TYPES
        assert {c.topic: c.msgcount for c in reader.connections} == want
        assert reader.message_count == sum(want.values())
        _check_qos(reader)
        start = reader.start_time
        offered = {c.topic: c.ext for c in reader.connections}
    with Reader(run / mcap_log.MCAP_NAME) as alone:  # the MCAP's own channel metadata
        assert {c.topic: c.ext for c in alone.connections} == offered

    topics = _messages(run)
    assert {k: len(v) for k, v in topics.items()} == want  # every topic's channel matched
    meta = json.loads((run / "meta.json").read_text())
    began = dt.datetime.fromisoformat(meta["start_time"]).timestamp()
    assert start == topics["/robot_description"][0][0]
    assert abs(start / 1e9 - began) < 1e-6  # the run's wall-clock start
    stamps = [t for t, _ in topics["/spm/reference"]]
    assert stamps == [start + round(float(c) * 1e9) for c in cells["t"]]

    ref = np.stack([_deg(cells[f"ref{i}"]) for i in (1, 2, 3)], axis=1)
    assert np.array_equal(np.array([m.position for _, m in topics["/spm/reference"]]), ref)
    meas = np.stack([_deg(cells[f"meas{i}"]) for i in (1, 2, 3)], axis=1)[read]
    vel = np.stack([_deg(cells[f"vel{i}"]) for i in (1, 2, 3)], axis=1)[read]
    measured = topics["/spm/measured"]
    assert np.array_equal(np.array([m.position for _, m in measured]), meas)
    assert np.array_equal(np.array([m.velocity for _, m in measured]), vel)
    states = topics["/joint_states"]
    assert [t for t, _ in states] == [stamps[k] for k in read]
    assert all(list(m.name) == [f"leg{n}_{j}_joint" for j in ("motor", "distal", "platform")
                                for n in (1, 2, 3)] for _, m in states)
    home = np.array(agile.home.theta_deg) * RAD  # the motor joints: θ − θ_home
    motors = np.array([m.position[:3] for _, m in states])
    assert np.allclose(motors, meas - home, rtol=0, atol=1e-15)
    urdf = topics["/robot_description"][0][1].data
    assert all(f'<joint name="{n}"' in urdf for n in states[0][1].name[:7])


def test_a_finished_run_is_a_bag(tmp_path: Path, agile: Profile) -> None:
    run = _run(tmp_path, agile)
    mcap_log.mcap_beside(agile)(run)  # what a run does as it finishes
    assert (run / "metadata.yaml").is_file()
    _check_bag(run, agile)


def test_logs_export_makes_an_older_run_a_bag(tmp_path: Path, agile: Profile,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    run = _run(tmp_path, agile)  # as logged before MCAP (or with its MCAP deferred)
    assert main(["logs", "export", "--mcap", str(run), "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)
    assert rec["mcap"] == str(run / "run.mcap")
    assert rec["bag_metadata"] == str(run / "metadata.yaml")
    _check_bag(run, agile)


def test_an_mcap_written_elsewhere_is_the_file_alone(tmp_path: Path, agile: Profile,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    run = _run(tmp_path / "logs", agile)
    out = tmp_path / "copy.mcap"
    assert main(["logs", "export", "--mcap", str(run), "--out", str(out), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["bag_metadata"] is None
    assert sorted(p.name for p in tmp_path.iterdir()) == ["copy.mcap", "logs"]
    assert not (run / "metadata.yaml").exists()
    assert set(_messages(out)) == set(TYPES)
    with Reader(out) as alone:  # the file alone: its channels carry the QoS
        _check_qos(alone)
