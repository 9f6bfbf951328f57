"""Which local addresses listen on a TCP port (for the viewer's loopback-only checks)."""

from __future__ import annotations

from pathlib import Path


def listening(port: int) -> list[str]:
    """Hex local addresses (as in /proc/net/tcp, tcp6) listening on ``port``."""
    out = []
    for name in ("/proc/net/tcp", "/proc/net/tcp6"):
        try:
            lines = Path(name).read_text().splitlines()[1:]
        except OSError:
            continue
        for ln in lines:
            f = ln.split()
            addr, p = f[1].rsplit(":", 1)
            if int(p, 16) == port and f[3] == "0A":  # LISTEN
                out.append(addr)
    return out
