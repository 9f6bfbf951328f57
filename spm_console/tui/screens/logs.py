"""Step 6: browse the run logs — outcome, exit code, stop reason, servo-loop time and plan
of each run, a filter by outcome, the log root in use — and plot one (reference, measured, model;
velocities)."""

from __future__ import annotations

from pathlib import Path
from typing import ClassVar

import numpy as np
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.content import Content
from textual.widgets import DataTable, Static

from spm_console.errors import BadInputError
from spm_console.formatting import fmt_deg
from spm_console.motion.logs.run_info import RunInfo
from spm_console.motion.logs.runlog import RunData, RunSummary, list_runs, load_run, logs_root
from spm_console.tui.messages import Outcome, RunOpened
from spm_console.tui.screens.base import StepScreen, describe_error
from spm_console.tui.screens.plan_words import KIND_WORDS
from spm_console.tui.widgets.plot import PlotView, Series

PLOTS = ("positions", "velocities", "tracking error")

FILTERS: tuple[str, ...] = ("all", "completed", "stopped", "refused", "killed", "error")
"""The outcome filter's values, in the order ``f`` steps through them."""

#: The reason last: the only long column (at 80 columns it is the one cut; the line above
#: the table names the highlighted run's whole reason).
RUN_COLUMNS = ("run", "kind", "outcome", "exit", "loop", "plan", "reason")
"""``loop``: how long the servo loop ran (the time Execute reports when a run ends), s."""


def _secs(x: float | None) -> str:
    return "–" if x is None else f"{x:.2f} s"


def plan_text(info: RunInfo) -> str:
    """'MVN [..]° → [..]°, 1.00 s (after an approach move)', or what the log lacks."""
    p = info.plan
    if p is None:
        return "plan: not recorded"
    ends = ("" if p.first_reference_deg is None or p.last_reference_deg is None
            else f" {fmt_deg(p.first_reference_deg)} → {fmt_deg(p.last_reference_deg)}")
    length = "" if p.duration_s is None else f", {p.duration_s:.2f} s"
    return (f"plan: {KIND_WORDS.get(p.kind, p.kind)}{ends}{length}"
            + (" (after an approach move)" if p.after_approach else ""))


#: Characters of a run's reason in the table (the whole reason: Enter opens the run).
REASON_CHARS = 40


def short_reason(reason: str, width: int = REASON_CHARS) -> str:
    """``reason`` on one line, cut at a word to ``width`` characters with '…' if longer."""
    text = " ".join(reason.split())
    if len(text) <= width:
        return text
    cut = text[:width - 1]
    if " " in cut:
        cut = cut[:cut.rindex(" ")]
    return cut.rstrip(" ,;:") + "…"


def run_row(info: RunInfo) -> tuple[str, ...]:
    """The runs table's cells of one run (RUN_COLUMNS)."""
    return (info.name, f"{info.kind} (preview)" if info.preview else info.kind, info.outcome,
            "" if info.exit_code is None else str(info.exit_code), _secs(info.loop_s),
            "" if info.plan is None else info.plan.kind, short_reason(info.reason))


def run_line(info: RunInfo) -> str:
    """The highlighted run under the log root, for a table too narrow for its columns (80
    columns show only the first three): outcome, exit code, the whole stop reason (the line
    wraps), the servo loop's time and the plan kind."""
    parts = [info.outcome, "exit –" if info.exit_code is None else f"exit {info.exit_code}",
             " ".join(info.reason.split()),
             "" if info.loop_s is None else f"servo loop {_secs(info.loop_s)}",
             "no plan recorded" if info.plan is None else f"plan {info.plan.kind}"]
    return "▸ " + " · ".join(p for p in parts if p)


def run_text(run: RunData) -> str:
    info = run.info
    code = "none" if info.exit_code is None else str(info.exit_code)
    started = ("start not recorded" if info.started is None
               else f"started {info.started.astimezone():%Y-%m-%d %H:%M:%S}")
    loop = ("servo loop not recorded" if info.loop_s is None
            else f"servo loop {info.loop_s:.2f} s ({info.samples or 0} cycles)")
    lines = [
        f"{info.name}: {info.kind} on {info.bus or '?'}"
        + (" — a PREVIEW on the wrist's twin (nothing moved)" if info.preview else ""),
        f"outcome {info.outcome} (exit code {code}): {info.message}",
    ]
    if info.stop_kind is not None:
        lines.append(f"stop reason: {info.stop_label}")
    lines += [
        f"{loop}; {started}, wall time {_secs(info.duration_s)} (set-up included)",
        plan_text(info),
        f"{run.rows} samples, {len(run.events)} events"
        + ("  (last line truncated)" if run.truncated else ""),
        f"folder {run.path}",
    ]
    faults = [e for e in run.events if e.get("event") in ("fault", "stop")]
    for e in faults[:3]:
        t = e.get("t", 0)
        when = f"t = {t:.2f} s" if isinstance(t, int | float) else "t = ?"
        lines.append(f"  {when} {e.get('event')}: {e.get('message', e.get('kind', ''))}")
    return "\n".join(lines)


