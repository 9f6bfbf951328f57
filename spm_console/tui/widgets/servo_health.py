"""The connect screen's servo widgets: the live health table (one row per joint; its row
cursor chooses the joint the tools act on) and the jog step field (what was typed stays as
typed; an invalid step is marked, with the reason beside it). Degrees."""

from __future__ import annotations

from typing import TYPE_CHECKING

from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Horizontal
from textual.content import Content
from textual.widgets import DataTable, Input, Static
from textual.widgets.data_table import ColumnKey

from spm_console.motion.servo_tools import JOG_MAX_STEP_DEG, JointHealth, ServoHealth
from spm_console.tui.widgets.field import TextField
from spm_console.tui.widgets.number import NumberRule

if TYPE_CHECKING:
    from spm_console.services.session import BusState

#: Table columns: key, label ("load" is "current" on Protocol 2.0).
COLUMNS = (("joint", "joint"), ("id", "id"), ("model", "model"), ("torque", "torque"),
           ("position", "position"), ("load", "load"), ("temperature", "temp"),
           ("voltage", "voltage"), ("hardware", "hardware error"))
_LIVE = COLUMNS[3:]
NO_REPLY = "no reply"


def _live_cells(h: JointHealth) -> tuple[str, ...]:
    return ("-" if h.torque_on is None else ("on" if h.torque_on else "off"),
            NO_REPLY if h.position_deg is None else f"{h.position_deg:.2f}°",
            h.load_text,
            NO_REPLY if h.temperature_c is None else f"{h.temperature_c:.0f} °C",
            NO_REPLY if h.voltage_v is None else f"{h.voltage_v:.1f} V",
            h.hardware_text)


class ServoTable(DataTable[str | Text]):
    """One row per joint: torque, position, current/load, temperature, voltage and the
    hardware error of its servo. Updated in place (the cursor stays on its joint)."""

    def __init__(self, protocol: str, id: str | None = None) -> None:
        super().__init__(id=id, cursor_type="row", zebra_stripes=True)
        self._protocol = protocol

    def on_mount(self) -> None:
        for key, label in COLUMNS:
            if key == "load" and self._protocol == "2.0":
                label = "current"
            self.add_column(label, key=key)

    @property
    def joint(self) -> int:
        """The joint (1-based) under the cursor."""
        return min(max(self.cursor_row, 0), 2) + 1

    def show(self, state: BusState | None, health: ServoHealth | None, silent: bool) -> None:
        """Rows of ``state``'s servos with ``health``'s values (the ping's before the first
        status read); ``silent``: the last status read failed, every live cell 'no reply'."""
        if state is None:
            self.clear()
            return
        statuses = state.statuses
        if self.row_count != len(statuses):
            self.clear()
            for j, st in enumerate(statuses, start=1):
                self.add_row(str(j), str(st.id), str(st.model_number), *("-",) * len(_LIVE),
                             key=str(j))
        rows: list[list[str | Text]] = []
        for j, st in enumerate(statuses, start=1):
            if silent:
                live: tuple[str, ...] = ("-", *(NO_REPLY,) * (len(_LIVE) - 1))
            elif health is not None and j <= len(health.joints):
                live = _live_cells(health.joints[j - 1])
            else:  # before the first status read: what the ping said
                live = ("-", "-", "-",
                        "-" if st.temperature_c is None else f"{st.temperature_c:.0f} °C",
                        "-" if st.voltage_v is None else f"{st.voltage_v:.1f} V",
                        "none" if st.hardware_error == 0 else f"0x{st.hardware_error:02x}")
            rows.append([Text(value, style="bold red")
                         if value == NO_REPLY or (key == "hardware" and value not in ("none", "-"))
                         else value for (key, _), value in zip(_LIVE, live, strict=True)])
        # Each column fits its label and the values it is about to show, set before the cells
        # change: every cell update then renders header and rows anew at these widths. (Left
        # to the table, widths were measured on its next idle moment, after a render had
        # cached the header at the old width: the header and the rows could disagree.)
        for i, (key, _) in enumerate(_LIVE):
            column = self.columns[ColumnKey(key)]
            column.content_width = max([column.label.cell_len,
                                        *(Text(v).cell_len if isinstance(v, str) else v.cell_len
                                          for v in (r[i] for r in rows))])
        for j, cells in enumerate(rows, start=1):
            for (key, _), cell in zip(_LIVE, cells, strict=True):
                self.update_cell(str(j), key, cell)
        self.refresh(layout=True)

#: The jog step: more than 0°, at most the runtime's own bound; a longer text than fits the
#: field is refused with the reason (never cut).
JOG_STEP_RULE = NumberRule("jog step", "a number of degrees", "°", lo=0.0, lo_open=True,
                           hi=JOG_MAX_STEP_DEG, max_chars=10)


class JogStepField(Horizontal):
    """'Jog step (°): [1    ] - / + move the chosen joint by 1°' — or the reason it is
    invalid (a step must be > 0 and ≤ JOG_MAX_STEP_DEG)."""

    DEFAULT_CSS = """
    JogStepField { height: 1; margin: 1 0 0 0; }
    JogStepField > Static { width: auto; }
    JogStepField > Input { width: 12; height: 1; padding: 0 1; }
    JogStepField > Input.-invalid { background: $error 30%; }
    JogStepField > #jog-note { padding: 0 1; }
    JogStepField > #jog-note.-invalid { color: $error; }
    """

    def compose(self) -> ComposeResult:
        yield Static("Jog step (°):", markup=False)
        yield TextField(value="1", id="jog-step", compact=True)  # no border, focused too
        yield Static(id="jog-note", markup=False)

    def on_mount(self) -> None:
        self.check()

    def on_input_changed(self, event: Input.Changed) -> None:
        event.stop()
        self.check()

    def check(self) -> float | None:
        """The step typed (deg, > 0), or None with the field marked and the reason shown."""
        field = self.query_one(Input)
        reason = JOG_STEP_RULE.reason(field.value)
        field.set_class(bool(reason), "-invalid")
        note = self.query_one("#jog-note", Static)
        note.set_class(bool(reason), "-invalid")
        if reason:
            note.update(Content(f"invalid: {reason}"))
            return None
        step = JOG_STEP_RULE.parse(field.value)
        note.update(Content(f"- / + move the chosen joint by {step:g}°"))
        return step
