"""The low-level controller (PROTOCOL.md): decoded frames in, thruster duties and replies out.

The controller owns no I/O. Its owner feeds it the received bytes (:meth:`Controller.receive`),
calls :meth:`Controller.tick` at the configured rate, and passes on what it writes: replies and
debug lines, through the ``write`` callback or from :meth:`Controller.read_output`. Hardware is
reached only through :class:`~rovlink.controller.hardware.Hardware`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable
from dataclasses import dataclass

from rovlink.controller.config import ControllerConfig, LeakAction
from rovlink.controller.debug_output import debug_line, describe_frame
from rovlink.controller.hardware import Hardware
from rovlink.controller.mixer import ThrusterMixer
from rovlink.controller.pid import DepthPid
from rovlink.logs import get_logger
from rovlink.protocol import (
    COMMANDS,
    BadFrame,
    Command,
    Decoder,
    Frame,
    Kind,
    Response,
    Setting,
    Text,
    VerticalMode,
    encode,
    get_algorithm,
)
from rovlink.protocol.announcements import (
    STOP_COMMAND,
    UNLOCKED_TEXT,
    another_line_text,
    locked_text,
)

__all__ = ["Controller", "ControllerState"]

logger = get_logger(__name__)

_MAX_DEPTH_CM = 9999
#: The top of the raw scale `qr` reports (P13).
_RAW_MAX = 1024
_FULL_UP_PERCENT = 100
#: How far above the maximum depth the robot must rise before down thrust is allowed again.
_MAX_DEPTH_RELEASE_CM = 5
#: A raw reading at the top of the pressure sensor's range is "at least this deep", which a depth
#: hold must not push deeper on. The top is 1023 on a 10-bit converter (an Arduino's, the
#: simulator's) and 1024 on P13's `qr` scale (a board that maps pressure onto it clips there):
#: either is the top.
_RAW_SATURATED = 1023
#: How far below the top a saturated reading must come before down thrust is allowed again, raw
#: counts: a reading that noise flips at the top must not flip the hold (and its debug line).
_SATURATION_RELEASE_COUNTS = 3


@dataclass(frozen=True, slots=True)
class ControllerState:
    """A snapshot of everything a command can change (for tests and tools)."""

    locked: bool
    vertical_mode: VerticalMode
    vertical_thrust_percent: int
    target_depth_cm: int | None
    direction_deg: int
    power_percent: int
    max_pwm: int
    gains: tuple[int, int, int]
    depth_zero_raw: int
    depth_k: int
    leak_latched: bool
    debug_enabled: bool
    checksum_enabled: bool
    claw_direction: int


class Controller:
    """The controller of PROTOCOL.md: every P-rule, driven by bytes and a periodic tick.

    A board's main loop (or the simulator) does three things: ``receive(data)`` with every
    chunk from the serial line, ``tick()`` every ``config.tick_s`` seconds, and send on what
    the controller writes. Queries are answered inside ``receive``, so a reply is ready as soon
    as the query's last byte has arrived (P19).

    Served on several lines (``receive(data, line)``), each line has its own framing and
    checksum mode; the rest is the controller's. What it writes while it handles a line's bytes
    is for that line (``write``), but for what every line must hear, wherever it came from: the
    lock changing and another line taking over the driving (``write_to_every_line``; by
    default ``write``).
    """

    def __init__(
        self,
        config: ControllerConfig,
        hardware: Hardware,
        write: Callable[[bytes], None] | None = None,
        write_to_every_line: Callable[[bytes], None] | None = None,
    ) -> None:
        self.config = config
        self._hardware = hardware
        self._output = bytearray()
        self._write = write if write is not None else self._output.extend
        # What every line must hear even while the controller handles another line's bytes:
        # the lock changing (a `#stop!` or `#start!` from any line, a failsafe) and another line
        # taking over the driving. One line served: the same as ``write``.
        self._write_to_every_line = (
            write_to_every_line if write_to_every_line is not None else self._write
        )
        self._algorithm = get_algorithm(config.checksum_algorithm)
        # One decoder for each line the controller is served on (a PTY and a TCP client at
        # once): half a frame on one line must not be spoilt by bytes from another. The
        # checksum mode is each line's own: it is how the bytes of that wire are framed, and a
        # program on one line switching it must not make every frame of a program on another
        # line a bad one (the two would take turns re-asserting their modes, P21).
        self._decoders: dict[Hashable, Decoder] = {}
        # The lines whose replies carry a checksum. A line's decoder switches its own mode as
        # it reads a mode frame, possibly ahead of frames of the same chunk not yet executed;
        # this switches when the mode frame is executed, so a reply never takes a mode set
        # after its query (P3).
        self._checksum_lines: set[Hashable] = set()
        self._reading_line: Hashable = None
        # The line whose `start` or motion command was obeyed last: only its frames feed the
        # link-loss failsafe (P17), so a host that dies while driving is stopped even while
        # another line (a monitor polling the sensors) keeps talking.
        self._driving_line: Hashable = None
        self._mixer = ThrusterMixer(config.thrusters, config.max_pwm)
        self._pid = DepthPid(config.depth_pid)
        self._idle_duties = [0] * len(config.thrusters)
        # Read every tick: kept at hand rather than looked up through the config.
        self._tick_s = config.tick_s
        self._watchdog_s = config.watchdog_s
        self._max_depth_cm = config.depth.max_depth_cm
        # Commands that switch an on/off state are dispatched by the state the command table
        # says they switch; the others by name.
        self._setting_handlers: dict[Setting, Callable[[bool], None]] = {
            Setting.CHECKSUM: self._on_checksum_mode,
            Setting.DEBUG: self._on_debug_mode,
            Setting.LOCKED: self._on_locked,
            Setting.DIRECT_MODE: self._on_direct_mode,
            Setting.CLAW_OPEN: self._on_claw,
        }
        self._handlers: dict[str, Callable[[Command], None]] = {
            "mgmp": self._on_max_pwm,
            "mvpdp": self._on_gain,
            "mvpdi": self._on_gain,
            "mvpidd": self._on_gain,
            "mvs": self._on_vertical_thrust,
            "mvd": self._on_target_depth,
            "th": self._on_horizontal,
            "sdz": self._on_depth_zero,
            "sdk": self._on_depth_k,
            "slreset": self._on_leak_reset,
        }
        for spec in COMMANDS:
            if spec.setting is not None:
                self._handlers[spec.name] = self._on_setting
        self.reset()

    # -- public API --------------------------------------------------------------------------

    def reset(self) -> None:
        """The state after power-on (P3, P5, P7, P9): locked, depth mode, defaults from config."""
        config = self.config
        for decoder in self._decoders.values():
            decoder.reset()
            decoder.checksum_enabled = False
        self._checksum_lines.clear()
        # No line drives after power-on: the first `#start!` takes over from nobody.
        self._driving_line = None
        self._debug_enabled = False
        self._locked = True
        self._vertical_mode = VerticalMode.DEPTH
        self._vertical_thrust_percent = 0
        self._target_depth_cm: int | None = None
        self._direction_deg = 0
        self._power_percent = 0
        self._mixer.max_pwm = config.max_pwm
        self._mixer.set_horizontal(0, 0)
        self._pid.set_gains(config.depth_pid.kp, config.depth_pid.ki, config.depth_pid.kd)
        self._pid.reset()
        self._zero_raw = config.depth.zero_raw
        self._k = config.depth.k
        self._leak_latched = False
        self._claw_direction = 0
        self._claw_until_s = 0.0
        self._depth_limited = False
        self._depth_saturated = False  # the last reading at the top of the range
        now = self._hardware.clock.now_s()
        self._last_frame_s = now
        self._last_tick_s: float | None = None
        self._depth_cm = self._read_depth_cm()
        self._duties = list(self._idle_duties)
        self._hardware.thrusters.set_duties(self._duties)
        self._hardware.claw.drive(0)

    def receive(self, data: bytes, line: Hashable = None) -> None:
        """Take bytes received on ``line`` (any key naming it; one line: leave it out):
        execute every complete frame in them, answer queries at once."""
        decoder = self._decoders.get(line)
        if decoder is None:  # a new line starts with checksum mode off, as after a reset
            decoder = self._decoders[line] = Decoder(algorithm=self._algorithm)
        self._reading_line = line
        try:
            for event in decoder.feed(data):
                if isinstance(event, Frame):
                    self._frame(event)
                elif isinstance(event, BadFrame):
                    self._debug(
                        f"dropped {describe_frame(event.raw)}: {event.reason}: {event.detail}"
                    )
                elif isinstance(event, Text):
                    self._debug(f"ignored text between frames: {event.text.strip()[:60]!r}")
        finally:
            self._reading_line = None

    def forget_line(self, line: Hashable) -> None:
        """``line`` is gone (a TCP client closed, a serial device unplugged): what it left of a
        frame is dropped, and if it drove the robot, the robot stops as on `#stop!`.

        Its host can no longer steer or stop what it commanded, and nobody else is known to be
        in charge: the link-loss failsafe would stop it only ``watchdog_s`` later, or never when
        it is off.
        """
        self._decoders.pop(line, None)
        self._checksum_lines.discard(line)
        if line == self._driving_line:
            self._driving_line = None
            if not self._locked:
                self._stop("failsafe: the line that drove has gone")

    def tick(self) -> None:
        """One control period: sensors, leak latch, watchdog, claw timer, PID, thruster outputs."""
        hardware = self._hardware
        now = hardware.clock.now_s()
        last = self._last_tick_s
        dt_s = self._tick_s if last is None else now - last
        self._last_tick_s = now
        raw = hardware.pressure.read_raw()
        # _read_raw, inlined (this runs every tick): on the scale `qr` reports, so that the PID
        # holds the depth `qd` reports (P13) even with a sensor that reads past 1024.
        if raw > _RAW_MAX:
            raw = _RAW_MAX
        elif raw < 0:
            raw = 0
        depth_cm = (raw - self._zero_raw) * self._k // 100
        if depth_cm < 0:
            depth_cm = 0
        elif depth_cm > _MAX_DEPTH_CM:
            depth_cm = _MAX_DEPTH_CM
        self._depth_cm = depth_cm  # P13, inlined: this runs every tick
        if self._depth_saturated:
            saturated = raw > _RAW_SATURATED - _SATURATION_RELEASE_COUNTS
        else:
            saturated = raw >= _RAW_SATURATED
        if saturated is not self._depth_saturated:
            self._depth_saturated = saturated
            if saturated:
                self._debug(f"depth reading saturated at raw {raw}: a depth hold goes no deeper")
        if hardware.leak.fired_since_last_read():
            self._leak_fired()
        if self._claw_direction and now + 1e-9 >= self._claw_until_s:
            self._claw_direction = 0
            hardware.claw.drive(0)
        watchdog_s = self._watchdog_s
        # The slack keeps float noise in clock readings from costing a whole tick.
        if not self._locked and watchdog_s and now - self._last_frame_s + 1e-9 >= watchdog_s:
            self._stop(f"failsafe: no valid frame for {watchdog_s:g} s")
        if self._locked:
            duties = self._idle_duties
        else:
            duties = self._mixer.duties(self._vertical_output(depth_cm, dt_s))
        self._duties = duties
        hardware.thrusters.set_duties(duties)

    def failsafe(self, why: str) -> None:
        """Stop as on `#stop!` for a reason of the board's (a stale sensor): every output off,
        set-points cleared, locked; logged and, in debug mode, a debug line."""
        self._stop(why)

    def debug(self, text: str) -> None:
        """Write a debug line (P5) from the board, if debug output is on."""
        self._debug(text)

    def read_output(self) -> bytes:
        """Take what the controller wrote since the last call (when no ``write`` was given)."""
        output = bytes(self._output)
        self._output.clear()
        return output

    def state(self, line: Hashable = None) -> ControllerState:
        """A snapshot of the settings and set-points; ``checksum_enabled`` is ``line``'s (each
        line has its own checksum mode)."""
        return ControllerState(
            locked=self._locked,
            vertical_mode=self._vertical_mode,
            vertical_thrust_percent=self._vertical_thrust_percent,
            target_depth_cm=self._target_depth_cm,
            direction_deg=self._direction_deg,
            power_percent=self._power_percent,
            max_pwm=self._mixer.max_pwm,
            gains=(self._pid.kp, self._pid.ki, self._pid.kd),
            depth_zero_raw=self._zero_raw,
            depth_k=self._k,
            leak_latched=self._leak_latched,
            debug_enabled=self._debug_enabled,
            checksum_enabled=line in self._checksum_lines,
            claw_direction=self._claw_direction,
        )

    @property
    def locked(self) -> bool:
        """Whether motion commands are refused and every output is off (P7)."""
        return self._locked

    @property
    def surfacing_for_leak(self) -> bool:
        """Whether a leak is being answered with `leak_action = "surface"` (P14) and the robot
        is still surfacing as it set (full up thrust in direct mode, horizontal power 0, not
        stopped). Surfacing so needs no depth: a board whose pressure sensor dies keeps it
        going rather than stop a leaking robot where it is."""
        return (
            self._leak_latched
            and self.config.leak_action is LeakAction.SURFACE
            and not self._locked
            and self._surfacing()
        )

    @property
    def depth_cm(self) -> int:
        """The depth measured at the last tick, cm (P13)."""
        return self._depth_cm

    @property
    def duties(self) -> tuple[int, ...]:
        """The duties applied at the last tick or stop, in layout order."""
        return tuple(self._duties)

    @property
    def pid(self) -> DepthPid:
        """The depth PID (read its state; change gains through frames)."""
        return self._pid

    # -- frames ------------------------------------------------------------------------------

    def _frame(self, frame: Frame) -> None:
        message = frame.message
        if message.kind is not Kind.COMMAND:
            self._drop(frame, "a reply, not a command")
            return
        assert isinstance(message, Command)
        spec = message.spec
        line = self._reading_line
        if spec.motion and self._locked:
            self._drop(frame, "motors are locked; send start first")
            return
        if spec.motion or message.setting == (Setting.LOCKED, False):  # motion, or `start`
            if line != self._driving_line and self._driving_line in self._decoders:
                # Two hosts driving at once: each takes the other for idle. Say so on both.
                self._debug(another_line_text(describe_frame(frame.raw)), every_line=True)
            self._driving_line = line
        # Any valid command of the driving line keeps the link alive (P17), even one dropped
        # below (a query is enough).
        if line == self._driving_line:
            self._last_frame_s = self._hardware.clock.now_s()
        if spec.mode is not None and spec.mode is not self._vertical_mode:
            self._drop(frame, f"needs {spec.mode} mode, the vertical mode is {self._vertical_mode}")
            return
        if spec.is_query:
            self._reply(spec.replies)
            return
        self._handlers[spec.name](message)

    def _drop(self, frame: Frame, why: str) -> None:
        self._debug(f"dropped {describe_frame(frame.raw)}: {why}")

    def _reply(self, names: tuple[str, ...]) -> None:
        checksum = self._algorithm if self._reading_line in self._checksum_lines else None
        values = self._sensor_values(names)
        self._write(b"".join(encode(Response(name, (values[name],)), checksum) for name in names))

    def _sensor_values(self, names: tuple[str, ...]) -> dict[str, int]:
        values: dict[str, int] = {}
        hardware = self._hardware
        if "qd" in names or "qr" in names:
            raw = self._read_raw()
            values["qr"] = raw
            values["qd"] = self._depth_from_raw(raw)
        if "q.l" in names:
            values["q.l"] = int(self._leak_latched)
        if "qro" in names or "qpi" in names or "qhe" in names:
            attitude = hardware.imu.read_attitude()
            values["qro"] = _attitude_deg(attitude.roll_deg)
            values["qpi"] = _attitude_deg(attitude.pitch_deg)
            values["qhe"] = _round_half_up(attitude.heading_deg) % 360
        return values

    # -- command handlers --------------------------------------------------------------------

    def _on_setting(self, command: Command) -> None:
        setting = command.setting
        assert setting is not None  # only commands with a setting are dispatched here
        self._setting_handlers[setting[0]](setting[1])

    def _on_checksum_mode(self, enabled: bool) -> None:
        # The line's decoder has already switched on this frame (P3), and may have read past
        # it; the line's replies switch now. Other lines keep their own mode.
        if enabled:
            self._checksum_lines.add(self._reading_line)
            self._debug(f"checksum mode on ({self._algorithm.name})")
        else:
            self._checksum_lines.discard(self._reading_line)
            self._debug("checksum mode off")

    def _on_locked(self, locked: bool) -> None:
        if locked:
            self._stop(STOP_COMMAND, commanded=True)
            return
        if not self._locked:
            self._debug("start: motors already unlocked, nothing changed")
            return
        self._locked = False
        self._clear_set_points()
        self._debug(UNLOCKED_TEXT, every_line=True)

    def _on_debug_mode(self, enabled: bool) -> None:
        if enabled == self._debug_enabled:
            return
        if not enabled:
            self._debug("debug output off")
        self._debug_enabled = enabled
        if enabled:
            self._debug("debug output on")

    def _on_max_pwm(self, command: Command) -> None:
        (max_pwm,) = command.values
        self._debug(f"max PWM {max_pwm} (was {self._mixer.max_pwm})")
        self._mixer.max_pwm = max_pwm

    def _on_gain(self, command: Command) -> None:
        (gain,) = command.values
        pid = self._pid
        gains = {"mvpdp": pid.kp, "mvpdi": pid.ki, "mvpidd": pid.kd}
        label = {"mvpdp": "kp", "mvpdi": "ki", "mvpidd": "kd"}[command.name]
        self._debug(f"depth PID {label} {gain} (was {gains[command.name]})")
        gains[command.name] = gain
        pid.set_gains(gains["mvpdp"], gains["mvpdi"], gains["mvpidd"])

    def _on_direct_mode(self, direct: bool) -> None:
        mode = VerticalMode.DIRECT if direct else VerticalMode.DEPTH
        if mode is self._vertical_mode:
            self._debug(f"vertical mode already {mode}, nothing changed")
            return
        self._vertical_mode = mode
        self._vertical_thrust_percent = 0
        self._pid.reset()
        if mode is VerticalMode.DEPTH and not self._locked:
            self._target_depth_cm = self._read_depth_cm()
            self._debug(f"vertical mode depth, holding {self._target_depth_cm} cm")
        else:
            self._target_depth_cm = None
            self._debug(f"vertical mode {mode}, vertical thrust 0")

    def _on_vertical_thrust(self, command: Command) -> None:
        (self._vertical_thrust_percent,) = command.values
        self._debug(f"vertical thrust {self._vertical_thrust_percent:+d} %")

    def _on_target_depth(self, command: Command) -> None:
        (target_cm,) = command.values
        max_depth_cm = self._max_depth_cm
        if max_depth_cm and target_cm > max_depth_cm:
            self._debug(
                f"dropped target {target_cm} cm: deeper than the maximum depth {max_depth_cm} cm"
            )
            return
        if self._target_depth_cm is None:
            self._pid.reset()
        self._target_depth_cm = target_cm
        self._debug(f"target depth {target_cm} cm")

    def _on_horizontal(self, command: Command) -> None:
        direction_deg, power_percent = command.values
        self._direction_deg = direction_deg % 360
        self._power_percent = power_percent
        self._mixer.set_horizontal(self._direction_deg, power_percent)
        self._debug(f"horizontal {self._direction_deg} deg at {power_percent} %")

    def _on_depth_zero(self, command: Command) -> None:
        (self._zero_raw,) = command.values
        self._debug(f"depth zero {self._zero_raw}")

    def _on_depth_k(self, command: Command) -> None:
        (self._k,) = command.values
        if self._k:
            self._debug(f"depth coefficient k {self._k}")
        else:
            self._debug("depth coefficient k 0: depth reads 0; a depth hold goes no deeper")

    def _on_leak_reset(self, command: Command) -> None:
        self._leak_latched = False
        self._debug("leak latch reset")

    def _on_claw(self, opening: bool) -> None:
        self._claw_direction = 1 if opening else -1
        pulse_ms = self.config.claw_pulse_ms
        self._claw_until_s = self._hardware.clock.now_s() + pulse_ms / 1000.0
        self._hardware.claw.drive(self._claw_direction)
        action = "opening" if self._claw_direction > 0 else "closing"
        self._debug(f"claw {action} for {pulse_ms} ms")

    # -- behaviour ---------------------------------------------------------------------------

    def _read_raw(self) -> int:
        """The pressure sensor's reading on the scale ``qr`` reports, 0–1024 (P13)."""
        return min(max(self._hardware.pressure.read_raw(), 0), _RAW_MAX)

    def _read_depth_cm(self) -> int:
        return self._depth_from_raw(self._read_raw())

    def _depth_from_raw(self, raw: int) -> int:
        depth_cm = (raw - self._zero_raw) * self._k // 100
        return 0 if depth_cm < 0 else min(depth_cm, _MAX_DEPTH_CM)

    def _clear_set_points(self) -> None:
        self._vertical_thrust_percent = 0
        self._target_depth_cm = None
        self._direction_deg = 0
        self._power_percent = 0
        self._mixer.set_horizontal(0, 0)
        self._pid.reset()

    def _stop(self, why: str, *, commanded: bool = False) -> None:
        """Every output off at once, set-points cleared, motion locked (P7, P14, P17)."""
        self._locked = True
        self._clear_set_points()
        self._duties = list(self._idle_duties)
        # The thrusters first: an output that fails to stop (an I²C error on the claw's
        # write) must not leave them driving.
        self._hardware.thrusters.set_duties(self._duties)
        if self._claw_direction:
            self._claw_direction = 0
        self._hardware.claw.drive(0)
        if not commanded:  # a failsafe: worth a line in the log of the board's owner
            logger.warning("%s", locked_text(why))
        self._debug(locked_text(why), every_line=True)

    def _leak_fired(self) -> None:
        """The leak sensor fired since the last tick: latch it and take the leak action (P14).

        The action is taken on every report, not only on the one that set the latch: a robot
        started again before the latch was reset is stopped (or surfaced) by the next leak.
        """
        first = not self._leak_latched
        self._leak_latched = True
        action = self.config.leak_action
        if first:
            logger.warning("leak detected, action %s", action)
            self._debug(f"leak detected, action {action}")
        if action is LeakAction.STOP:
            if not self._locked:
                self._stop("leak")
        elif action is LeakAction.SURFACE:
            if self._locked:
                if first:
                    self._debug("leak: motors are locked, not surfacing")
                return
            if self._surfacing():
                return
            self._vertical_mode = VerticalMode.DIRECT
            self._vertical_thrust_percent = _FULL_UP_PERCENT
            self._target_depth_cm = None
            self._direction_deg = self._power_percent = 0
            self._mixer.set_horizontal(0, 0)
            self._pid.reset()
            self._debug("leak: surfacing, full up thrust in direct mode")

    def _surfacing(self) -> bool:
        """Whether the set-points are the leak action's `surface`: full up thrust in direct
        mode, horizontal power 0."""
        return (
            self._vertical_mode is VerticalMode.DIRECT
            and self._vertical_thrust_percent == _FULL_UP_PERCENT
            and self._power_percent == 0
        )

    def _vertical_output(self, depth_cm: int, dt_s: float) -> float:
        max_depth_cm = self._max_depth_cm
        # Released only a little above the limit: sensor noise at the limit must not flip it
        # (and its debug line) every tick.
        release_cm = max_depth_cm - _MAX_DEPTH_RELEASE_CM if self._depth_limited else max_depth_cm
        limited = max_depth_cm > 0 and depth_cm > release_cm
        if limited is not self._depth_limited:
            self._depth_limited = limited
            if limited:
                self._debug(f"past the maximum depth {max_depth_cm} cm: down thrust refused")
        lower = 0.0 if limited else -100.0
        if self._vertical_mode is VerticalMode.DIRECT:
            return max(float(self._vertical_thrust_percent), lower)
        target_cm = self._target_depth_cm
        if target_cm is None:
            return 0.0
        if self._depth_saturated or not self._k:
            # The depth is not measured (a reading at its top, or k 0: every depth reads 0):
            # a target below what it shows would be pushed for ever.
            lower = 0.0
        return self._pid.update(target_cm, depth_cm, dt_s, lower=lower)

    def _debug(self, text: str, *, every_line: bool = False) -> None:
        if self._debug_enabled:
            (self._write_to_every_line if every_line else self._write)(debug_line(text))


def _attitude_deg(value_deg: float) -> int:
    """Roll or pitch as the protocol writes it: rounded to nearest, clamped to ±90 (P15)."""
    rounded = _round_half_up(value_deg)
    return -90 if rounded < -90 else min(rounded, 90)


def _round_half_up(value: float) -> int:
    """To the nearest integer, halves up (Python's round() takes halves to the even one)."""
    return math.floor(value + 0.5)
