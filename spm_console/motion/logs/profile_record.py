"""The profile a run was logged with, as its ``meta.json`` records it (``profile``: name, hash,
and the digests of the sections that make the wrist that wrist), and whether a logged run
was measured on the wrist a profile describes.

The wrist's sections are what a record of it means: ``geometry`` and ``home`` (its kinematics,
the poses it was read at, the weight's load along them) and ``bus`` without how it is reached
(servo ids, offsets, directions, limits, encoder, model and protocol; not the port, the baud
rate or the reply timeout). The servo model, limits, safety thresholds and the emulated plant
are what a profile says about the wrist, and change when it is identified again: a run logged
before is still a record of the same wrist.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping

from spm_console.config.plant import PLANT_MODELS
from spm_console.config.schema import Profile

#: The sections whose digests a run log records as its wrist.
WRIST_SECTIONS = ("geometry", "home", "bus")
#: Keys of those sections that say how the wrist is reached, not which wrist it is.
_REACHED_BY: dict[str, set[str]] = {"bus": {"port", "baud", "timeout_s"}}


def wrist_digests(profile: Profile) -> dict[str, str]:
    """SHA-256 of each of the wrist's sections of ``profile`` (:data:`WRIST_SECTIONS`)."""
    out = {}
    for name in WRIST_SECTIONS:
        data = getattr(profile, name).model_dump(mode="json", exclude=_REACHED_BY.get(name))
        for joint in data.get("joints", []) if name == "bus" else []:
            if joint.get("tick_trim") == 0.0:  # a key added later: digested once it is used
                del joint["tick_trim"]
        blob = json.dumps(data, sort_keys=True, separators=(",", ":"))
        out[name] = hashlib.sha256(blob.encode()).hexdigest()
    return out


def other_wrist(logged: Mapping[str, object], profile: Profile) -> list[str] | None:
    """The wrist's sections in which a run's ``profile`` record differs from ``profile`` ([]:
    none, the same wrist); None when the record has no wrist digests (a run logged before
    they were recorded)."""
    wrist = logged.get("wrist")
    if not isinstance(wrist, dict):
        return None
    now = wrist_digests(profile)
    return [name for name in WRIST_SECTIONS if wrist.get(name) != now[name]]


def same_profile(logged: Mapping[str, object], profile: Profile) -> bool:
    """Whether a run's ``profile`` record has ``profile``'s hash, with the emulated plant the
    run chose (``[plant] model``, set per run by ``--plant`` or the console): a choice of
    emulator, not an edit of the profile."""
    digest = logged.get("hash")
    return any(digest == profile.with_plant_model(model).digest()
               for model in (profile.plant.model, *PLANT_MODELS))
