"""The vehicle's physics: heave with buoyancy and drag, planar motion and yaw, wave roll/pitch.

Planar motion carries the hull's rigid-body Coriolis and centripetal terms (Fossen's C_RB): in a
turn its mass goes on along a straight line, so that, seen from the hull, it skids outward (a
sway against the turn, growing with speed × turn rate). The added mass's own terms (C_A) are left
out with the Munk moment they bring: without the hull's lift, which damps a yaw more the faster
it goes and which this model does not have, that moment turns a vehicle running straight across
its way (at full ahead it spun into a 0.7 m/s skid within 10 s).

Coordinates: depth ``depth_m`` positive down from the surface, between the surface and a flat
bottom (``bottom_depth_m``); the planar position is north/east in metres; body axes are x
forward (surge), y starboard (sway); heading is clockwise from north.
Time advances in fixed steps of at most 10 ms whatever the controller's rate (semi-implicit Euler,
the drag taken at the end of each step so that no drag or step makes it oscillate), so a run is
a pure function of its inputs and its seed.
"""

from __future__ import annotations

import math
import operator
import random
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields

from rovlink.controller import ThrusterSpec
from rovlink.controller.config import parameter_doc as _doc

__all__ = ["MAX_STEP_S", "Vehicle", "VehicleParams", "thrust_n"]

_GRAVITY_M_S2 = 9.80665
_KGF_N = _GRAVITY_M_S2
_MAX_DUTY = 255.0
_FULL_TURN_RAD = 2.0 * math.pi
#: The periods of the three heave swells, as multiples of the wave period.
_SWELL_PERIOD_FACTORS = (0.8, 1.0, 1.3)
#: The longest step the equations of motion take: a longer one (a controller configured below
#: 100 Hz) is taken in equal steps no longer than this. The explicit drag terms are stable only
#: for short steps: at 1 Hz the vehicle under full down thrust bounced between the surface and
#: 1.9 m, and at 2 Hz it sank a third faster than at 100 Hz.
MAX_STEP_S = 0.01
#: Fields that must be ≥ 0 (masses added by the water, drags, a lag, a noise level).
_NON_NEGATIVE = (
    "added_mass_heave_kg",
    "added_mass_surge_kg",
    "added_mass_sway_kg",
    "heave_drag_n_s2_m2",
    "heave_linear_drag_n_s_m",
    "surge_drag_n_s2_m2",
    "sway_drag_n_s2_m2",
    "planar_linear_drag_n_s_m",
    "yaw_drag_n_m_s2",
    "yaw_linear_drag_n_m_s",
    "thruster_time_constant_s",
    "yaw_disturbance_n_m",
    "wave_roll_deg",
    "wave_pitch_deg",
    "wave_heave_n",
)


