"""What the console exits with to start again on another profile: the settings (ctrl+o) or
the servo model the identification found (step 1, key i).

The app closes its session (E-stop, motion process, viewer) and exits with a
:class:`SwitchRequest`; ``spm-console tui`` starts the next console for it in the same
terminal. A request may carry the workspace loaded in the console it leaves
(:class:`KeptWorkspace`): the next console uses it when its profile's workspace is the same
one (the cache key: geometry, home, links, workspace grid; not the servo), so a servo-only
change never loads or builds it again.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from spm_console.config.schema import Profile
from spm_console.core.workspace.data import Workspace
from spm_console.store.workspace_cache import CacheInfo, cache_key


@dataclass(frozen=True)
class KeptWorkspace:
    """A loaded workspace and how it was obtained (its cache key)."""

    workspace: Workspace
    info: CacheInfo

    def fits(self, profile: Profile) -> bool:
        """True when ``profile``'s workspace is this one (same cache key)."""
        return self.info.key == cache_key(profile, profile.workspace.refined_cover)


@dataclass(frozen=True)
class SwitchRequest:
    """Restart the console with this profile file and workspace grid step (deg)."""

    profile_path: Path
    grid_step_deg: float
    why: str = ""
    """The note the next console shows ("": the settings' own)."""
    kept: KeptWorkspace | None = field(default=None, compare=False, repr=False)
    """The workspace the next console starts with when it fits its profile."""

    @classmethod
    def keeping(cls, profile_path: Path, profile: Profile, workspace: Workspace | None,
                info: CacheInfo | None, why: str) -> SwitchRequest:
        """Restart on ``profile_path`` with the grid step of ``profile`` (the one in use) and
        its loaded workspace kept, if any (a new servo model or wiring: the workspace's
        sections are unchanged, so the next console takes it when it fits)."""
        kept = None if workspace is None or info is None else KeptWorkspace(workspace, info)
        return cls(profile_path, float(profile.workspace.step_deg), why, kept)

    def describe(self) -> str:
        return f"profile {self.profile_path}, grid step {self.grid_step_deg:g}°"

    def note(self) -> str:
        """What the next console says once it is up."""
        return self.why or f"Settings applied: {self.describe()} (the console restarted for them)."
