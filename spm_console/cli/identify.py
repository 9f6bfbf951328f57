"""``identify``: fit the servo model to a logged response (``--run``, ``--csv``), or run the
identification experiment on the wrist and write a profile with the model it found
(``--experiment``: beside the profile, as :mod:`spm_console.store.identified_profiles` lays
it out; ``--out NEW.toml`` elsewhere; ``--apply`` into the profile itself, kept as it was in a
backup).

``--run`` and ``--csv`` fit the paper's p (and with ``--delay`` a pure delay); ``--damping``
adds the damping ratio ζ; ``--load`` fits the experiment's structure (ωn, ζ, delay and the
servo's load). The experiment homes the wrist,
runs an excitation the runtime verifies like any plan (:mod:`spm_console.services.identify.experiment`),
fits ωn, ζ and a delay on its first part and measures the model's error on the second,
held out. Exit codes: 0 done; a stop of the experiment ends with its own code (20–25);
3 a model no profile can hold; 4 bad input; 8 a fit that does not determine the model.
"""

from __future__ import annotations

import argparse
import csv
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from spm_console.cli.common import PLOT_SUFFIXES, add_force, emit, info, output_file, profile_of
from spm_console.cli.run import _bus_opts, _report, _request, with_progress
from spm_console.config.checks import PTS_MAX, PTS_MIN
from spm_console.config.models import servo_limits_deg
from spm_console.config.schema import Profile, Servo
from spm_console.core.servo.identify import ANGLE_MAX_DEG, CLOCK_MAX_S, identify
from spm_console.core.servo.load_fit import fit_load
from spm_console.description.weight import holding_torque_nm
from spm_console.errors import BadInputError, ExitCode, OptionConflictError, SolverError, SpmError
from spm_console.formatting import fmt_deg
from spm_console.motion.logs.profile_record import other_wrist, same_profile
from spm_console.motion.logs.runlog import RunData, load_run
from spm_console.numbers import NotANumberError, parse_number
from spm_console.report.plot_identify import plot_experiment
from spm_console.safe_io import MB, read_text, write_text_atomic
from spm_console.services.identify.experiment import (
    experiment_once,
    fit_experiment,
    identified_servo,
)
from spm_console.services.identify.report import fit_data, fit_lines, identified_text
from spm_console.store.identified_profiles import apply_in_place, identified_path, write_beside

#: Largest CSV file ``identify --csv`` reads, and most samples identified (33 min at 20 ms).
MAX_CSV_BYTES = 20 * MB
MAX_IDENTIFY_SAMPLES = 100_000
#: ``--load``: largest move between two samples (the servo's rated 270 °/s for 37 ms), and
#: how far past the servo limits a measured pose may lie (a tick's round-off and then some), deg.
MAX_POSE_JUMP_DEG = 10.0
LIMIT_SLACK_DEG = 1.0


def register(sub: Any) -> None:
    i = sub.add_parser("identify", help="fit the servo model to a logged response, or run the "
                       "identification experiment and write a profile with the model found")
    _bus_opts(i)
    src = i.add_mutually_exclusive_group(required=True)
    src.add_argument("--run", metavar="RUN", help="an executed run (folder or name under the logs)")
    src.add_argument("--csv", type=Path, metavar="FILE",
                     help="CSV with a header: t, ref1[, ref2, ref3], meas1[, meas2, meas3]")
    src.add_argument("--experiment", action="store_true",
                     help="home the wrist, run the identification experiment (about 20 s of "
                          "motion about home) and fit ωn, ζ and a delay to it")
    i.add_argument("--delay", action="store_true", help="--run/--csv: also fit a pure delay")
    i.add_argument("--damping", action="store_true",
                   help="--run/--csv: also fit a damping ratio ζ (p is then ωn)")
    i.add_argument("--load", action="store_true",
                   help="--run/--csv: fit ωn, ζ, a delay and the servo's load (deg per N·m of "
                        "the weight's holding torque from the profile's masses, and Coulomb "
                        "friction), the experiment's structure; needs the three joints")
    i.add_argument("--out", type=Path, metavar="NEW.toml",
                   help="--experiment: write the profile with the identified [servo] here "
                        "(default: beside the profile, as PROFILE.identified-TIME.toml)")
    i.add_argument("--apply", action="store_true",
                   help="--experiment: write the identified [servo] into the profile itself, "
                        "keeping it as it was in PROFILE.toml.bak-TIME")
    add_force(i)
    i.add_argument("--plot", type=Path, metavar="FILE.png",
                   help="--experiment: save measured against fitted responses")
    i.set_defaults(func=cmd_identify)
