"""Step 0 commissions the wrist as built (key 0, F10; its form's refusals:
``test_commission_form.py``): started after a yes/no, each stage's line streams into the
step's log, the result stays on the step, the profile is written beside the profile in use
with the ids as built, and "Use the commissioned profile now?" restarts the console on it
with the workspace kept. SPACE reaches commissioning's own motion process."""

from __future__ import annotations

import asyncio
import json
import os
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from textual.widgets import RichLog

from spm_console.config.load import load_profile
from spm_console.config.schema import Profile
from spm_console.devices.emulator.bus import EmulatorHandle, start_emulator
from spm_console.motion.logs.runlog import load_run
from spm_console.services.commissioning.imu_stage import FIT_POSES, HELD_OUT
from spm_console.tui.screens.commission import CommissionScreen
from spm_console.tui.switch import SwitchRequest
from spm_console.tui.widgets.answer import AnswerScreen
from spm_console.tui.widgets.checkbox import TickBox
from spm_console.tui.widgets.confirm import LongConfirm
from spm_console.tui.widgets.field import TextField
from tests.conftest import ROOT
from tests.support.console_helpers import screen_text, settle, status_of, text_of
from tests.support.wiring import IDS, REVERSED, Operator, as_built

pytestmark = pytest.mark.realtime  # an emulated bus on the wall clock (see tests/conftest.py)

POSES = FIT_POSES + HELD_OUT

SMALL = (80, 24)
TWIN = ROOT / "tests" / "data" / "as_built" / "twin.toml"


def _fill(app, bus: str, imu: str) -> None:  # type: ignore[no-untyped-def]
    app.screen.query_one("#bus-port", TextField).value = bus
    app.screen.query_one("#imu-port", TextField).value = imu


