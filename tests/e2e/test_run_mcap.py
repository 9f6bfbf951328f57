"""Run logs as MCAP: written beside the CSV when a run ends, read back with the mcap reader and
its ROS 2 decoder, every sample equal to the CSV's; the run folder a ROS 2 bag (read by
rosbags); ``logs export --mcap`` for older runs."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.interfaces import QosDurability
from rosbags.rosbag2 import Reader

from spm_console.cli.main import main
from spm_console.config.models import model_of
from spm_console.config.schema import Profile
from spm_console.core.kinematics.joint_states import joint_states
from spm_console.motion.logs.mcap_log import MCAP_NAME, platform_rotations, start_ns
from spm_console.motion.logs.runlog import load_run
from spm_console.motion.plans import synthetic_plan
from spm_console.store.plan_file import save_plan
from tests.support.exec_helpers import PAPER_START

RAD = math.pi / 180.0


def _read(path: Path) -> dict[str, list[tuple[int, object]]]:
    """Topic -> [(log time ns, decoded message)], in file order."""
    topics: dict[str, list[tuple[int, object]]] = {}
    with path.open("rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        for _schema, channel, message, decoded in reader.iter_decoded_messages():
            topics.setdefault(channel.topic, []).append((message.log_time, decoded))
    return topics


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory, agile: Profile) -> Path:
    """One execution on the emulated bus (homing skipped and logged), with its log."""
    tmp = tmp_path_factory.mktemp("mcap")
    plan = tmp / "short.json"
    save_plan(synthetic_plan(agile, PAPER_START, np.array([100.0, 120.0, 110.0]), 1.5), plan)
    logs = tmp / "logs"
    code = main(["execute", "--plan", str(plan), "--sim", "--plant", "ideal", "--logs", str(logs),
                 "--skip-homing", "test of logs", "--sim-start",
                 *(f"{x:g}" for x in PAPER_START)])
    assert code == 0
    (run,) = [p for p in logs.iterdir() if p.name.endswith("-execute")]
    return run


def test_every_sample_of_the_csv_is_in_the_mcap(run_dir: Path, agile: Profile) -> None:
    run = load_run(run_dir)
    path = run_dir / MCAP_NAME
    assert path.is_file()
    topics = _read(path)
    t0 = start_ns(run.meta)
    stamps = t0 + np.round(run.columns["t"] * 1e9).astype(np.int64)
    for topic, column, vel in (("/spm/reference", "ref", None), ("/spm/model", "pred", "pred_vel"),
                               ("/spm/measured", "meas", "vel")):
        msgs = topics[topic]
        assert len(msgs) == run.rows, topic  # every read succeeded in this run
        pos = np.array([m.position for _, m in msgs])
        assert np.array_equal(pos, run.vec(column) * RAD), topic
        if vel is not None:
            assert np.array_equal(np.array([m.velocity for _, m in msgs]), run.vec(vel) * RAD)
        assert [t for t, _ in msgs] == stamps.tolist()
        head = msgs[0][1].header.stamp
        assert head.sec * 10**9 + head.nanosec == int(stamps[0])
    err = np.array([m.position for _, m in topics["/spm/error"]])
    assert np.array_equal(err, run.vec("meas") * RAD - run.vec("pred") * RAD)

    # the wrist's joints and the platform: the FK of the measured θ, independently here
    model = model_of(agile)
    meas = run.vec("meas") * RAD
    rots = platform_rotations(model, meas)
    js = joint_states(model, meas, rots)
    states = topics["/joint_states"]
    assert len(states) == run.rows
    assert list(states[0][1].name) == [f"leg{i}_{k}_joint" for k in ("motor", "distal", "platform")
                                       for i in (1, 2, 3)]
    got = np.array([m.position for _, m in states])
    assert np.allclose(got, np.hstack([js.motor, js.distal, js.platform]), atol=1e-12)
    quats = np.array([[m.quaternion.x, m.quaternion.y, m.quaternion.z, m.quaternion.w]
                      for _, m in topics["/spm/platform"]])
    w, x, y, z = quats[:, 3], quats[:, 0], quats[:, 1], quats[:, 2]
    R = np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
                  np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
                  np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1)],
                 -2)
    assert np.allclose(R, rots, atol=1e-12)
    tf = topics["/tf"][0][1].transforms[0]
    assert tf.header.frame_id == "base_link" and tf.child_frame_id == "platform_fk"

    with Reader(run_dir) as bag:  # the folder as rosbag2 opens it: metadata.yaml, the same file
        assert {c.topic: c.msgcount for c in bag.connections} == {k: len(v) for k, v in
                                                                  topics.items()}
        assert sum(1 for _ in bag.messages()) == bag.message_count
        durable = {c.topic for c in bag.connections
                   if c.ext.offered_qos_profiles[0].durability == QosDurability.TRANSIENT_LOCAL}
        assert durable == {"/robot_description"}

    events = [json.loads(m.data) for _, m in topics["/spm/events"]]
    assert events == [json.loads(json.dumps(e)) for e in run.events]
    (urdf,) = topics["/robot_description"]
    assert urdf[1].data.startswith("<?xml") and '"leg1_motor_joint"' in urdf[1].data


def test_logs_export_writes_the_same_file_again(run_dir: Path, tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "again.mcap"
    assert main(["logs", "export", "--mcap", str(run_dir), "--out", str(out), "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)
    assert rec["ok"] and rec["mcap"] == str(out) and rec["profile_digest_matches"] is True
    a, b = _read(run_dir / MCAP_NAME), _read(out)
    assert a.keys() == b.keys()
    assert all(len(a[k]) == len(b[k]) for k in a)
    code = main(["logs", "export", "--mcap", str(run_dir), "--profile", "profiles/coaxial_spm.toml",
                 "--json"])
    assert code == 4
    assert "was logged with profile 'agile_wrist'" in json.loads(capsys.readouterr().out)["error"]
