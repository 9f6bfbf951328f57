"""A physical emulated wrist: three MX-106 drives on the rigid-body wrist (MuJoCo).

Each servo is its firmware's position loop driving a DC motor (Protocol 2.0 e-manual):

* PWM = K_PP·e + K_PI·Σe + K_PD·Δe on the position error e in ticks, with K_PP = P/128,
  K_PI = I/65536, K_PD = D/16 (Position P/I/D Gain), clipped to the PWM Limit (885 = 100 %);
* the motor's torque at the output τ = kt/R·(duty·V − kt·ω): back-EMF, the supply and the
  winding resistance bound it (stall torque kt·V/R, no-load speed V/kt less friction);
* Coulomb and viscous friction and the rotor's reflected inertia act on the output joint.

The joints drive :func:`~spm_console.description.mjcf.wrist_mjcf`'s closed chain
under gravity (turned by the profile's base tilt). Angles are the joints' θ in radians
(θ_home at the model's rest pose). A wrist as built (an
:class:`~spm_console.description.mjcf.AsBuiltBody`) stands tilted as built, carries a payload,
an IMU whose truth :meth:`PhysicalWrist.truth` reads, and a home jig
(:mod:`spm_console.devices.emulator.as_built_parts`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np
from numpy.typing import NDArray

from spm_console.config.plant import STALL_DAMPING_NMS
from spm_console.config.schema import Plant
from spm_console.core.kinematics.links import LinkModel
from spm_console.core.kinematics.model import SpmModel
from spm_console.description import names
from spm_console.description.mjcf import (
    AsBuiltBody,
    PlantParams,
    plant_params,
    wrist_mjcf,
)
from spm_console.devices.dynamixel.control_table import table_for
from spm_console.devices.emulator.as_built_parts import AsBuiltParts, WristTruth
from spm_console.devices.emulator.bno055 import ImuTruth
from spm_console.devices.emulator.leg_contacts import CONTACT_CHECK_S, LegContacts

F = NDArray[np.float64]

#: The PWM register's full scale (PWM Limit 885 = 100 % duty).
PWM_FULL = 885.0
#: Overload shutdown: the drive at ≥ this duty with its shaft slower than OVERLOAD_RAD_S for
#: OVERLOAD_S on end latches the Overload error (assumed: the e-manual says only "a persistent
#: load that exceeds the maximum output").
OVERLOAD_DUTY = 0.95
OVERLOAD_RAD_S = 0.05
OVERLOAD_S = 1.0
#: A blocked shaft (stall fault): stiffness, N·m/rad, and damping, N·m·s/rad, of the stop
#: (the profile's ``plant.armature_kgm2`` is bounded below for that damping).
BLOCK_STIFFNESS = 2000.0
BLOCK_DAMPING = STALL_DAMPING_NMS


@dataclass(frozen=True)
class DriveGains:
    """Control-table values of one servo's position loop (raw register values: Position
    P/I/D Gain, PWM Limit)."""

    p: int
    i: int
    d: int
    pwm_limit: int

    @classmethod
    def power_on(cls) -> DriveGains:
        """The Protocol 2.0 firmware's values at power-on (its control table's initial values);
        also the loop of a servo on the 1.0 firmware, whose gains are not modelled."""
        t = table_for("2.0")
        return cls(*(int(t[name].initial or 0) for name in
                     ("position_p_gain", "position_i_gain", "position_d_gain", "pwm_limit")))

    def scaled(self) -> tuple[float, float, float, float]:
        """(K_P, K_I, K_D, PWM bound): the firmware's PWM per tick of error, of its sum and of
        its change, and the PWM it never exceeds (the e-manual's gain scaling: P/128, I/65536,
        D/16)."""
        return self.p / 128.0, self.i / 65536.0, self.d / 16.0, min(float(self.pwm_limit), PWM_FULL)


@dataclass
class Drive:
    """The firmware loop and motor of one servo (state: the integral and last error)."""

    params: PlantParams
    ticks_per_rad: float
    gains: DriveGains = field(default_factory=DriveGains.power_on)
    integral: float = 0.0
    last_error: float = 0.0
    pwm: float = 0.0

    def duty(self, goal_ticks: float, present_ticks: float) -> float:
        """One firmware sample: the PWM duty (−1..1) for this error."""
        e = goal_ticks - present_ticks
        self.integral += e
        kp, ki, kd, lim = self.gains.scaled()
        pwm = kp * e + ki * self.integral + kd * (e - self.last_error)
        self.last_error = e
        self.pwm = max(-lim, min(lim, pwm))
        return self.pwm / PWM_FULL

    def torque(self, duty: float, omega: float) -> float:
        """Motor torque at the output, N·m, for a duty and the output speed ω (rad/s)."""
        p = self.params
        return p.kt_nm_per_a / p.resistance_ohm * (duty * p.supply_v - p.kt_nm_per_a * omega)

    def current(self, duty: float, omega: float) -> float:
        """Winding current, A."""
        p = self.params
        return (duty * p.supply_v - p.kt_nm_per_a * omega) / p.resistance_ohm

    def reset(self) -> None:
        self.integral = 0.0
        self.last_error = 0.0
        self.pwm = 0.0


class PhysicalWrist:
    """The wrist's rigid bodies and its three drives, stepped to a time on demand."""

    def __init__(self, model: SpmModel, params: PlantParams | None = None,
                 ticks_per_turn: int = 4096, links: LinkModel | None = None,
                 body: AsBuiltBody | None = None) -> None:
        self.params = params or plant_params(Plant())
        self.spm = model
        self.mj = mujoco.MjModel.from_xml_string(wrist_mjcf(model, self.params, links, body))
        if self.mj.nu != 3:
            raise ValueError(f"the wrist's model has {self.mj.nu} actuators, not 3")
        self.parts = None if body is None else AsBuiltParts(self.mj, body)
        """The IMU and the jig of a wrist as built (None: the profile's wrist, neither)."""
        self.contacts = LegContacts(self.mj, links)
        """The legs' collision envelopes (none without a link model)."""
        self.data = mujoco.MjData(self.mj)
        self.ticks_per_rad = ticks_per_turn / (2.0 * math.pi)
        self.drives = [Drive(self.params, self.ticks_per_rad) for _ in range(3)]
        play = self.params.backlash_rad > 0.0
        # the output shaft's joint: against the rotor with a gear play, else the drive's own
        output = [names.play_joint(i) if play else names.motor_joint(i) for i in range(3)]
        self._joint = [self.mj.joint(n).qposadr[0] for n in output]
        self._dof = [self.mj.joint(n).dofadr[0] for n in output]
        self._motor_q = ([self.mj.joint(names.motor_joint(i)).qposadr[0] for i in range(3)]
                         if play else [])
        self._motor_dof = [self.mj.joint(names.motor_joint(i)).dofadr[0] for i in range(3)]
        """The drive's joint per servo: the rotor's with a gear play, else the output's."""
        self.goal = np.array(model.theta_home, float)
        """Goal angle per joint, rad (the servos' Goal Position)."""
        self.enabled = [False, False, False]
        """Torque on per joint (off: no drive; the gear, driven from the output, holds up to
        the backdrive friction)."""
        self.blocked: list[float | None] = [None, None, None]
        """Per joint, the angle (rad) at which its shaft is blocked (a stall fault), or None."""
        self.t = 0.0
        self._next_contact_check = 0.0
        self.duty = np.zeros(3)
        self.strain_s = np.zeros(3)
        """Per joint, how long its drive has pushed at full duty against a shaft that does
        not turn, s."""
        self.peak_current_a = np.zeros(3)
        """Per joint, the largest |winding current| of a driven motor since
        :meth:`take_peak_current`, A (0 with torque off: the winding is open)."""

    def overloaded(self, index: int) -> bool:
        """Whether joint ``index``'s drive has strained long enough to shut down."""
        return bool(self.strain_s[index] >= OVERLOAD_S)

    def command(self, index: int, goal_rad: float, enabled: bool, blocked: bool,
                gains: DriveGains | None = None) -> None:
        """One servo's goal (rad), torque on/off, whether its shaft is blocked and the gains
        of its position loop (None: unchanged)."""
        self.goal[index] = goal_rad
        if gains is not None:
            self.drives[index].gains = gains
        if enabled and not self.enabled[index]:
            self.drives[index].reset()
            self.strain_s[index] = 0.0
            self.release_jig()  # the operator takes the jig off as torque goes on
        self.enabled[index] = enabled
        # torque on: the motor drives the gear (Coulomb friction); off: the gear is driven
        # from the output, and holds
        self.mj.dof_frictionloss[self._motor_dof[index]] = (
            self.params.coulomb_nm if enabled else self.params.backdrive_friction_nm)
        if blocked and self.blocked[index] is None:
            self.blocked[index] = float(self.motor_angle()[index])
        elif not blocked:
            self.blocked[index] = None

    def take_peak_current(self) -> F:
        """The largest |winding current| per joint since the last call (A); starts again."""
        peak, self.peak_current_a = self.peak_current_a, np.zeros(3)
        return peak

    def current(self, index: int) -> float:
        """Winding current of joint ``index`` now, A."""
        return self.drives[index].current(float(self.duty[index]),
                                          float(self.motor_omega()[index]))

    def theta(self) -> F:
        """Joint angles θ at the output shafts (what the encoders read), rad."""
        q = self.data.qpos[self._joint]
        if self._motor_q:
            q = q + self.data.qpos[self._motor_q]
        return np.asarray(self.spm.theta_home + q, float)

    def omega(self) -> F:
        """Output shafts' speeds, rad/s."""
        w = self.data.qvel[self._dof]
        if self._motor_q:
            w = w + self.data.qvel[self._motor_dof]
        return np.asarray(w, float)

    def motor_angle(self) -> F:
        """The drives' angles at the output's scale (the gear's input side), rad from home."""
        src = self._motor_q if self._motor_q else self._joint
        return np.asarray(self.data.qpos[src], float)

    def motor_omega(self) -> F:
        """The drives' speeds at the output's scale, rad/s (back-EMF and current)."""
        return np.asarray(self.data.qvel[self._motor_dof], float)

    def hold_jig(self) -> None:
        """Fit the home jig (a wrist as built only): every output shaft held at θ_home, whatever
        its drive does, until :meth:`release_jig` or the first torque-on of any joint."""
        if self.parts is None:
            raise ValueError("only a wrist as built (an AsBuiltBody) has a home jig")
        self.parts.hold(self.data)

    def release_jig(self) -> None:
        """Take the home jig off (nothing without one)."""
        if self.parts is not None:
            self.parts.release(self.data)

    @property
    def jig_held(self) -> bool:
        return self.parts is not None and self.parts.held(self.data)

    def truth(self) -> WristTruth:
        """The truth now (a wrist as built only): what the IMU senses, the sensor's and the
        platform's orientation in the world, θ. Leaves the motion unchanged
        (:mod:`~spm_console.devices.emulator.as_built_parts`)."""
        if self.parts is None:
            raise ValueError("only a wrist as built (an AsBuiltBody) carries an IMU")
        return self.parts.read(self.mj, self.data, self.t, self.theta())

    def imu_truth(self) -> ImuTruth:
        """What an ideal IMU on the platform senses now (an emulated IMU's truth)."""
        return self.truth().imu

    def set_theta(self, theta: F) -> None:
        """Place the wrist at rest at θ (rad): the chain is assembled by the solver from θ (a
        jig is taken off)."""
        q = np.asarray(theta, float) - self.spm.theta_home
        mujoco.mj_resetData(self.mj, self.data)
        held = self._motor_q if self._motor_q else self._joint  # the output in mid-play
        self.data.qpos[held] = q
        # let the constraint solver assemble the passive joints with the motors held: the
        # held joints made heavy meanwhile, so the solver's corrections go to the passive ones
        forced = list(self._dof) + (list(self._motor_dof) if self._motor_q else [])
        armature = self.mj.dof_armature[forced].copy()
        self.mj.dof_armature[forced] = 1e3
        for _ in range(400):
            self.data.qpos[held] = q
            if self._motor_q:
                self.data.qpos[self._joint] = 0.0
            self.data.qvel[:] = 0.0
            mujoco.mj_step(self.mj, self.data)
        self.mj.dof_armature[forced] = armature
        self.data.qpos[held] = q
        if self._motor_q:
            self.data.qpos[self._joint] = 0.0
        self.data.qvel[:] = 0.0
        mujoco.mj_forward(self.mj, self.data)
        self.goal = np.asarray(theta, float).copy()
        for d in self.drives:
            d.reset()

    def closure_error(self) -> float:
        """Largest distance between the points each ``connect`` equality joins, m."""
        err = 0.0
        for k in range(self.mj.neq):
            b1, b2 = self.mj.eq_obj1id[k], self.mj.eq_obj2id[k]
            a1 = self.mj.eq_data[k, 0:3]
            a2 = self.mj.eq_data[k, 3:6]
            p1 = self.data.xpos[b1] + self.data.xmat[b1].reshape(3, 3) @ a1
            p2 = self.data.xpos[b2] + self.data.xmat[b2].reshape(3, 3) @ a2
            err = max(err, float(np.linalg.norm(p1 - p2)))
        return err

    def platform_rotation(self) -> F:
        """The platform's rotation from home (3, 3)."""
        return np.asarray(self.data.xmat[self.mj.body(names.PLATFORM).id].reshape(3, 3), float)

    def advance(self, t: float) -> None:
        """Step the wrist to time ``t`` (s), the drives sampled every step.

        The inner loop works on Python floats read once per step (``tolist``): MuJoCo's step
        takes about 7 µs here, and NumPy's per-element indexing and rounding of its scalars
        took five times that, so the emulated servos answered late under load. The drives'
        firmware sample (:meth:`Drive.duty`, :meth:`Drive.torque`, :meth:`Drive.current`) is
        inlined with its coefficients computed once per call: the same operations on the same
        numbers, without three method calls per joint and step."""
        dt = self.params.timestep_s
        if self.t + dt > t + 1e-12:
            return
        mj, data = self.mj, self.data
        qpos, qvel, ctrl = data.qpos, data.qvel, data.ctrl
        out_q, motor_q, motor_dof = self._joint, self._motor_q, self._motor_dof
        # the angle the drive turns: the rotor's with a gear play, else the output's
        drive_q = motor_q if motor_q else out_q
        home = [float(x) for x in self.spm.theta_home]
        goal = [float(x) * self.ticks_per_rad for x in self.goal]
        tpr = self.ticks_per_rad
        drives, enabled, blocked = self.drives, self.enabled, self.blocked
        kp, ki, kd, lim = (list(k) for k in zip(*(d.gains.scaled() for d in drives), strict=True))
        integral = [d.integral for d in drives]
        last = [d.last_error for d in drives]
        pwm_out = [d.pwm for d in drives]
        duty = [0.0, 0.0, 0.0]
        torque = [0.0, 0.0, 0.0]
        strain = [float(x) for x in self.strain_s]
        peak = [float(x) for x in self.peak_current_a]
        p = self.params
        volts, kt, ohm = p.supply_v, p.kt_nm_per_a, p.resistance_ohm
        kt_ohm = kt / ohm
        play = bool(motor_q)
        while self.t + dt <= t + 1e-12:
            qp = qpos.tolist()
            qv = qvel.tolist()
            for i in range(3):
                om = qv[motor_dof[i]]
                tau = 0.0
                du = 0.0
                if enabled[i]:
                    q = qp[out_q[i]] + qp[motor_q[i]] if play else qp[out_q[i]]
                    e = goal[i] - round((home[i] + q) * tpr)  # Drive.duty
                    integral[i] += e
                    pwm = kp[i] * e + ki[i] * integral[i] + kd[i] * (e - last[i])
                    last[i] = e
                    pwm = max(-lim[i], min(lim[i], pwm))
                    pwm_out[i] = pwm
                    du = pwm / PWM_FULL
                    tau = kt_ohm * (du * volts - kt * om)  # Drive.torque
                    amps = abs(du * volts - kt * om) / ohm  # Drive.current
                    if amps > peak[i]:
                        peak[i] = amps
                lock = blocked[i]
                if lock is not None:  # a blocked shaft: a stiff, damped stop where it stuck
                    tau += -BLOCK_STIFFNESS * (qp[drive_q[i]] - lock) - BLOCK_DAMPING * om
                duty[i] = du
                torque[i] = tau
                straining = abs(du) >= OVERLOAD_DUTY and abs(om) < OVERLOAD_RAD_S
                strain[i] = strain[i] + dt if straining else 0.0
            ctrl[0], ctrl[1], ctrl[2] = torque
            mujoco.mj_step(mj, data)
            self.t += dt
            if self.t >= self._next_contact_check:
                self._next_contact_check = self.t + CONTACT_CHECK_S
                self.contacts.check(self.data, self.t, self.theta)
        for i, d in enumerate(drives):
            d.integral, d.last_error, d.pwm = integral[i], last[i], pwm_out[i]
        self.duty = np.array(duty)
        self.strain_s = np.array(strain)
        self.peak_current_a = np.array(peak)
