"""The payload commissioning finds, in the load model: the platform's weight with the
payload's first moment (``[plant] payload_moment_kgmm``), the fit of a profile that already
has one giving the whole payload again, and the commissioned profile's text holding it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from spm_console.config.edit import with_values
from spm_console.config.models import model_of
from spm_console.config.schema import Profile
from spm_console.core.commissioning.payload import HoldingFit
from spm_console.core.kinematics.loads import GRAVITY_MPS2, gravity_regressor
from spm_console.description.weight import PLATFORM, UP, Weight
from spm_console.services.commissioning.payload_stage import (
    PayloadReport,
    approach_signs,
    payload_from_holding,
    payload_seen,
    sent_at_rest,
    with_load_model,
)

AGILE = Path(__file__).resolve().parents[3] / "profiles" / "agile_wrist.toml"
S_KGMM = (3.0, -1.5, 36.0)  # 0.3 kg at (10, −5, 120) mm
K_TRUE = 1.4  # deg/(N·m)


def _with(agile: Profile, moment: tuple[float, float, float] | None,
          load: float | None = None) -> Profile:
    plant = agile.plant.model_copy(update={"payload_moment_kgmm": moment})
    servo = agile.servo.model_copy(update={"load_deg_per_nm": load})
    return Profile.model_validate(agile.model_copy(update={"plant": plant, "servo": servo})
                                  .model_dump(mode="python"))


def _poses(agile: Profile, n: int) -> tuple[np.ndarray, np.ndarray]:
    """n poses within 20° of home (deg) and their platform rotations."""
    model = model_of(agile)
    rng = np.random.default_rng(7)
    th = np.asarray(agile.home.theta_deg) + rng.uniform(-20, 20, (n, 3))
    R = np.array([model.track(np.radians(t)).pose.R for t in th])  # type: ignore[union-attr]
    return th, R


def test_the_payload_adds_its_first_moment_to_the_platforms_weight(agile: Profile) -> None:
    loaded = _with(agile, S_KGMM)
    th, R = _poses(agile, 12)
    rad = np.radians(th)
    extra = Weight.of(loaded).torque_nm(rad, R) - Weight.of(agile).torque_nm(rad, R)
    yp = gravity_regressor(model_of(agile), rad, R, UP)[:, :, PLATFORM]
    np.testing.assert_allclose(extra, GRAVITY_MPS2 * yp @ (np.array(S_KGMM) * 1e-3), atol=1e-12)
    assert np.abs(extra).max() > 0.05  # N·m: a load the servos feel
    np.testing.assert_array_equal(Weight.of(loaded, payload=False).moments_kgm,
                                  Weight.of(agile).moments_kgm)


def test_a_profile_without_a_payload_keeps_its_hash(agile: Profile) -> None:
    assert _with(agile, None).digest() == agile.digest()
    assert _with(agile, S_KGMM).digest() != agile.digest()


@pytest.mark.parametrize("before", [None, (1.0, 2.0, 20.0)])
def test_the_fit_gives_the_whole_payload_whatever_the_profile_compensated(
        agile: Profile, before: tuple[float, float, float] | None) -> None:
    """The servos hold θ = θ* + k_c·τ_model(θ*) − k·τ_true(θ): the profile's load model
    (k_c, its payload s₀) sent at the pose commanded, the wrist's true one (k, the payload S)
    held at the pose reached."""
    k_c = None if before is None else 1.1
    profile = _with(agile, before, k_c)
    measured, R = _poses(agile, 24)
    rad = np.radians(measured)
    true_tau = Weight.of(_with(agile, S_KGMM)).torque_nm(rad, R)
    # θ* + d(θ*) − θ = k·τ: the runtime's offset d is its model's at the pose it commands
    commanded = measured + K_TRUE * true_tau
    for _ in range(30):
        commanded = measured - sent_at_rest(profile, commanded) + K_TRUE * true_tau
    held = np.zeros(len(measured), bool)
    held[-4:] = True
    report = payload_from_holding(profile, commanded, measured, held)
    np.testing.assert_allclose(report.fit.first_moment_kgm * 1e3, S_KGMM, atol=1e-6)
    assert report.fit.compliance_deg_per_nm == pytest.approx(K_TRUE, abs=1e-8)
    assert report.held_out_rms_deg < 1e-8
    built = with_load_model(profile, report)
    assert built.plant.payload_moment_kgmm == pytest.approx(S_KGMM, abs=0.05)
    assert built.servo.load_deg_per_nm == pytest.approx(K_TRUE, abs=1e-4)


def _report(s_kgm: tuple[float, float, float], std_kgm: float, k_std: float,
            friction_deg: float | None = None) -> PayloadReport:
    fit = HoldingFit(np.array(s_kgm), np.full(3, std_kgm), K_TRUE, k_std, 0.05,
                     np.ones(4), 24, friction_deg)
    return PayloadReport(fit, 0.05)


def test_what_the_fit_does_not_determine_is_not_written(agile: Profile) -> None:
    unclear = _report((0.001, 0.0, 0.002), 0.002, 0.5)
    assert not payload_seen(unclear)
    assert with_load_model(agile, unclear) == agile
    clear = _report((0.003, -0.0015, 0.036), 0.001, 0.05)
    built = with_load_model(agile, clear)
    assert built.plant.payload_moment_kgmm == (3.0, -1.5, 36.0)
    assert built.servo.load_deg_per_nm == K_TRUE
    assert built.settle.duration_s == 0.0  # friction not fitted: no settling asked for
    rough = with_load_model(agile, _report((0.003, -0.0015, 0.036), 0.001, 0.05, -0.06))
    assert rough.settle.duration_s > 0.0
    # on the goal's nearest tick: half a tick (0.044°) and a little
    assert 0.044 < rough.settle.tolerance_deg < agile.settle.tolerance_deg
    smooth = with_load_model(agile, _report((0.003, -0.0015, 0.036), 0.001, 0.05, 0.01))
    assert smooth.settle.duration_s == 0.0


def test_the_commissioned_text_gains_a_plant_section_it_lacked(agile: Profile) -> None:
    text = AGILE.read_text()
    assert "[plant]" not in text
    new, back = with_values(text, {("plant", "payload_moment_kgmm"): list(S_KGMM),
                                   ("servo", "load_deg_per_nm"): K_TRUE}, "commissioned", "test")
    assert back.plant.payload_moment_kgmm == S_KGMM and back.servo.load_deg_per_nm == K_TRUE
    assert new.count("[plant]") == 1 and back.bus == agile.bus
    again, back2 = with_values(new, {("plant", "payload_moment_kgmm"): [1.0, 1.0, 1.0]},
                               "again", "test")
    assert again.count("[plant]") == 1 and back2.plant.payload_moment_kgmm == (1.0, 1.0, 1.0)


def test_each_joints_approach_is_the_sign_of_its_last_move() -> None:
    poses = np.array([[10.0, 0.0, 5.0], [12.0, 0.0, 4.0], [11.0, 0.02, 4.0]])
    np.testing.assert_array_equal(approach_signs(np.zeros(3), poses),
                                  [[1, 0, 1], [1, 0, -1], [-1, 0, -1]])


def test_the_imu_stage_holds_its_poses_without_settling(
        agile: Profile, monkeypatch: pytest.MonkeyPatch) -> None:
    """A profile commissioned before settles at its goals: the stage's own session does not,
    or the offsets the payload is fitted to would be taken up."""
    import spm_console.services.commissioning.imu_stage as stage
    from spm_console.errors import BusError

    seen: list[Profile] = []

    class Refused:
        def __init__(self, profile: Profile, **_kw: object) -> None:
            seen.append(profile)

        def connect(self) -> None:
            raise BusError("no bus in this test")

        def close(self) -> None:
            pass

    settles = agile.model_copy(update={"settle": agile.settle.model_copy(
        update={"duration_s": 2.0})})
    monkeypatch.setattr(stage, "Session", Refused)
    with pytest.raises(BusError):
        stage.refine_with_imu(settles, "/dev/null", object(), lambda _m: None)  # type: ignore[arg-type]
    assert len(seen) == 1 and seen[0].settle.duration_s == 0.0
    assert seen[0].bus == agile.bus and seen[0].servo == agile.servo


def test_a_weighed_mass_is_written_beside_the_first_moment_it_places(agile: Profile) -> None:
    """``payload_kg`` (weighed) goes with the fitted m·c: the payload's centre is m·c / m.
    Without a first moment it is not written; the profile refuses a mass without one, or one
    that puts the centre beyond ±300 mm; a profile without it keeps its hash."""
    clear = _report((0.003, -0.0015, 0.036), 0.001, 0.05)
    built = with_load_model(agile, clear, 0.3)
    assert built.plant.payload_kg == 0.3
    assert built.plant.payload_centre_mm == pytest.approx((10.0, -5.0, 120.0))
    unclear = _report((0.001, 0.0, 0.002), 0.002, 0.5)
    assert with_load_model(agile, unclear, 0.3).plant.payload_kg is None
    # a mass far lighter than weighed (or a first moment far off) would put the centre
    # beyond what a profile holds: the mass is left out, the first moment written, and the
    # profile validates (a whole commissioning is not lost to the typo)
    light = with_load_model(agile, clear, 0.05)  # m·c / m: z = 720 mm
    assert light.plant.payload_kg is None and light.plant.payload_moment_kgmm is not None
    Profile.model_validate(light.model_dump(mode="python"))
    assert _with(agile, S_KGMM).digest() == Profile.model_validate(
        _with(agile, S_KGMM).model_dump(mode="python")).digest()
    weighed = Profile.model_validate(built.model_dump(mode="python"))
    assert weighed.digest() != _with(agile, built.plant.payload_moment_kgmm).digest()
    for moment, kg, why in ((None, 0.3, "needs plant.payload_moment_kgmm"),
                            ((0.0, 0.0, 400.0), 1.0, "beyond ±300 mm"),
                            (S_KGMM, 0.0, "greater than 0")):
        plant = agile.plant.model_copy(update={"payload_moment_kgmm": moment, "payload_kg": kg})
        with pytest.raises(ValueError, match=why):
            Profile.model_validate(agile.model_copy(update={"plant": plant})
                                   .model_dump(mode="python"))


def test_a_tilted_base_is_fitted_with_its_gravity(agile: Profile) -> None:
    """The servos hold a wrist whose base stands 3° off level: fitted with the profile's
    gravity turned by that tilt (``[plant] base_tilt_deg``, what the IMU stage fits), the
    payload comes back exactly; fitted as if level, its first moment is several % off (the
    bias the IMU stage's tilt removes)."""
    tilted = agile.model_copy(update={"plant": agile.plant.model_copy(
        update={"base_tilt_deg": (2.1, -2.1)})})
    measured, R = _poses(agile, 24)
    rad = np.radians(measured)
    commanded = measured + K_TRUE * Weight.of(_with(tilted, S_KGMM)).torque_nm(rad, R)
    held = np.zeros(len(measured), bool)
    held[-4:] = True
    right = payload_from_holding(tilted, commanded, measured, held)
    np.testing.assert_allclose(right.fit.first_moment_kgm * 1e3, S_KGMM, atol=1e-6)
    level = payload_from_holding(agile, commanded, measured, held)
    err = np.linalg.norm(level.fit.first_moment_kgm * 1e3 - S_KGMM) / np.linalg.norm(S_KGMM)
    assert err > 0.03


def test_poses_held_on_the_profile_before_the_fit_are_fitted_on_the_wrist_as_fitted(
        agile: Profile) -> None:
    """The IMU stage's poses are held on the profile it ran on (a load model with a level
    base: k_c·τ_level sent) and fitted on the wrist as fitted (its base tilted): with what
    was sent given, the payload and the compliance come back exactly; taking the fitted
    profile's own load model as what was sent leaves k_c·(τ_tilted − τ_level) in the fit."""
    ran_on = _with(agile, (1.0, 2.0, 20.0), 1.1)
    tilted = ran_on.model_copy(update={"plant": ran_on.plant.model_copy(
        update={"base_tilt_deg": (2.1, -2.1)})})
    measured, R = _poses(agile, 24)
    true_tau = Weight.of(_with(tilted, S_KGMM)).torque_nm(np.radians(measured), R)
    commanded = measured + K_TRUE * true_tau
    for _ in range(30):
        commanded = measured - sent_at_rest(ran_on, commanded) + K_TRUE * true_tau
    held = np.zeros(len(measured), bool)
    held[-4:] = True
    right = payload_from_holding(tilted, commanded, measured, held,
                                 sent_deg=sent_at_rest(ran_on, commanded))
    np.testing.assert_allclose(right.fit.first_moment_kgm * 1e3, S_KGMM, atol=1e-6)
    assert right.fit.compliance_deg_per_nm == pytest.approx(K_TRUE, abs=1e-8)
    wrong = payload_from_holding(tilted, commanded, measured, held)
    err = np.linalg.norm(wrong.fit.first_moment_kgm * 1e3 - S_KGMM) / np.linalg.norm(S_KGMM)
    assert err > 0.01


@pytest.mark.parametrize(("s_kgm", "std", "kg", "says"), [
    ((0.003, -0.0015, 0.036), 0.001, 0.05, "payload mass 0.05 kg (weighed) not written: with "
     "the first moment fitted it puts the payload's centre beyond ±300 mm"),
    ((0.001, 0.0, 0.002), 0.002, 0.3, "payload mass 0.3 kg (weighed) not written: the offsets "
     "do not determine the first moment"),
    ((0.003, -0.0015, 0.036), 0.001, None, "give --payload-kg, weighed"),
    ((0.003, -0.0015, 0.036), 0.001, 0.3, "payload 0.3 kg (weighed) centred at"),
])
def test_the_report_says_why_a_weighed_mass_was_not_written(
        agile: Profile, s_kgm: tuple[float, float, float], std: float, kg: float | None,
        says: str) -> None:
    """A mass the operator gave and the profile does not carry is named, with the reason
    (before, the report asked for the --payload-kg it had been given)."""
    from types import SimpleNamespace

    from spm_console.services.commissioning.profile_out import commissioned_lines

    report = _report(s_kgm, std, 0.05)
    refinement = SimpleNamespace(
        horn_deg=(0.0, 0.0, 0.0), verification=SimpleNamespace(gravity_max_deg=0.05),
        motion_s=30.0, fit=SimpleNamespace(parameters=[], undetermined_named=[]),
        arcs_deg=None, tilt_deg=None, payload=report)
    result = SimpleNamespace(legs=[], rest_zero=None, tick_offsets=(1, 2, 3),
                             tick_trims=(0.0, 0.0, 0.0), refinement=refinement,
                             profile=with_load_model(agile, report, kg), payload_kg_weighed=kg,
                             held_at_jig=())
    lines = commissioned_lines(result)  # type: ignore[arg-type]
    assert any(says in line for line in lines), lines