@dataclass(frozen=True, slots=True)
class VehicleParams:
    """A small ROV (about 12 kg, thrusters of 2–2.5 kgf); every value is configurable."""

    mass_kg: float = field(default=12.0, metadata=_doc("dry mass, kg"))
    added_mass_heave_kg: float = field(
        default=8.0, metadata=_doc("water moved along with the hull in heave, kg")
    )
    added_mass_surge_kg: float = field(default=5.0, metadata=_doc("added mass in surge, kg"))
    added_mass_sway_kg: float = field(default=9.0, metadata=_doc("added mass in sway, kg"))
    net_buoyancy_n: float = field(
        default=2.0,
        metadata=_doc("buoyancy minus weight, N; + floats (2 N rises at about 0.2 m/s)"),
    )
    heave_drag_n_s2_m2: float = field(
        default=50.0, metadata=_doc("quadratic heave drag, N per (m/s)²")
    )
    heave_linear_drag_n_s_m: float = field(
        default=2.0, metadata=_doc("linear heave drag, N per m/s")
    )
    surge_drag_n_s2_m2: float = field(
        default=35.0, metadata=_doc("quadratic surge drag, N per (m/s)²")
    )
    sway_drag_n_s2_m2: float = field(
        default=55.0, metadata=_doc("quadratic sway drag, N per (m/s)²")
    )
    planar_linear_drag_n_s_m: float = field(
        default=3.0, metadata=_doc("linear surge and sway drag, N per m/s")
    )
    yaw_inertia_kg_m2: float = field(
        default=0.5, metadata=_doc("yaw moment of inertia with added inertia, kg·m²")
    )
    yaw_drag_n_m_s2: float = field(
        default=0.8, metadata=_doc("quadratic yaw drag, N·m per (rad/s)²")
    )
    yaw_linear_drag_n_m_s: float = field(
        default=0.5, metadata=_doc("linear yaw drag, N·m per rad/s")
    )
    forward_thrust_kgf: float = field(
        default=2.5, metadata=_doc("one thruster's thrust at full forward duty, kgf")
    )
    reverse_thrust_kgf: float = field(
        default=2.0, metadata=_doc("one thruster's thrust at full reverse duty, kgf")
    )
    thruster_deadband: float = field(
        default=0.04, metadata=_doc("duty fraction below which a thruster gives no thrust")
    )
    thruster_curve_linear: float = field(
        default=0.4,
        metadata=_doc(
            "thrust curve: share of the linear term (the rest grows with the square of duty)"
        ),
    )
    thruster_time_constant_s: float = field(
        default=0.1, metadata=_doc("thrust lag behind a duty change, s")
    )
    yaw_disturbance_n_m: float = field(
        default=0.002, metadata=_doc("slow random yaw torque, rms N·m")
    )
    yaw_disturbance_period_s: float = field(
        default=20.0, metadata=_doc("correlation time of the yaw torque, s")
    )
    wave_roll_deg: float = field(
        default=2.0, metadata=_doc("wave roll amplitude at the surface, degrees")
    )
    wave_pitch_deg: float = field(
        default=1.0, metadata=_doc("wave pitch amplitude at the surface, degrees")
    )
    wave_period_s: float = field(default=5.0, metadata=_doc("wave period, s"))
    wave_decay_depth_m: float = field(
        default=2.0, metadata=_doc("depth over which wave motion falls by e, m")
    )
    wave_heave_n: float = field(
        default=0.0,
        metadata=_doc(
            "surface waves pushing the hull up and down: force amplitude at the surface, N "
            "(0: none); fades with depth as the wave motion does, seeded"
        ),
    )
    bottom_depth_m: float = field(
        default=50.0,
        metadata=_doc(
            "depth of the bottom, m: the vehicle rests on it as it floats against the surface"
        ),
    )
    roll_trim_deg: float = field(default=0.0, metadata=_doc("static roll, degrees"))
    pitch_trim_deg: float = field(default=0.0, metadata=_doc("static pitch, degrees"))

    def __post_init__(self) -> None:
        # Every value is a number of the physics: NaN or infinity anywhere ends up in the depth,
        # and the simulated pressure sensor then failed mid-run with a traceback.
        for item in fields(self):
            value = getattr(self, item.name)
            if not math.isfinite(value):
                raise ValueError(f"{item.name} must be a finite number, got {value}")
        for name in _NON_NEGATIVE:
            value = getattr(self, name)
            if value < 0:
                raise ValueError(f"{name} must be ≥ 0, got {value}")
        if not 0 <= self.thruster_curve_linear <= 1:
            raise ValueError(
                f"thruster_curve_linear must be in [0, 1], got {self.thruster_curve_linear}"
            )
        for name in (
            "mass_kg",
            "wave_period_s",
            "wave_decay_depth_m",
            "yaw_inertia_kg_m2",
            "yaw_disturbance_period_s",
            "forward_thrust_kgf",
            "reverse_thrust_kgf",
            "bottom_depth_m",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be > 0, got {value}")
        if not 0 <= self.thruster_deadband < 1:
            raise ValueError(f"thruster_deadband must be in [0, 1), got {self.thruster_deadband}")


def thrust_n(duty: float, params: VehicleParams) -> float:
    """One thruster's steady thrust for a signed duty (−255…+255), N.

    A dead band around zero, then a curve between linear and quadratic in the duty, weaker in
    reverse, as propeller thrusters are.
    """
    fraction = abs(duty) / _MAX_DUTY
    deadband = params.thruster_deadband
    if fraction <= deadband:
        return 0.0
    effective = min((fraction - deadband) / (1.0 - deadband), 1.0)
    linear = params.thruster_curve_linear
    shaped = effective * (linear + (1.0 - linear) * effective)
    if duty > 0:
        return shaped * params.forward_thrust_kgf * _KGF_N
    return -shaped * params.reverse_thrust_kgf * _KGF_N


def _picker(indices: Sequence[int]) -> Callable[[Sequence[int]], tuple[int, ...]]:
    """A fast function that picks ``indices`` out of a sequence, always as a tuple."""
    if not indices:
        return lambda values: ()
    if len(indices) == 1:
        (index,) = indices
        return lambda values: (values[index],)
    return operator.itemgetter(*indices)


class Vehicle:
    """The state of the simulated vehicle and its equations of motion."""

    def __init__(
        self,
        params: VehicleParams,
        thrusters: Sequence[ThrusterSpec],
        rng: random.Random,
    ) -> None:
        self.params = params
        self._random = rng.random
        self.time_s = 0.0
        self.depth_m = 0.0
        self.heave_m_s = 0.0  # + down
        self.north_m = 0.0
        self.east_m = 0.0
        self.surge_m_s = 0.0
        self.sway_m_s = 0.0
        self.heading_rad = rng.uniform(0.0, 2.0 * math.pi)
        self.yaw_rate_rad_s = 0.0
        self.net_buoyancy_n = params.net_buoyancy_n
        self.current_north_m_s = 0.0
        self.current_east_m_s = 0.0
        self._yaw_disturbance_n_m = 0.0
        self._wave_phase_rad = rng.uniform(0.0, 2.0 * math.pi)
        # Heave waves: three swells around the wave period with seeded phases, together as
        # strong (rms) as one wave of the configured amplitude. Drawn only when on, so that the
        # random streams of a vehicle without them stay as they were.
        self._heave_waves: tuple[tuple[float, float, float], ...] = ()
        if params.wave_heave_n > 0:
            weight = params.wave_heave_n / math.sqrt(3.0)
            self._heave_waves = tuple(
                (
                    weight,
                    2.0 * math.pi / (params.wave_period_s * factor),
                    rng.uniform(0.0, 2.0 * math.pi),
                )
                for factor in _SWELL_PERIOD_FACTORS
            )
        vertical = [i for i, spec in enumerate(thrusters) if spec.vertical]
        horizontal = [i for i, spec in enumerate(thrusters) if not spec.vertical]
        self._pick_vertical = _picker(vertical)
        self._pick_horizontal = _picker(horizontal)
        self._horizontal_axes = tuple(
            (
                math.cos(math.radians(thrusters[i].angle_deg)),
                math.sin(math.radians(thrusters[i].angle_deg)),
                thrusters[i].x_m,
                thrusters[i].y_m,
            )
            for i in horizontal
        )
        # Duties are whole numbers −255…+255: a table is exact and faster than the curve.
        self._thrust_table = {duty: thrust_n(duty, params) for duty in range(-255, 256)}
        self._duties: tuple[int, ...] = (0,) * len(thrusters)
        self._horizontal_duties: tuple[int, ...] = (0,) * len(horizontal)
        # Thrust the motors are asked for, and what they give after their lag (N, N·m).
        self._command_up_n = self._command_surge_n = self._command_sway_n = 0.0
        self._command_yaw_n_m = 0.0
        self.up_thrust_n = self.surge_thrust_n = self.sway_thrust_n = self.yaw_torque_n_m = 0.0
        self._heave_mass_kg = params.mass_kg + params.added_mass_heave_kg
        self._surge_mass_kg = params.mass_kg + params.added_mass_surge_kg
        self._sway_mass_kg = params.mass_kg + params.added_mass_sway_kg
        # The rigid-body Coriolis terms, m·v·r in surge and −m·u·r in sway, turn (u, v) along an
        # ellipse that keeps the kinetic energy ½(M_u·u² + M_v·v²): its scaled form turns at
        # m/√(M_u·M_v) times the yaw rate (a ratio, rad per rad), and is turned exactly (no
        # energy from the step).
        self._coriolis_turn_per_yaw = params.mass_kg / math.sqrt(
            self._surge_mass_kg * self._sway_mass_kg
        )
        self._sway_per_surge = math.sqrt(self._surge_mass_kg / self._sway_mass_kg)
        self._bottom_depth_m = params.bottom_depth_m
        self._dt_s = 0.0
        self._prepare(0.01)

    @property
    def duties(self) -> tuple[int, ...]:
        """The duties last applied to the thrusters."""
        return self._duties

    @property
    def heading_deg(self) -> float:
        """True heading, degrees 0–360."""
        return math.degrees(self.heading_rad) % 360.0

    def set_duties(self, duties: Sequence[int]) -> None:
        """Apply thruster duties (layout order); the thrust follows after the motors' lag."""
        new = tuple(duties)
        if new == self._duties:
            return
        if new and (max(new) > _MAX_DUTY or min(new) < -_MAX_DUTY):
            # Beyond what an ESC takes: it saturates at full thrust.
            new = tuple(int(max(-_MAX_DUTY, min(_MAX_DUTY, duty))) for duty in new)
        self._duties = new
        table = self._thrust_table
        up = 0.0
        for duty in self._pick_vertical(new):
            up += table[duty]
        self._command_up_n = up
        horizontal = self._pick_horizontal(new)
        if horizontal != self._horizontal_duties:
            self._horizontal_duties = horizontal
            surge = sway = torque = 0.0
            for duty, (cos_a, sin_a, x_m, y_m) in zip(
                horizontal, self._horizontal_axes, strict=True
            ):
                force = table[duty]
                surge += force * cos_a
                sway += force * sin_a
                torque += force * (x_m * sin_a - y_m * cos_a)
            self._command_surge_n = surge
            self._command_sway_n = sway
            self._command_yaw_n_m = torque

    def _prepare(self, dt_s: float) -> None:
        """Coefficients for steps of ``dt_s``: the step runs 100 000 times a second in fast mode."""
        params = self.params
        time_constant = params.thruster_time_constant_s
        self._lag = 1.0 - math.exp(-dt_s / time_constant) if time_constant > 0 else 1.0
        heave = dt_s / self._heave_mass_kg
        surge = dt_s / self._surge_mass_kg
        sway = dt_s / self._sway_mass_kg
        yaw = dt_s / params.yaw_inertia_kg_m2
        self._heave_dt = heave
        self._heave_quadratic = params.heave_drag_n_s2_m2 * heave
        self._heave_linear = params.heave_linear_drag_n_s_m * heave
        self._surge_dt = surge
        self._surge_quadratic = params.surge_drag_n_s2_m2 * surge
        self._surge_linear = params.planar_linear_drag_n_s_m * surge
        self._sway_dt = sway
        self._sway_quadratic = params.sway_drag_n_s2_m2 * sway
        self._sway_linear = params.planar_linear_drag_n_s_m * sway
        self._yaw_dt = yaw
        self._yaw_quadratic = params.yaw_drag_n_m_s2 * yaw
        self._yaw_linear = params.yaw_linear_drag_n_m_s * yaw
        period = params.yaw_disturbance_period_s
        self._disturbance_decay = -math.expm1(-dt_s / period)  # dt / period, and stable
        # Uniform kicks with the variance of the process's Gaussian ones (variance 1/12 → ×√12):
        # over many steps only the variance counts.
        self._disturbance_kick = params.yaw_disturbance_n_m * math.sqrt(24.0 * dt_s / period)
        self._dt_s = dt_s

    def step(self, dt_s: float) -> None:
        """Advance the state by ``dt_s`` seconds (in steps of at most :data:`MAX_STEP_S`)."""
        if dt_s != self._dt_s:
            if dt_s > MAX_STEP_S:
                steps = math.ceil(dt_s / MAX_STEP_S - 1e-9)
                for _ in range(steps):
                    self.step(dt_s / steps)
                return
            self._prepare(dt_s)
        lag = self._lag
        up_thrust = self.up_thrust_n
        up_thrust += (self._command_up_n - up_thrust) * lag
        self.up_thrust_n = up_thrust
        surge_thrust = self.surge_thrust_n
        surge_thrust += (self._command_surge_n - surge_thrust) * lag
        self.surge_thrust_n = surge_thrust
        sway_thrust = self.sway_thrust_n
        sway_thrust += (self._command_sway_n - sway_thrust) * lag
        self.sway_thrust_n = sway_thrust
        yaw_torque = self.yaw_torque_n_m
        yaw_torque += (self._command_yaw_n_m - yaw_torque) * lag
        self.yaw_torque_n_m = yaw_torque

        # Heave: buoyancy, thrust, waves and drag; the surface is a limit the vehicle floats
        # against, the bottom one it rests on (without it, full down thrust went on for ever:
        # 12 km down after four hours).
        speed = self.heave_m_s
        up_force = self.net_buoyancy_n + up_thrust
        if self._heave_waves:
            up_force += self.heave_wave_n()
        # Drag is taken at the end of the step (linearised implicit Euler): stable for any drag
        # and step, where the explicit form oscillated and blew up once drag × speed × step
        # outgrew the mass. The terminal speed is the same.
        speed = (speed - up_force * self._heave_dt) / (
            1.0 + self._heave_quadratic * abs(speed) + self._heave_linear
        )
        depth = self.depth_m + speed * dt_s
        if depth <= 0.0:
            depth = 0.0
            speed = max(speed, 0.0)
        elif depth >= self._bottom_depth_m:
            depth = self._bottom_depth_m
            speed = min(speed, 0.0)
        self.depth_m = depth
        self.heave_m_s = speed

        # Surge and sway: drag acts on the speed through the water, so a current carries the
        # vehicle along.
        heading = self.heading_rad
        cos_h = math.cos(heading)
        sin_h = math.sin(heading)
        current_north = self.current_north_m_s
        current_east = self.current_east_m_s
        surge = self.surge_m_s
        sway = self.sway_m_s
        flow = current_north * cos_h + current_east * sin_h
        relative = surge - flow
        surge = flow + (relative + surge_thrust * self._surge_dt) / (
            1.0 + self._surge_quadratic * abs(relative) + self._surge_linear
        )
        flow = current_east * cos_h - current_north * sin_h
        relative = sway - flow
        sway = flow + (relative + sway_thrust * self._sway_dt) / (
            1.0 + self._sway_quadratic * abs(relative) + self._sway_linear
        )
        self.surge_m_s = surge
        self.sway_m_s = sway
        self.north_m += (surge * cos_h - sway * sin_h) * dt_s
        self.east_m += (surge * sin_h + sway * cos_h) * dt_s

        # Yaw: a slow random torque (an Ornstein–Uhlenbeck process) makes the heading wander.
        disturbance = self._yaw_disturbance_n_m
        disturbance += (
            self._disturbance_kick * (self._random() - 0.5) - disturbance * self._disturbance_decay
        )
        self._yaw_disturbance_n_m = disturbance
        rate = self.yaw_rate_rad_s
        rate = (rate + (yaw_torque + disturbance) * self._yaw_dt) / (
            1.0 + self._yaw_quadratic * abs(rate) + self._yaw_linear
        )
        self.yaw_rate_rad_s = rate
        self.heading_rad = (heading + rate * dt_s) % _FULL_TURN_RAD
        # Coriolis: as the hull turns, its velocity turns back against it, taken as a rotation of
        # the scaled velocity by the Cayley transform (norm-preserving: a long turn gains no
        # speed from the steps), with the turn just made: a hull of its own mass alone keeps
        # its velocity over the ground as it turns.
        half_angle = 0.5 * self._coriolis_turn_per_yaw * rate * dt_s
        if half_angle:
            squared = half_angle * half_angle
            cos_turn = (1.0 - squared) / (1.0 + squared)
            sin_turn = 2.0 * half_angle / (1.0 + squared)
            ratio = self._sway_per_surge
            self.surge_m_s, self.sway_m_s = (
                surge * cos_turn + sway * sin_turn / ratio,
                sway * cos_turn - surge * sin_turn * ratio,
            )
        self.time_s += dt_s

    def heave_wave_n(self) -> float:
        """The waves' vertical force on the hull now, N (+ up), fading with depth."""
        if not self._heave_waves:
            return 0.0
        time_s = self.time_s
        total = sum(
            weight * math.sin(rate * time_s + phase) for weight, rate, phase in self._heave_waves
        )
        return total * math.exp(-self.depth_m / self.params.wave_decay_depth_m)

    def roll_pitch_deg(self) -> tuple[float, float]:
        """True roll and pitch: the trim plus wave motion that fades with depth."""
        params = self.params
        fade = math.exp(-self.depth_m / params.wave_decay_depth_m)
        phase = 2.0 * math.pi * self.time_s / params.wave_period_s + self._wave_phase_rad
        roll = params.roll_trim_deg + params.wave_roll_deg * fade * math.sin(phase)
        pitch = params.pitch_trim_deg + params.wave_pitch_deg * fade * math.sin(phase + 1.3)
        return roll, pitch
