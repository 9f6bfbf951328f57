"""Step 6: browse the run logs and plot one (reference, measured, model; velocities)."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Horizontal, Vertical
from textual.content import Content
from textual.widgets import DataTable, Static

from spm_console.tui.messages import Outcome, RunOpened
from spm_console.tui.screens.base import StepScreen
from spm_console.tui.widgets.plot import PlotView, Series

PLOTS = ("positions", "velocities", "tracking error")


def run_text(run: Any) -> str:
    m = run.meta
    lines = [
        f"{m.get('run', run.path.name)}: {m.get('kind', '?')} on {m.get('bus', '?')}",
        f"outcome {m.get('outcome', '?')} (exit code {m.get('exit_code')}): {m.get('message', '')}",
        f"{run.rows} samples, {len(run.events)} events"
        + ("  (last line truncated)" if run.truncated else ""),
        f"folder {run.path}",
    ]
    faults = [e for e in run.events if e.get("event") in ("fault", "stop")]
    for e in faults[:3]:
        lines.append(f"  t = {e.get('t', 0):.2f} s {e.get('event')}: "
                     f"{e.get('message', e.get('kind', ''))}")
    return "\n".join(lines)


class LogsScreen(StepScreen):
    MODE = "logs"
    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("r", "reload", "Refresh"),
        Binding("enter", "open", "Open run", show=True),
        Binding("p", "next_plot", "Plot"),
        Binding("j", "next_joint", "Joint"),
    ]

    def __init__(self) -> None:
        super().__init__()
        self.plot_kind = 0
        self.joint = 0
        self.run: Any = None

    def compose_body(self) -> ComposeResult:
        with Horizontal(classes="body"):
            yield DataTable(id="runs", cursor_type="row", zebra_stripes=True)
            with Vertical(id="run-detail"):
                yield Static(id="run-text", markup=False, classes="result")
                yield PlotView(id="run-plot")

    def on_mount(self) -> None:
        self.query_one("#runs", DataTable).add_columns("run", "kind", "outcome", "samples")
        self.query_one("#run-text", Static).update(Content(
            "Pick a run with ↑/↓ and press Enter to plot it."))

    def on_screen_resume(self) -> None:
        super().on_screen_resume()
        self.action_reload()

    def action_reload(self) -> None:
        from spm_console.run.runlog import list_runs

        table = self.query_one("#runs", DataTable)
        table.clear()
        try:
            runs = list_runs(self.session.logs_root)
        except OSError as exc:
            self.status.error(f"cannot list the logs: {exc}")
            return
        for r in reversed(runs):  # newest first
            m = r.meta
            table.add_row(r.name, str(m.get("kind", "?")), str(m.get("outcome", "?")),
                          str(m.get("samples", "")), key=str(r.path))
        table.focus()
        self.status.ok(f"{len(runs)} runs under {self.session.logs_root or 'logs'}/"
                       if runs else "no runs logged yet: execute a plan first (step 5)")

    def action_open(self) -> None:
        table = self.query_one("#runs", DataTable)
        if table.row_count == 0:
            self.status.error("no runs to open")
            return
        key = table.coordinate_to_cell_key(table.cursor_coordinate).row_key.value
        from spm_console.run.runlog import load_run

        self.run_blocking("open", lambda: RunOpened(load_run(str(key))), "reading the run …")

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:
        event.stop()
        self.action_open()

    def action_next_plot(self) -> None:
        self.plot_kind = (self.plot_kind + 1) % len(PLOTS)
        self.draw()

    def action_next_joint(self) -> None:
        self.joint = (self.joint + 1) % 3
        self.draw()

    def handle_done(self, outcome: Outcome) -> None:
        if isinstance(outcome, RunOpened):
            result = self.run = outcome.run
            self.query_one("#run-text", Static).update(Content(run_text(result)))
            self.draw()
            self.status.ok(f"run {result.path.name}: p changes the plot, j the joint")

    def draw(self) -> None:
        run = self.run
        if run is None or run.rows < 2:
            return
        view = self.query_one("#run-plot", PlotView)
        t = run.columns["t"]
        j = self.joint
        kind = PLOTS[self.plot_kind]
        if kind == "positions":
            series = [Series("reference θ*", run.vec("ref")[:, j], "yellow", faint=True),
                      Series("model θ", run.vec("pred")[:, j], "blue", faint=True),
                      Series("measured θ", run.vec("meas")[:, j], "red")]
            title = f"joint {j + 1}: positions [deg]"
        elif kind == "velocities":
            series = [Series("model", run.vec("pred_vel")[:, j], "blue", faint=True),
                      Series("finite difference", run.vec("fd_vel")[:, j], "yellow", faint=True),
                      Series("Kalman filter", run.vec("vel")[:, j], "red")]
            title = f"joint {j + 1}: velocities [deg/s]"
        else:
            err = run.vec("meas")[:, j] - run.vec("pred")[:, j]
            series = [Series("measured − model", np.asarray(err), "red")]
            title = f"joint {j + 1}: tracking error [deg]"
        view.plot(title, t, series)