async def test_an_imu_port_that_does_not_open_is_shown_on_the_step(
        console, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    app = console()
    async with app.run_test(size=SMALL) as pilot:
        await settle(pilot)
        await pilot.press("0")
        await settle(pilot)
        _fill(app, f"unix:{tmp_path}/no-bus", f"{tmp_path}/no-imu")
        app.screen.query_one("#jig", TickBox).value = True
        await pilot.press("s")
        await pilot.pause()
        await pilot.press("y")
        await settle(pilot)
        assert isinstance(app.screen, CommissionScreen)
        assert "no-imu" in status_of(app) and "internal error" not in status_of(app), (
            status_of(app))
        log = "\n".join(line.text for line in app.screen.query_one("#stages", RichLog).lines)
        assert "ended:" in log, log
        assert not app.moving and app.stop_elsewhere is None
        assert not list(tmp_path.glob("*.commissioned-*.toml"))


async def test_step_0_is_listed_and_reached_by_f10(console) -> None:  # type: ignore[no-untyped-def]
    app = console()
    async with app.run_test(size=(160, 48)) as pilot:
        await settle(pilot)
        assert "F10 Commission" in screen_text(app)
        await pilot.press("f10")
        await settle(pilot)
        assert isinstance(app.screen, CommissionScreen)
        await pilot.press("question_mark")
        await pilot.pause()
        assert "Start" in screen_text(app) and "F10" in screen_text(app)


@pytest.fixture
def twin() -> Iterator[dict[str, object]]:
    """The physical twin as built, with its IMU and on its jig, in a process of its own."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "spm_console", "emulate", "--plant", "physical", "--as-built",
         str(TWIN), "--imu", "--jig", "--link", "socket", "--duration", "600", "--json"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=dict(os.environ))
    assert proc.stdout is not None
    head = json.loads(proc.stdout.readline())
    yield head
    proc.send_signal(2)
    proc.communicate(timeout=30)


@pytest.mark.slow  # the physical twin: discovery, the map, 32 poses of the IMU stage
async def test_commission_the_twin_from_step_0_and_use_the_profile(
        console, twin: dict[str, object], tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    folder = tmp_path / "profiles"
    folder.mkdir()
    in_use = folder / "agile_wrist.toml"
    in_use.write_bytes((ROOT / "profiles" / "agile_wrist.toml").read_bytes())
    # the console itself on the twin's bus: commissioning releases it first, reconnects after
    app = console(profile_path=in_use, port=str(twin["port"]))
    async with app.run_test(size=SMALL) as pilot:
        await settle(pilot)
        assert app.session.bus is not None and not app.session.sim
        await pilot.press("0")
        await settle(pilot)
        assert app.screen.query_one("#bus-port", TextField).value == str(twin["port"])
        app.screen.query_one("#imu-port", TextField).value = str(twin["imu_port"])
        app.screen.query_one("#jig", TickBox).value = True
        await pilot.press("s")
        await pilot.pause()
        assert isinstance(app.screen, LongConfirm)
        assert "nudged" in text_of(app, "#confirm-body")
        assert "closed first and opened again after" in text_of(app, "#confirm-body")
        await pilot.press("y")
        await pilot.pause()
        assert app.moving  # steps locked, SPACE armed
        await settle(pilot, timeout_s=240)
        assert isinstance(app.screen, LongConfirm), (status_of(app), "\n".join(
            line.text for line in app.screen.query_one("#stages", RichLog).lines))
        assert "Use the commissioned profile now?" in screen_text(app)
        step = app.screen_stack[-2]
        assert isinstance(step, CommissionScreen)
        log = "\n".join(line.text for line in step.query_one("#stages", RichLog).lines)
        for stage in ("console: closing its own connection", "discover:", "jig:", "map: nudging",
                      "map: leg 1 = id 3", f"imu: pose {POSES}/{POSES}", "verify: held-out",
                      "console: connecting to", "written:"):
            assert stage in log, log
        assert app.session.bus is not None  # connected again
        result = str(step.query_one("#commission-result").render())
        assert "leg 1: servo id 3" in result and "tick offsets from the jig" in result, result
        written = sorted(folder.glob("agile_wrist.commissioned-*.toml"))
        assert len(written) == 1 and re.match(
            r"^agile_wrist\.commissioned-\d{4}-\d{2}-\d{2}T\d{6}Z\.toml$", written[0].name), written
        built = load_profile(written[0])
        assert [j.id for j in built.bus.joints] == [3, 1, 2]
        assert [j.direction for j in built.bus.joints] == [1, -1, 1]
        await pilot.press("y")
        await settle(pilot)
    request = app.return_value
    assert isinstance(request, SwitchRequest) and request.profile_path == written[0]
    assert not app.moving and app.stop_elsewhere is None


class _Client:
    """Stands in for a stage's motion process: records the E-stops it is sent."""

    def __init__(self) -> None:
        self.estops: list[tuple[str, bool]] = []

    def estop(self, reason: str, by_signal: bool = False) -> None:
        self.estops.append((reason, by_signal))


async def test_space_stops_commissioning_in_its_motion_process_and_the_console_lives_on(
        console, monkeypatch: pytest.MonkeyPatch) -> None:  # type: ignore[no-untyped-def]
    import threading

    from spm_console.tui.screens import commission as step0

    client = _Client()
    attached = threading.Event()

    def fake(profile, profile_path, form, stop, on_stage, *_rest):  # type: ignore[no-untyped-def]
        on_stage("map: nudging servo id 1 by 2°")
        stop.attach(client)  # type: ignore[arg-type]
        attached.set()
        for _ in range(500):  # a nudge under way until the E-stop comes
            if client.estops:
                break
            threading.Event().wait(0.01)
        stop.detach()
        stop.check()  # the stage refuses to go on
        raise AssertionError("not stopped")

    monkeypatch.setattr(step0, "commission_blocking", fake)
    app = console()
    async with app.run_test(size=SMALL) as pilot:
        await settle(pilot)
        await pilot.press("0")
        await settle(pilot)
        _fill(app, "unix:/tmp/no-such-bus", "/dev/pts/99")
        app.screen.query_one("#jig", TickBox).value = True
        await pilot.press("s")
        await pilot.pause()
        await pilot.press("y")
        await pilot.pause()
        assert app.moving and app.stop_elsewhere is not None
        await asyncio.to_thread(attached.wait, 5)
        await pilot.press("1")  # steps are locked while it runs
        assert isinstance(app.screen, CommissionScreen)
        await pilot.press("space")
        await settle(pilot)
        assert client.estops == [("operator E-stop (SPACE)", False)]
        assert "commission stopped: operator E-stop (SPACE)" in status_of(app), status_of(app)
        assert not app.moving and app.stop_elsewhere is None
        log = "\n".join(line.text for line in app.screen.query_one("#stages", RichLog).lines)
        assert "map: nudging servo id 1" in log and "ended: commission stopped" in log, log
        await pilot.press("1")  # the console goes on
        await settle(pilot)
        assert app.current_mode == "connect"


@pytest.fixture
def wired(agile: Profile) -> Iterator[EmulatorHandle]:
    """The emulated bus of a wrist wired otherwise than its profile says
    (:mod:`tests.support.wiring`), at rest on its jig, in this process."""
    switch = sys.getswitchinterval()
    sys.setswitchinterval(0.0005)  # threads of this process answer the bus
    em = start_emulator(as_built(agile), record=False, link="socket")
    yield em
    em.stop()
    sys.setswitchinterval(switch)


async def _next_question(pilot, timeout_s: float = 60.0) -> AnswerScreen | None:  # type: ignore[no-untyped-def]
    """The question the worker asks next (None once it no longer asks: the worker ended)."""
    app = pilot.app
    loop = asyncio.get_running_loop()
    t_end = loop.time() + timeout_s
    while loop.time() < t_end:
        await pilot.pause(0.02)
        if isinstance(app.screen, AnswerScreen):
            return app.screen
        if not app.moving and not any(w.is_running for w in app.workers):
            return None
    raise TimeoutError("no question and the worker still runs")


async def _closed(pilot, screen: AnswerScreen, timeout_s: float = 10.0) -> None:  # type: ignore[no-untyped-def]
    """Wait until ``screen`` is no longer shown (TimeoutError after ``timeout_s``)."""
    loop = asyncio.get_running_loop()
    t_end = loop.time() + timeout_s
    while pilot.app.screen is screen:
        if loop.time() >= t_end:
            raise TimeoutError("the question is still shown")
        await pilot.pause(0.02)


def _profile_in_use(tmp_path: Path) -> Path:
    folder = tmp_path / "profiles"
    folder.mkdir()
    in_use = folder / "agile_wrist.toml"
    in_use.write_bytes((ROOT / "profiles" / "agile_wrist.toml").read_bytes())
    return in_use


async def _start_without_imu(app, pilot, port: str) -> None:  # type: ignore[no-untyped-def]
    await settle(pilot)
    await pilot.press("0")
    await settle(pilot)
    _fill(app, port, "")
    app.screen.query_one("#jig", TickBox).value = True
    app.screen.query_one("#imu-stage", TickBox).value = False
    await pilot.press("s")
    await pilot.pause()
    assert isinstance(app.screen, LongConfirm), status_of(app)
    assert "you are asked which leg's arm moved" in text_of(app, "#confirm-body")
    await pilot.press("y")


async def test_without_an_imu_the_operator_answers_which_arm_moved_in_a_dialog(
        console, agile: Profile, wired: EmulatorHandle, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """Each nudge's question in a dialog, answered by its keys ("again" first: the nudge is
    made again); the profile written maps the legs as built; the run is on the Logs step's
    root with every question and answer."""
    operator = Operator(wired, agile)
    app = console(profile_path=_profile_in_use(tmp_path))
    async with app.run_test(size=(100, 30)) as pilot:
        await _start_without_imu(app, pilot, wired.port)
        while (asked := await _next_question(pilot)) is not None:
            assert app.moving  # SPACE armed while the operator looks
            answer = operator(asked.question, asked.answers)
            await pilot.press(asked.keys[asked.answers.index(answer)])
        await settle(pilot)
        assert isinstance(app.screen, LongConfirm), status_of(app)
        assert "Use the commissioned profile now?" in screen_text(app)
        step = app.screen_stack[-2]
        assert isinstance(step, CommissionScreen)
        assert "leg 1: servo id 3" in str(step.query_one("#commission-result").render())
        await pilot.press("n")
        await settle(pilot)
    assert len(operator.questions) == 7
    (written,) = (tmp_path / "profiles").glob("agile_wrist.commissioned-*.toml")
    built = load_profile(written)
    assert [(j.id, j.direction) for j in built.bus.joints] == [
        (i, j.direction * d) for i, j, d in zip(IDS, agile.bus.joints, REVERSED, strict=True)]
    (run_dir,) = [d for d in (tmp_path / "logs").iterdir() if "commission" in d.name]
    asked_events = [e for e in load_run(run_dir).events if e["event"] == "asked"]
    assert [e["question"] for e in asked_events] == operator.questions
    assert not app.moving and app.stop_elsewhere is None


@pytest.mark.parametrize(("key", "outcome", "said"), [
    ("space", "stopped", "E-stop"),
    ("escape", "refused", "no answer"),
])
async def test_space_or_esc_at_a_question_ends_commissioning_and_writes_nothing(
        console, wired: EmulatorHandle, tmp_path: Path, key: str, outcome: str,
        said: str) -> None:  # type: ignore[no-untyped-def]
    """SPACE at the question E-stops (the wrist holds where the nudge left it); esc gives up:
    the nudged servo goes back, and the stage ends refused. Either way the dialog closes and
    nothing is written."""
    rest = np.asarray(wired.joint_deg(), float)
    app = console(profile_path=_profile_in_use(tmp_path))
    async with app.run_test(size=(100, 30)) as pilot:
        await _start_without_imu(app, pilot, wired.port)
        asked = await _next_question(pilot)
        assert asked is not None and "which leg" in asked.question
        await pilot.press(key)
        # esc closes the dialog at once; after SPACE the worker closes it when it next looks
        # at the E-stop (every 0.1 s)
        await _closed(pilot, asked)
        assert await _next_question(pilot) is None  # no other question: the worker ended
        await settle(pilot)
        assert isinstance(app.screen, CommissionScreen)
        assert said in status_of(app), status_of(app)
        assert not app.moving and app.stop_elsewhere is None
    assert not list((tmp_path / "profiles").glob("*.commissioned-*.toml"))
    (run_dir,) = [d for d in (tmp_path / "logs").iterdir() if "commission" in d.name]
    assert load_run(run_dir).meta["outcome"] == outcome
    moved = np.abs(np.asarray(wired.joint_deg(), float) - rest).max()
    if key == "escape":
        assert moved < 0.2  # the nudge went back
    else:
        assert moved > 1.0  # held where the nudge had brought it