Samples = tuple[np.ndarray, np.ndarray, np.ndarray, Callable[[int], str]]
"""t, reference and measured of identify, and the name of sample k in messages."""


def _cell(text: str) -> float:
    """A CSV cell: a plain decimal number (:func:`~spm_console.numbers.parse_number`), or a
    written NaN/inf, which the column checks refuse naming the column (a column not used may
    hold them)."""
    if text.strip().lower().lstrip("+-") in ("nan", "inf", "infinity"):
        return float(text)
    return parse_number(text)


def _read_csv(path: Path) -> Samples:
    """The samples of an identify CSV; a cell that is not a number, or a non-finite or
    out-of-range value in a column used, is refused naming its line."""
    text = read_text(path, "--csv", MAX_CSV_BYTES, BadInputError)
    numbered = [(n, line) for n, line in enumerate(text.splitlines(), start=1)
                if line.strip() and not line.startswith("#")]
    if len(numbered) < 2:
        raise BadInputError(f"{path}: expected a header line and data rows")
    head = [h.strip() for h in next(csv.reader([numbered[0][1]]))]
    lines = [n for n, _ in numbered[1:]]
    values: list[list[float]] = []
    for n, row in zip(lines, csv.reader(line for _, line in numbered[1:]), strict=True):
        if len(row) != len(head):
            raise BadInputError(f"{path}, line {n}: {len(row)} cells, the header has {len(head)}")
        try:
            values.append([_cell(c) for c in row])
        except NotANumberError as exc:
            raise BadInputError(f"{path}, line {n}: every data cell must be a number ({exc})") from None
    data = np.array(values, float).reshape(len(values), len(head))
    return _columns(dict(zip(head, data.T, strict=True)), str(path), lines)


def _columns(cols: dict[str, np.ndarray], src: str, lines: list[int] | None = None) -> Samples:
    """The samples (θ in deg) in named columns: t with ref1/meas1 (… ref3/meas3), or t, ref,
    meas. ``lines`` are a CSV's line numbers of the rows: every value used must
    be finite. Without them (a run log), a row whose measurement is missing (NaN: a lost
    reply) is skipped. A non-finite value otherwise, an angle beyond ±ANGLE_MAX_DEG or a time
    beyond ±CLOCK_MAX_S is refused naming the line (or the data row of a run log)."""
    if "t" not in cols:
        raise BadInputError(f"{src}: missing column 't'")
    if len(cols["t"]) > MAX_IDENTIFY_SAMPLES:
        raise BadInputError(f"{src}: {len(cols['t']):,} samples, more than the "
                            f"{MAX_IDENTIFY_SAMPLES:,} identify fits; cut the log")
    joints = [i for i in (1, 2, 3) if f"ref{i}" in cols and f"meas{i}" in cols]
    if not joints and "ref" in cols and "meas" in cols:
        rnames, mnames = ["ref"], ["meas"]
    elif joints:
        rnames, mnames = [f"ref{i}" for i in joints], [f"meas{i}" for i in joints]
    else:
        raise BadInputError(f"{src}: needs columns ref1/meas1 (… ref3/meas3) or ref/meas")
    t = cols["t"]
    ref = np.column_stack([cols[c] for c in rnames])
    meas = np.column_stack([cols[c] for c in mnames])
    keep = np.ones(t.size, bool) if lines is not None else ~np.isnan(meas).any(axis=1)

    def where(k: int) -> str:
        return f"line {lines[k]}" if lines is not None else f"data row {k + 1}"

    for name, col, bound, unit in [("t", t, CLOCK_MAX_S, " s")] + [
            (c, cols[c], ANGLE_MAX_DEG, "°") for c in rnames + mnames]:
        bad = np.flatnonzero(keep & ~(np.abs(col) <= bound))
        if bad.size:
            k = int(bad[0])
            why = "not finite" if not np.isfinite(col[k]) else f"outside ±{bound:g}{unit}"
            raise BadInputError(f"{src}, {where(k)}: {name} = {col[k]:g} is {why}")
    rows = np.flatnonzero(keep)  # sample k is row rows[k]
    return t[keep], ref[keep], meas[keep], lambda k: where(int(rows[k]))


