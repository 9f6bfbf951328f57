"""Write an identified ``[servo]`` section into a profile's TOML text, everything else kept.

The profile's other sections, their comments and their order stay as written; the ``[servo]``
table (with any ``[servo.identified]`` below it) is replaced by the identified model, each
value with a comment naming where it came from. The result is parsed and validated as a
profile before anyone writes it.
"""

from __future__ import annotations

import re

from spm_console.config.edit import HEADER, key_line, toml_value
from spm_console.config.load import parse_profile_text
from spm_console.config.schema import Profile, Servo


def servo_lines(servo: Servo) -> list[str]:
    """The ``[servo]`` and ``[servo.identified]`` tables of ``servo`` as TOML lines."""
    why = "[identified]" if servo.identified is not None else "[typed in]"
    notes = {
        "p": f"{why} natural frequency ωn, rad/s (the double pole of eq. 27 when zeta = 1)",
        "zeta": f"{why} damping ratio",
        "delay_s": f"{why} transport delay, s",
        "ts_s": "sampling interval Ts, s (kept)",
        "discretization": "exact sampling of the model (kept)",
        "linear_range_deg": f"{why} largest |θ* − θ| the servo followed the model at, deg",
        "residual_bound_deg": f"{why} largest |model − θ| on held-out data, deg",
        "load_deg_per_nm": f"{why} offset per N·m of the weight's holding torque, deg/(N·m)",
        "coulomb_deg": f"{why} offset against the motion (Coulomb friction), deg",
    }
    out = ["[servo]"]
    for key, note in notes.items():
        v = getattr(servo, key)
        if v is None:
            continue
        out.append(key_line(key, v, note))
    if servo.identified is not None:
        out += ["", "[servo.identified]"]
        for key, v in servo.identified.model_dump().items():
            if v is not None:
                out.append(f"{key} = {toml_value(v)}")
    return out


def with_servo(text: str, servo: Servo, source: str) -> tuple[str, Profile]:
    """``text`` (a profile's TOML) with its ``[servo]`` tables replaced by ``servo``; the new
    text and the profile it parses to (ProfileError naming ``source`` when it does not)."""
    lines = text.splitlines()
    keep: list[str] = []
    inside = False
    placed = False
    for line in lines:
        m = HEADER.match(line)
        if m:
            name = re.sub(r"\s+", "", m.group(1))
            inside = name == "servo" or name.startswith("servo.")
            if inside and not placed:
                keep += [*servo_lines(servo), ""]
                placed = True
        if not inside:
            keep.append(line)
    if not placed:
        keep += ["", *servo_lines(servo)]
    new = "\n".join(keep).rstrip("\n") + "\n"
    return new, parse_profile_text(new, source)
