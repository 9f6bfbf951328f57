"""Messages that workers post to screens (the only way blocking work reports back)."""

from __future__ import annotations

from typing import Any

from textual.message import Message


class Done(Message):
    """A blocking operation finished; ``result`` is what it returned."""

    def __init__(self, op: str, result: Any = None) -> None:
        super().__init__()
        self.op = op
        self.result = result


class Failed(Message):
    """A blocking operation failed with a message for the operator (no traceback)."""

    def __init__(self, op: str, message: str) -> None:
        super().__init__()
        self.op = op
        self.message = message


class Telemetry(Message):
    """The latest executor sample. Bursts coalesce: only the newest is handled."""

    def __init__(self, sample: Any) -> None:
        super().__init__()
        self.sample = sample

    def can_replace(self, message: Message) -> bool:
        return isinstance(message, Telemetry)


class Progress(Message):
    """Progress of a long build: stage name and fraction in [0, 1]. Bursts coalesce."""

    def __init__(self, stage: str, fraction: float) -> None:
        super().__init__()
        self.stage = stage
        self.fraction = fraction

    def can_replace(self, message: Message) -> bool:
        return isinstance(message, Progress)
