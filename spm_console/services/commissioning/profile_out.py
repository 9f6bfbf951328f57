"""The commissioned profile: the base profile's text with what commissioning found, each
changed key commented with its provenance (date, how it was found, the commissioning's run
folder), written beside the profile or where the operator asked; and the result in words."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

from spm_console.config.edit import Value, with_joints, with_values
from spm_console.config.plant import MAX_PAYLOAD_CENTRE_MM
from spm_console.config.schema import Profile
from spm_console.errors import BadInputError
from spm_console.safe_io import read_text, write_text_atomic
from spm_console.services.commissioning.payload_stage import (
    compliance_known,
    friction_seen,
    payload_seen,
)
from spm_console.services.commissioning.stages import Commissioned
from spm_console.store.identified_profiles import write_new


def commissioned_text(base_text: str, result: Commissioned, source: str,
                      when: dt.datetime | None = None, run: str = "",
                      port: str = "") -> tuple[str, Profile]:
    """The base profile's text with ``[[bus.joints]]`` as built (ids, directions and, from the
    jig, tick offsets), each changed key commented with its provenance (``run``: the
    commissioning's run folder; ``port``: the bus the wrist was commissioned on, written as
    ``[bus] port`` where the base has another, so that the profile's next commands drive that
    wrist and not the emulated bus an empty port means); parsed and read back."""
    stamp = (when or dt.datetime.now(dt.UTC)).strftime("%Y-%m-%dT%H:%M:%SZ")
    joints: list[dict[str, object]] = []
    for k, m in enumerate(result.legs):
        values: dict[str, object] = {"id": m.id, "direction": m.direction}
        if result.tick_offsets is not None:
            values["tick_offset"] = result.tick_offsets[k]
            if result.tick_trims[k] != 0.0 or "tick_trim" in base_text:  # none left stale
                values["tick_trim"] = result.tick_trims[k]
        joints.append(values)
    mapped = "IMU" if result.legs[0].source == "imu" else "operator"
    zero = ("" if result.tick_offsets is None else ", zero: IMU at rest"
            if result.rest_zero is not None else ", zero: jig")
    how = f"map: {mapped}{zero}" + (" and IMU" if result.refinement is not None else "")
    where = f", run {run}" if run else ""
    note = f"commissioned {stamp} ({how}{where})"
    text, prof = with_joints(base_text, joints, note, source)  # type: ignore[arg-type]
    if kept_port(port) and port != prof.bus.port:
        text, prof = with_values(text, {("bus", "port"): port}, note, source)
    fitted: dict[tuple[str, str], Value] = {}
    if result.refinement is not None and result.refinement.arcs_deg is not None:
        g = result.profile.geometry
        fitted.update({
            ("geometry", "alpha1_leg_offset_deg"): list(g.alpha1_leg_offset_deg),
            ("geometry", "alpha2_leg_offset_deg"): list(g.alpha2_leg_offset_deg)})
        if tuple(result.profile.home.sign_seed) != tuple(prof.home.sign_seed):
            fitted[("home", "sign_seed")] = list(result.profile.home.sign_seed)
    if result.refinement is not None and result.refinement.tilt_deg is not None:
        fitted[("plant", "base_tilt_deg")] = list(result.profile.plant.base_tilt_deg)
    if fitted:
        text, prof = with_values(text, fitted, f"commissioned {stamp} (IMU fit{where})", source)
    load = _load_values(result, prof)
    if load:
        text, prof = with_values(text, load, f"commissioned {stamp} (holding offsets{where})",
                                 source)
    return text, prof


def kept_port(port: str) -> bool:
    """Whether the commissioned profile keeps ``port`` as its ``[bus] port``: not a
    pseudo-terminal's (``/dev/pts/N``: the name goes to the next terminal opened)."""
    return bool(port) and not port.startswith("/dev/pts/")