def cmd_identify(args: argparse.Namespace) -> int:
    profile = profile_of(args)
    if args.experiment:
        return _experiment(args, profile)
    if args.load and (args.delay or args.damping):
        raise OptionConflictError("--load fits the delay and ζ too: leave out --delay and --damping")
    for flag in ("out", "apply", "plot", "port", "sim_start"):
        if getattr(args, flag) not in (None, False):
            raise BadInputError(f"--{flag.replace('_', '-')} goes with --experiment")
    if args.sim or args.fault or args.plant:
        raise BadInputError("--sim, --fault and --plant go with --experiment")
    if args.csv is not None:
        t, ref, meas, at = _read_csv(args.csv)
        src = named = str(args.csv)
    else:
        run = load_run(args.run, args.logs)
        _same_wrist(run, profile, args.profile)
        src, named = str(run.path), str(run.path / "samples.csv")
        t, ref, meas, at = _columns(dict(run.columns), named)
    hold = _holding(profile, ref, meas) if args.load else None  # checked before any fit
    try:
        res = identify(t, ref, meas, fit_delay=args.delay or args.load, at=at,
                       fit_damping=args.damping or args.load)
        load = (None if hold is None else
                fit_load(t, ref, meas, hold[:, :, None], np.zeros(len(t), bool), res))
    except SpmError as exc:  # the refusal names the file its sample numbers refer to
        raise type(exc)(f"{named}: {exc.message}") from None
    if load is not None:
        res = load.result
    ts = profile.servo.ts_s
    if not PTS_MIN <= res.p * ts <= PTS_MAX:
        raise SolverError(
            f"{src}: fitted p = {res.p:.4g} rad/s gives p·Ts = {res.p * ts:.4g} with the "
            f"profile's Ts = {ts:g} s, outside the [{PTS_MIN:g}, {PTS_MAX:g}] a profile accepts "
            "(servo.p), so this profile's model (28) cannot use it")
    rec = res.to_dict()
    rec.update({"source": src, "profile_p": profile.servo.p,
                "relative_to_profile": res.p / profile.servo.p - 1.0})
    human = (f"p = {res.p:.3f} ± {res.p_std:.3f} rad/s (profile {profile.servo.p:g}, "
             f"{100 * (res.p / profile.servo.p - 1):+.1f} %)"
             + (f", ζ = {res.zeta:.3f} ± {res.zeta_std:.3f}" if res.fit_damping else "")
             + (f", delay {1e3 * res.delay_s:.1f} ms" if res.fit_delay else "")
             + f"; RMS residual {res.rms_deg:.4f} deg over {res.samples} samples × {res.joints} joints")
    if load is not None:
        rec.update(load_deg_per_nm=float(load.load.moments_deg[0]),
                   coulomb_deg=load.load.coulomb_deg)
        human += (f"; load {load.load.moments_deg[0]:.3f} deg/(N·m) of holding torque, Coulomb "
                  f"{load.load.coulomb_deg:.3f}°")
    emit(args, rec, human)
    sys.stdout.flush()
    return int(ExitCode.OK)


def _same_wrist(run: RunData, profile: Profile, path: str) -> None:
    """``--run``: the run was logged on the wrist ``profile`` describes (its geometry, home and
    servo wiring: :mod:`spm_console.motion.logs.profile_record`), else exit 4 naming both. A
    run logged before runs recorded their wrist is checked by its profile's name (the same
    hash passes; another version of the same name is fitted with a note); a run that records
    no profile is fitted with a note."""
    logged = run.meta.get("profile")
    here = f"profile '{profile.name}' ({path})"
    if not isinstance(logged, dict):
        info(f"note: {run.path.name} records no profile: fitted as a record of the wrist of {here}")
        return
    theirs = f"profile '{logged.get('name')}'"
    differ = other_wrist(logged, profile)
    own = "give the run's own profile with --profile"
    if differ:
        raise BadInputError(f"{run.path}: logged on another wrist: its {theirs} differs from {here} "
                            f"in {', '.join(differ)}; a fit would be another wrist's servos: {own}")
    if differ is None and not same_profile(logged, profile):
        if logged.get("name") != profile.name:
            raise BadInputError(f"{run.path}: logged with {theirs}, not {here}: {own}")
        info(f"note: {run.path.name} was logged with another version of {here}, before runs "
             "recorded their wrist: fitted as a record of this wrist")


