"""The warm start is handed a real standard error, whatever the front end did to sys.stderr:
a console (Textual) replaces it by a capture whose fileno() is -1, and the fork request then
failed (EBADF), so every console connection started its motion process cold."""

from __future__ import annotations

import tempfile

from spm_console.services.warm_start import _has_fd


class _Captured:
    """What Textual puts in sys.stderr while an app runs."""

    def fileno(self) -> int:
        return -1


class _NoFd:
    def fileno(self) -> int:
        raise OSError("no fd")


def test_only_an_open_descriptor_counts() -> None:
    assert not _has_fd(_Captured()) and not _has_fd(_NoFd()) and not _has_fd(object())
    with tempfile.TemporaryFile() as f:
        assert _has_fd(f)

    class _Unopened:
        def fileno(self) -> int:
            return 1 << 20  # above any descriptor this process opened

    assert not _has_fd(_Unopened())