def _load_values(result: Commissioned, base: Profile) -> dict[tuple[str, str], Value | None]:
    """The load model's keys (the payload's first moment, the drive's compliance, settling)
    where the commissioned profile differs from ``base``: what the IMU stage determined
    (:func:`~spm_console.services.commissioning.payload_stage.with_load_model` decides)."""
    built = result.profile
    out: dict[tuple[str, str], Value | None] = {}
    moment = built.plant.payload_moment_kgmm
    if moment is not None and moment != base.plant.payload_moment_kgmm:
        out[("plant", "payload_moment_kgmm")] = list(moment)
    mass = built.plant.payload_kg
    if mass != base.plant.payload_kg:  # None: the base's mass no longer places the payload
        out[("plant", "payload_kg")] = mass
    load = built.servo.load_deg_per_nm
    if load is not None and load != base.servo.load_deg_per_nm:
        out[("servo", "load_deg_per_nm")] = load
    if built.settle.duration_s != base.settle.duration_s:
        out[("settle", "duration_s")] = built.settle.duration_s
    if built.settle.tolerance_deg != base.settle.tolerance_deg:
        out[("settle", "tolerance_deg")] = built.settle.tolerance_deg
    return out


#: Largest profile text read, bytes.
MAX_PROFILE_BYTES = 1 << 20


def commissioned_path(profile_path: Path, when: dt.datetime) -> Path:
    """Where the commissioning of ``profile_path`` at ``when`` goes by default (before a taken
    name's ``-2`` …): ``NAME.commissioned-YYYY-mm-ddTHHMMSSZ.toml`` beside it (the stamp of
    an identified profile's name)."""
    stamp = when.astimezone(dt.UTC).strftime("%Y-%m-%dT%H%M%SZ")
    return profile_path.with_name(f"{profile_path.stem}.commissioned-{stamp}.toml")


def write_commissioned(profile_path: Path, result: Commissioned, out: Path | None = None,
                       when: dt.datetime | None = None, run: str = "", port: str = "") -> Path:
    """Write the commissioned profile: ``profile_path``'s text with ``[[bus.joints]]`` as
    built, to ``out`` (replaced atomically: the caller decided it may be) or beside the
    profile (:func:`commissioned_path`, never over a file); the path written; ``port``: see
    :func:`commissioned_text`. The CLI and the console both write through here."""
    when = when or dt.datetime.now(dt.UTC)
    base = read_text(profile_path, "--profile", MAX_PROFILE_BYTES, BadInputError)
    target = out or commissioned_path(profile_path, when)
    text, _prof = commissioned_text(base, result, str(target), when, run, port)
    if out is not None:
        write_text_atomic(out, text, BadInputError)
        return Path(out)
    return write_new(target, text)