class LogsScreen(StepScreen):
    MODE = "logs"
    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("r", "reload", "Refresh"),
        Binding("enter", "open", "Open run", show=True),
        Binding("f", "next_filter", "Filter"),
        Binding("p", "next_plot", "Plot"),
        Binding("j", "next_joint", "Joint"),
    ]

    DEFAULT_CSS = """
    LogsScreen #logs-head { height: auto; padding: 0 1; }
    LogsScreen #run-line { height: auto; padding: 0 1; text-style: bold; }
    LogsScreen #logs-main { height: 1fr; }
    """

    def __init__(self) -> None:
        super().__init__()
        self.plot_kind = 0
        self.joint = 0
        self.run: RunData | None = None
        self._listed: dict[str, RunInfo] = {}
        """The listed runs by row key (their folder)."""
        self.outcome_filter = "all"
        """One of FILTERS: which runs the table lists."""

    @property
    def root(self) -> Path:
        """The log root this session writes to and reads from (``--logs``,
        ``$SPM_CONSOLE_LOGS`` or ``logs/``), absolute."""

        return logs_root(self.session.logs_root).absolute()

    def compose_body(self) -> ComposeResult:
        with Vertical(classes="body"):
            yield Static(id="logs-head", markup=False)
            yield Static(id="run-line", markup=False)
            with Horizontal(id="logs-main"):
                yield DataTable(id="runs", cursor_type="row", zebra_stripes=True)
                # focusable (tab): ↑/↓, PgUp/PgDn, Home/End scroll an opened run's text and plot
                with VerticalScroll(id="run-detail"):
                    yield Static(id="run-text", markup=False, classes="result")
                    yield PlotView(id="run-plot")

    def on_mount(self) -> None:
        table = self.query_one("#runs", DataTable)
        table.add_columns(*RUN_COLUMNS)
        self.query_one("#run-text", Static).update(Content(
            "Pick a run with ↑/↓ and press Enter to plot it; tab moves to its details (they "
            "scroll), tab again back to the runs."))

    def on_screen_resume(self) -> None:
        super().on_screen_resume()
        self.action_reload()

    def action_reload(self) -> None:
        table = self.query_one("#runs", DataTable)
        table.clear()
        self._listed.clear()
        self.query_one("#run-line", Static).update("")
        root = self.root
        try:
            runs = list_runs(root)
        except (OSError, BadInputError) as exc:
            self.show_head(root, 0, 0)
            self.status.error(f"cannot list the logs in {root}: {describe_error(exc)}")
            return
        shown = self.fill(table, runs)
        self.show_head(root, shown, len(runs))
        if self.run is not None and str(self.run.path) not in self._listed:
            self._close_run(f"The run opened before ({self.run.path.name}) is not listed "
                            "now. Pick a run with ↑/↓ and press Enter to plot it.")
        table.focus()
        if not runs:
            self.status.ok(f"no runs logged yet in {root}: execute a plan first (step 5)")
        elif not shown:
            self.status.ok(f"no {self.outcome_filter} run among {len(runs)}: "
                           "f shows another outcome")
        else:
            self.status.ok(f"{shown} of {len(runs)} runs in {root}: Enter opens one, "
                           "f filters by outcome")

    def fill(self, table: DataTable[str], runs: list[RunSummary]) -> int:
        """List ``runs`` newest first, those of the filter's outcome; how many are listed."""
        shown = 0
        for r in reversed(runs):  # list_runs gives them oldest first
            info = r.info
            if self.outcome_filter != "all" and info.outcome != self.outcome_filter:
                continue
            table.add_row(*run_row(info), key=str(r.path))
            self._listed[str(r.path)] = info
            shown += 1
        return shown

    def show_head(self, root: Path, shown: int, total: int) -> None:
        which = ("all outcomes" if self.outcome_filter == "all"
                 else f"outcome {self.outcome_filter}")
        self.query_one("#logs-head", Static).update(Content(
            f"logs in {root} · {which}: {shown} of {total} runs · f: filter by outcome"))

    def action_next_filter(self) -> None:
        i = FILTERS.index(self.outcome_filter)
        self.outcome_filter = FILTERS[(i + 1) % len(FILTERS)]
        self.action_reload()

    def action_open(self) -> None:
        table = self.query_one("#runs", DataTable)
        if table.row_count == 0:
            self.status.error("no runs to open")
            return
        key = table.coordinate_to_cell_key(table.cursor_coordinate).row_key.value

        self.run_blocking("open", lambda: RunOpened(load_run(str(key))), "reading the run …")

    def _close_run(self, text: str) -> None:
        """Nothing on the detail side but ``text``: no run shown that the table hides."""
        self.run = None
        self.query_one("#run-text", Static).update(Content(text))
        self.query_one("#run-plot", PlotView).plot("no run opened", np.zeros(0), [])

    def on_data_table_row_highlighted(self, event: DataTable.RowHighlighted) -> None:
        info = self._listed.get(str(event.row_key.value))
        self.query_one("#run-line", Static).update(
            "" if info is None else Content(run_line(info)))

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