def _holding(profile: Profile, ref: np.ndarray, meas: np.ndarray) -> np.ndarray:
    """``--load``: the weight's holding torque (n, 3), N·m, at the poses read of a record of
    the three joints (a path from home through them, by continuation), from the profile."""
    if ref.ndim != 2 or ref.shape[1] != 3:
        raise BadInputError("--load needs the three joints (ref1..ref3, meas1..meas3): the "
                            "weight's load depends on the whole pose")
    # the poses' FK is followed row to row (about a millisecond a row): a record of this wrist
    # lies inside its servo limits and moves little between samples
    lo, hi = servo_limits_deg(profile)
    outside = np.flatnonzero(((meas < lo - LIMIT_SLACK_DEG) | (meas > hi + LIMIT_SLACK_DEG)).any(1))
    if outside.size:
        k = int(outside[0])
        raise BadInputError(f"--load: sample {k + 1} (θ = {fmt_deg(meas[k])}) lies outside the "
                            f"profile's servo limits: not a record of this wrist")
    jumps = np.flatnonzero(np.abs(np.diff(meas, axis=0)).max(axis=1) > MAX_POSE_JUMP_DEG)
    if jumps.size:
        k = int(jumps[0])
        raise BadInputError(f"--load: the wrist moves more than {MAX_POSE_JUMP_DEG:g}° between "
                            f"samples {k + 1} and {k + 2}: the weight's load is followed along "
                            "the poses, record faster or cut the log")
    try:
        return holding_torque_nm(profile, meas)
    except ValueError as exc:
        raise BadInputError(f"--load: the poses read have no FK from home in the profile's "
                            f"modes ({exc})") from None


def _experiment(args: argparse.Namespace, profile: Profile) -> int:
    profile_path = Path(args.profile)
    _where_to_write(args, profile_path)
    output_file(args.plot, "--plot", PLOT_SUFFIXES)
    if args.delay or args.damping or args.load:
        raise BadInputError("--delay, --damping and --load go with --run/--csv (the experiment "
                            "fits all three)")
    req = _request(args, profile)
    with with_progress(args, req):
        run = experiment_once(profile, req)
    extra: dict[str, Any] = {"experiment": {"motion_s": run.excitation.duration_s,
                                            "step_deg": run.excitation.step_deg,
                                            "speed_degps": run.excitation.speed_degps}}
    if run.t is None or run.reference_deg is None or run.measured_deg is None:
        extra["stopped_during"] = "homing" if run.execution is (
            run.homing.execution if run.homing else None) else "experiment"
        return _report(args, run.execution, extra)
    try:
        fit = fit_experiment(profile, run)
    except SpmError as exc:
        raise type(exc)(f"{run.execution.log_dir}: {exc.message}") from None
    servo = identified_servo(profile, fit, str(run.execution.log_dir))
    written, line = _write(args, profile_path, servo)
    if args.plot is not None:
        plot_experiment(run.excitation, run.t, run.measured_deg, fit, args.plot)
    data = {**fit_data(run, fit, servo), **written}
    emit(args, data, "\n".join([*fit_lines(run, fit, servo, profile.servo), line]))
    return int(ExitCode.OK)


def _where_to_write(args: argparse.Namespace, profile_path: Path) -> None:
    """Refuse, before anything moves, a place the identified profile cannot be written."""
    if args.out is not None and args.apply:
        raise BadInputError("--apply writes the identified [servo] into the profile itself, "
                            "--out into a new file: give one of them")
    if args.out is not None:
        if args.out.resolve() == profile_path.resolve():
            raise BadInputError("--out must name a new file: to change the profile the "
                                "experiment runs with, use --apply (it keeps a backup)")
        output_file(args.out, "--out", (".toml",), replace=args.force)
        return
    if not profile_path.is_file():
        raise BadInputError(f"--profile {profile_path}: not a file (the identified profile is "
                            "written beside it)")
    if not os.access(profile_path.parent, os.W_OK):
        raise BadInputError(f"the profile's folder {profile_path.parent} is not writable: give "
                            "--out NEW.toml")


def _write(args: argparse.Namespace, profile_path: Path, servo: Servo) -> tuple[dict[str, str], str]:
    """The identified profile written where the options say (never over a file, but --out's):
    what the JSON and the text say of it."""
    assert servo.identified is not None
    date = servo.identified.date
    if args.out is not None:
        text, _ = identified_text(profile_path, servo, str(args.out))
        write_text_atomic(args.out, text, BadInputError)
        return {"profile_written": str(args.out)}, f"profile written: {args.out}"
    if args.apply:
        text, _ = identified_text(profile_path, servo, str(profile_path))
        backup = apply_in_place(profile_path, text, date)
        return ({"profile_written": str(profile_path), "backup": str(backup)},
                f"profile updated: {profile_path} (its [servo] only; as it was: {backup})")
    text, _ = identified_text(profile_path, servo, str(identified_path(profile_path, date)))
    out = write_beside(profile_path, text, date)
    return {"profile_written": str(out)}, f"profile written: {out}"