def commissioned_lines(result: Commissioned, port: str = "") -> list[str]:
    """The result in words, one line each: legs, ids and directions, the jig's tick offsets,
    the IMU stage's residuals and every fitted parameter with its status; with the ``port``
    commissioned on, why it was not written as ``[bus] port`` when it was not."""
    lines = [f"leg {m.leg}: servo id {m.id}, direction {m.direction:+d} "
             + (f"(platform turned {m.rotation_deg:.2f}°, |cos| {m.cos:.2f})"
                if m.source == "imu" else "(confirmed by the operator)") for m in result.legs]
    rest = result.rest_zero
    if rest is not None:
        lines.append("tick offsets from the IMU at rest (no jig): " + str(list(
            result.tick_offsets or ())) + ", joint angles at rest " + ", ".join(
            f"{t:.2f} ± {e:.2f}" for t, e in zip(rest.fit.theta_deg, rest.fit.theta_std_deg,
                                                 strict=True)) + "°")
    elif result.tick_offsets is not None:
        lines.append(f"tick offsets from the jig: {list(result.tick_offsets)}")
        if result.held_at_jig:
            lines.append(
                f"warning: servo ids {list(result.held_at_jig)} held the wrist (torque on) when "
                "the jig stage began; a wrist on its jig is powered with torque off. If it was "
                "not on its jig, the zero is where it stood: "
                + ("the IMU stage's held-out poses checked it" if result.refinement is not None
                   else "commission again on the jig, or with the IMU stage to check it"))
    else:
        lines.append("not zeroed: give --jig (the wrist on its home jig, torque off), or "
                     "--imu-port (the IMU zeroes it where it rests)")
    r = result.refinement
    if r is not None:
        beyond = "the jig" if rest is None else "the zero at rest"
        lines.append(f"IMU stage: horn offsets beyond {beyond} {[round(h, 3) for h in r.horn_deg]}°"
                     f" (tick trims {list(result.tick_trims)}), "
                     f"held-out gravity residual {r.verification.gravity_max_deg:.3f}° at most, "
                     f"{r.motion_s:.1f} s of motion")
        lines += [f"  {p.name}: {p.value_deg:+.3f}°"
                  + ("" if p.std_expected_deg is None else f" ± {p.std_expected_deg:.3f}°")
                  + f" ({p.status})" for p in r.fit.parameters]
        undetermined = list(r.fit.undetermined_named)
        if undetermined:
            lines.append("  undetermined by the data: " + ", ".join(map(str, undetermined)))
        if r.arcs_deg is not None:
            lines.append("link arcs as fitted written to [geometry]: the workspace is rebuilt "
                         "for them on its first use")
        if r.tilt_deg is not None:
            lines.append(f"base tilt as fitted written to [plant] base_tilt_deg "
                         f"{list(result.profile.plant.base_tilt_deg)}°: the load model's gravity")
        if r.payload is not None:
            f = r.payload.fit
            lines.append("payload first moment m·c [" + ", ".join(
                f"{x * 1e3:.1f} ± {d * 1e3:.1f}" for x, d in
                zip(f.first_moment_kgm, f.first_moment_std_kgm, strict=True))
                + f"] kg·mm in the platform's frame, drive compliance "
                f"{f.compliance_deg_per_nm:.3f} ± {f.compliance_std:.3f} deg/(N·m); held-out "
                f"offsets {r.payload.held_out_rms_deg:.3f}° RMS")
            if f.friction_deg is not None:
                lines.append(f"  at rest the drives stop {abs(f.friction_deg):.3f}° "
                             + ("short of" if f.friction_deg >= 0 else "past")
                             + " their goals in the direction they came from (friction, play)")
            written = [w for w, ok in (("[plant] payload_moment_kgmm", payload_seen(r.payload)),
                                       ("[servo] load_deg_per_nm", compliance_known(r.payload)),
                                       ("[settle] duration_s, tolerance_deg",
                                        friction_seen(r.payload)))
                       if ok]
            lines.append("  load model written: " + ", ".join(written) if written else
                         "  load model not written: the offsets do not determine it (the "
                         "profile's own kept)")
            mass = result.profile.plant.payload_kg
            centre = result.profile.plant.payload_centre_mm
            if mass is not None and centre is not None:
                sd = f.first_moment_std_kgm * 1e3 / mass
                lines.append(f"  payload {mass:g} kg (weighed) centred at [" + ", ".join(
                    f"{c:.1f} ± {e:.1f}" for c, e in zip(centre, sd, strict=True))
                    + "] mm (m·c / m): the twin and the exports carry it")
            elif result.payload_kg_weighed is not None:
                given = result.payload_kg_weighed
                lines.append(f"  payload mass {given:g} kg (weighed) not written: " + (
                    "the offsets do not determine the first moment that places it"
                    if not payload_seen(r.payload) else
                    f"with the first moment fitted it puts the payload's centre beyond "
                    f"±{MAX_PAYLOAD_CENTRE_MM:g} mm of the wrist's centre (check the weighing)"))
            else:
                lines.append("  the payload's mass alone is not seen by a wrist turning about a "
                             "point (give --payload-kg, weighed): the emulated wrist carries no "
                             "payload")
    if port and not kept_port(port):
        kept = result.profile.bus.port
        lines.append(f"[bus] port not written: {port} is a pseudo-terminal, whose name the next "
                     "terminal opened takes; give --port to the commands that use this profile "
                     + (f"(without it they open {kept}, the port it keeps)" if kept else
                        "(without it they drive the emulated bus)")
                     + ", or write a stable name there")
    return lines
