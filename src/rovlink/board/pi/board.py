"""The Raspberry Pi board (or any Linux board with I²C and GPIO): drivers wired per rov.toml.

Start-up order is the safety order: the PCA9685 first, its outputs at neutral before anything
else (ESC arming), then the sensors, each read once so a wrong address or a dead sensor is
refused at start, naming the device. If anything fails on the way, the outputs go back to
neutral and every device opened so far is released.
"""

from __future__ import annotations

import contextlib
import functools
import time
from collections.abc import Callable
from typing import Any, TypeVar

from rovlink.board.board import Board, BoardStartError, MonotonicClock
from rovlink.board.pi.ads1115 import Ads1115
from rovlink.board.pi.bno055 import Bno055Imu
from rovlink.board.pi.bus_check import check_bus
from rovlink.board.pi.claim import BoardInUseError, claim_exclusively
from rovlink.board.pi.config import (
    ClawKind,
    I2cBackend,
    ImuKind,
    PiConfig,
    PressureKind,
)
from rovlink.board.pi.fake_bus import FakeAds1115, FakeBno055, FakeI2cBus, FakeMs5837, FakePca9685
from rovlink.board.pi.i2c import I2cBus, Smbus2Bus
from rovlink.board.pi.imu_retry import IMU_RETRY_INTERVAL_S, ImuStartedInBackground
from rovlink.board.pi.leak import GpioLeakSensor
from rovlink.board.pi.ms5837 import Ms5837
from rovlink.board.pi.outputs import EscChannel, EscThrusters, MotorClaw, ServoClaw
from rovlink.board.pi.pca9685 import Pca9685
from rovlink.board.pi.pca9685_watch import Pca9685ResetWatch
from rovlink.board.pi.pressure import AnalogPressure, AnalogTransducer, Ms5837Pressure, RawScale
from rovlink.board.sensors import (
    LEVEL,
    PolledImu,
    PolledPressure,
    PolledSensor,
    SensorSource,
)
from rovlink.controller import Attitude, Hardware
from rovlink.logs import get_logger

__all__ = [
    "IMU_DID_NOT_START",
    "IMU_LOST_WHEN_STALE",
    "PwmBoardInUseError",
    "fake_bus_for",
    "open_pi_board",
    "set_pi_outputs_at_rest",
]

logger = get_logger(__name__)

_T = TypeVar("_T")
_FIRST_READING_S = 0.5  # how long a sensor has at start to give its first reading
_FAKE_WATER_C = 20.0  # the fake pressure sensor's temperature
#: What a dead IMU takes from the pilot. Not the motors: the controller steers by no attitude
#: (the protocol has no yaw command, P11, so it holds no heading), and stopping a robot that
#: can still be driven and surfaced by hand would make a compass fault a lost dive.
IMU_LOST_WHEN_STALE = (
    "roll, pitch and heading are not measured, qro, qpi and qhe repeat the last good reading"
)
#: What an IMU that did not start takes from the pilot (until it starts: it is tried again in
#: the background).
IMU_DID_NOT_START = (
    "roll, pitch and heading are not measured, qro, qpi and qhe read 0 until it answers "
    f"(started again every {IMU_RETRY_INTERVAL_S:g} s)"
)


class PwmBoardInUseError(BoardStartError):
    """Another rovlink controller holds the PWM board's bus: nothing was written to it."""


class _NoLeakSensor:
    def fired_since_last_read(self) -> bool:
        return False


class _NoClaw:
    def drive(self, direction: int) -> None:
        pass

    def neutral(self) -> None:
        pass


class _LevelImu:
    def read_attitude(self) -> Attitude:
        return LEVEL


def fake_bus_for(config: PiConfig, log_path: str = "") -> FakeI2cBus:
    """A fake bus with every device ``config`` names, at its address, at the surface."""
    devices: dict[int, Any] = {
        pwm.address: FakePca9685(pwm.oscillator_hz) for pwm in config.pwm_boards
    }
    pressure = config.pressure
    if pressure.sensor is PressureKind.MS5837:
        devices[pressure.ms5837.address] = FakeMs5837.reading(
            pressure.ms5837.model, pressure.surface_mbar, _FAKE_WATER_C
        )
    else:
        ads = pressure.ads1115
        fraction = (pressure.surface_mbar - ads.min_mbar) / (ads.max_mbar - ads.min_mbar)
        devices[ads.address] = FakeAds1115(
            ads.min_volts + fraction * (ads.max_volts - ads.min_volts)
        )
    if config.imu.sensor is ImuKind.BNO055 and not _imu_has_own_bus(config):
        devices[config.imu.address] = FakeBno055()
    return FakeI2cBus(devices, _fake_log(log_path))


def _fake_log(log_path: str) -> Any:
    # Appended line by line, flushed each time: several fake buses may share one file.
    return open(log_path, "a", encoding="utf-8") if log_path else None


def _imu_has_own_bus(config: PiConfig) -> bool:
    return config.imu.bus not in (-1, config.i2c.bus)


def _open_imu_bus(config: PiConfig, bus: I2cBus) -> I2cBus:
    """The main bus, or the IMU's own one."""
    if not _imu_has_own_bus(config):
        return bus
    if config.i2c.backend is I2cBackend.FAKE:
        return FakeI2cBus({config.imu.address: FakeBno055()}, _fake_log(config.i2c.fake_log))
    try:
        return Smbus2Bus(config.imu.bus)
    except OSError as error:
        raise BoardStartError(
            f"cannot open the IMU's I²C bus {config.imu.bus} (/dev/i2c-{config.imu.bus}): "
            f"{error.strerror or error}"
        ) from None


def open_pi_board(config: PiConfig, *, bus: I2cBus | None = None, pin_factory: Any = None) -> Board:
    """Open every device of ``config`` and return the board, thrusters at neutral.

    ``bus`` and ``pin_factory`` replace the I²C bus and gpiozero's pin factory (tests); without
    them they follow ``[i2c] backend``. Raises :class:`BoardStartError`.
    """
    closers: list[Callable[[], None]] = []
    if bus is None:
        bus = _open_bus(config)
        closers.append(_claim_or_close(config, bus))
    closers.append(bus.close)
    if pin_factory is None and config.i2c.backend is I2cBackend.FAKE and config.leak.pin >= 0:
        pin_factory = _starting("gpiozero's mock pins for the fake board", _mock_pins)
    thrusters, claw = _pwm_outputs(config, bus)
    where = f"on I²C bus {config.i2c.bus}"
    started = False
    devices = _devices_on_main_bus(config)

    def rest_pulses_us() -> dict[Pca9685, dict[int, float]]:
        return _rest_pulses_us(thrusters, claw)

    try:
        rest = rest_pulses_us()
        for pca, pwm in zip(thrusters.chips, config.pwm_boards, strict=True):
            started = True  # (from the first write on: neutral is set on the way out)
            _starting(
                f"PWM board PCA9685 at {pca.address:#04x} {where}",
                functools.partial(pca.start, pwm.frequency_hz, rest[pca]),
            )
            logger.info(
                "thrusters at neutral for ESC arming: PCA9685 at %#04x, pulses on channels %s "
                "at %.1f Hz",
                pca.address,
                ", ".join(str(channel) for channel in sorted(rest[pca])) or "none",
                pwm.frequency_hz,
            )
        clock = MonotonicClock()
        stale_after_s = config.board.stale_after_s
        pressure_name, pressure_source = _pressure_source(config, bus, where, clock)
        pressure = PolledSensor(
            pressure_name,
            pressure_source,
            _first_reading(f"{pressure_name} {where}", pressure_source, clock),
            stale_after_s,
        )
        sensors: list[PolledSensor[Any]] = [pressure]
        warnings: list[str] = []
        imu: Any = _LevelImu()
        if config.imu.sensor is ImuKind.BNO055:
            imu_sensor = _open_bno055(config, bus, closers, clock, warnings)
            sensors.append(imu_sensor)
            imu = PolledImu(imu_sensor)
        leak: Any = _NoLeakSensor()
        if config.leak.pin >= 0:
            leak = _starting(
                f"leak probe on GPIO {config.leak.pin}",
                lambda: GpioLeakSensor(
                    config.leak.pin,
                    active_high=config.leak.active_high,
                    pull=config.leak.pull,
                    pin_factory=pin_factory,
                ),
            )
            closers.append(leak.close)
    except BaseException as error:
        if started:
            with contextlib.suppress(Exception):
                thrusters.neutral()
        stuck = None
        if isinstance(error, BoardStartError):  # (after neutral: a probe may take its time)
            with contextlib.suppress(Exception):
                check = check_bus(bus, config.i2c.bus, devices)
                stuck = str(check) if check.stuck else None
        for release in reversed(closers):
            with contextlib.suppress(Exception):
                release()
        if stuck is not None:
            raise BoardStartError(f"{error}; {stuck}") from None
        raise

    def make_safe() -> None:
        try:
            thrusters.neutral()
        finally:  # a claw motor on a board that answers stops even if another board does not
            claw.neutral()

    def close_all() -> None:
        for release in reversed(closers):
            try:
                release()
            except Exception:
                logger.exception("closing the board")

    hardware = Hardware(
        thrusters=thrusters,
        pressure=PolledPressure(pressure),
        imu=imu,
        leak=leak,
        claw=claw,
        clock=clock,
    )
    checks = [
        Pca9685ResetWatch(pca, _rest_of(pca, rest_pulses_us), pwm.check_interval_s)
        for pca, pwm in zip(thrusters.chips, config.pwm_boards, strict=True)
        if pwm.check_interval_s > 0
    ]
    return Board(
        "pi",
        hardware,
        make_safe,
        close_all,
        tuple(sensors),
        tuple(checks),
        tuple(warnings),
        diagnose=lambda: str(check_bus(bus, config.i2c.bus, devices)),
    )


def _devices_on_main_bus(config: PiConfig) -> dict[int, str]:
    """The devices of ``config`` on its [i2c] bus, address → name, for a probe of the bus."""
    devices = {pwm.address: f"PWM board PCA9685 at {pwm.address:#04x}" for pwm in config.pwm_boards}
    pressure = config.pressure
    if pressure.sensor is PressureKind.MS5837:
        devices[pressure.ms5837.address] = f"MS5837 at {pressure.ms5837.address:#04x}"
    else:
        devices[pressure.ads1115.address] = f"ADS1115 at {pressure.ads1115.address:#04x}"
    if config.imu.sensor is ImuKind.BNO055 and not _imu_has_own_bus(config):
        devices[config.imu.address] = f"BNO055 at {config.imu.address:#04x}"
    return devices


def set_pi_outputs_at_rest(config: PiConfig, *, bus: I2cBus | None = None) -> str:
    """Put the thrusters at neutral and a claw motor at rest on the PCA9685 of ``config``, and
    nothing else (no sensor is opened); what was done, for a log line.

    For a controller that died without doing so itself (killed with SIGKILL, by the kernel's
    out-of-memory killer, a crash of the interpreter): the chip keeps making the last pulses it
    was given. A chip still running as the controller left it keeps a servo claw's pulse; one
    that is not (reset, not answering) is started as at the controller's start. Raises
    :class:`BoardStartError` naming the chip.
    """
    release: Callable[[], None] = _nothing
    if bus is None:
        bus = _open_bus(config)
        release = _claim_or_close(config, bus)
    done: list[str] = []
    failures: list[str] = []
    try:
        thrusters, claw = _pwm_outputs(config, bus)
        start = _rest_pulses_us(thrusters, claw)
        neutral = thrusters.neutral_pulses_us()  # (a servo claw keeps its place)
        if isinstance(claw, MotorClaw):
            neutral[claw.pca][claw.channel] = claw.rest_pulse_us()
        # Every chip, even after one failed: it must not keep another's thrusters running.
        for pca, pwm in zip(thrusters.chips, config.pwm_boards, strict=True):
            name = f"PWM board PCA9685 at {pca.address:#04x} on I²C bus {config.i2c.bus}"
            try:
                started = _starting(
                    name,
                    functools.partial(pca.take_over, pwm.frequency_hz, neutral[pca], start[pca]),
                )
            except BoardStartError as error:
                failures.append(str(error))
                continue
            how = "started again" if started else "running"
            channels = ", ".join(str(channel) for channel in sorted(neutral[pca])) or "none"
            done.append(f"{name} ({how}): neutral pulses on channels {channels}")
    finally:
        with contextlib.suppress(Exception):
            bus.close()
        release()
    if failures:
        raise BoardStartError("; ".join(failures + [f"done: {text}" for text in done]))
    return "; ".join(done)


def _nothing() -> None:
    pass


def _claim_or_close(config: PiConfig, bus: I2cBus) -> Callable[[], None]:
    """Lock the PWM board's bus for this process before anything is written to it (closing
    ``bus`` if it cannot be); the function that releases the lock.

    The lock is on /dev/i2c-N; on the fake bus, on its log, which stands for the one chip the
    processes of a test share.
    """
    addresses = " and ".join(f"{pwm.address:#04x}" for pwm in config.pwm_boards)
    boards = "PWM board" if len(config.pwm_boards) == 1 else "PWM boards"
    what = f"{boards} PCA9685 at {addresses} on I²C bus {config.i2c.bus}"
    if config.i2c.backend is I2cBackend.FAKE:
        path = config.i2c.fake_log
        if not path:
            return _nothing
    else:
        path = f"/dev/i2c-{config.i2c.bus}"
    try:
        return claim_exclusively(path)
    except BoardInUseError:
        bus.close()
        raise PwmBoardInUseError(
            f"{what} {'is' if len(config.pwm_boards) == 1 else 'are'} in use by another "
            "rovlink controller; stop it first "
            "(sudo systemctl stop rovlink)"
        ) from None
    except OSError as error:
        bus.close()
        raise BoardStartError(f"{what}: cannot lock {path}: {error.strerror or error}") from None


def _open_bus(config: PiConfig) -> I2cBus:
    if config.i2c.backend is I2cBackend.FAKE:
        logger.warning("fake I²C bus: simulated devices, nothing reaches hardware")
        return fake_bus_for(config, config.i2c.fake_log)
    try:
        return Smbus2Bus(config.i2c.bus)
    except ModuleNotFoundError as error:
        raise BoardStartError(
            f"I²C bus {config.i2c.bus}: the Python package {error.name} is missing; "
            "pip install 'rovlink[pi]'"
        ) from None
    except OSError as error:
        raise BoardStartError(
            f"cannot open I²C bus {config.i2c.bus} (/dev/i2c-{config.i2c.bus}): "
            f"{error.strerror or error}; is I²C enabled (raspi-config) and are you in the "
            "i2c group?"
        ) from None


def _open_bno055(
    config: PiConfig,
    bus: I2cBus,
    closers: list[Callable[[], None]],
    clock: MonotonicClock,
    warnings: list[str],
) -> PolledSensor[Attitude]:
    """Start the BNO055 (on its own bus if it has one) and take its first reading; a chip that
    does not is a sensor that fails every read (and a line in ``warnings``)."""
    imu = config.imu
    imu_bus = _open_imu_bus(config, bus)
    if imu_bus is not bus:
        closers.append(imu_bus.close)
    bno = Bno055Imu(
        imu_bus,
        address=imu.address,
        placement=imu.placement,
        heading_offset_deg=imu.heading_offset_deg,
        invert_roll=imu.invert_roll,
        invert_pitch=imu.invert_pitch,
        poll_hz=imu.poll_hz,
    )
    name = f"IMU BNO055 at {bno.address:#04x}"
    bus_number = imu.bus if imu_bus is not bus else config.i2c.bus
    where = f"{name} on I²C bus {bus_number}"
    # A board without the library is not set up: refused. A chip that does not answer is a
    # dead sensor the pilot can drive without (a restart mid-dive must not leave the robot
    # without thrusters): the controller goes on, and says so.
    _starting(where, _bno055_library)
    try:
        _starting(where, bno.start)
        first = _first_reading(where, bno, clock)
    except BoardStartError as error:
        logger.error("%s; going on without it: %s", error, IMU_DID_NOT_START)
        warnings.append(f"{name} not answering: {IMU_DID_NOT_START}")
        sensor: PolledSensor[Attitude]

        def started() -> None:  # (from now on, a stale IMU repeats its last good reading)
            sensor.lost_when_stale = IMU_LOST_WHEN_STALE

        retry = ImuStartedInBackground(bno, where, f"did not start ({error})", on_started=started)
        # Before the bus's closer (which runs later: closers run in reverse).
        closers.append(retry.close)
        sensor = PolledSensor(
            name, retry, LEVEL, config.board.stale_after_s, lost_when_stale=IMU_DID_NOT_START
        )
        return sensor
    return PolledSensor(
        name, bno, first, config.board.stale_after_s, lost_when_stale=IMU_LOST_WHEN_STALE
    )


def _bno055_library() -> None:
    import adafruit_bno055  # noqa: F401, PLC0415 - the pi extra, needed on the board only


def _mock_pins() -> Any:
    from gpiozero.pins.mock import MockFactory  # noqa: PLC0415

    return MockFactory()


def _rest_pulses_us(
    thrusters: EscThrusters, claw: MotorClaw | ServoClaw | _NoClaw
) -> dict[Pca9685, dict[int, float]]:
    """The outputs as the controller starts them, by chip: every ESC at neutral, a claw at
    rest."""
    rest = thrusters.neutral_pulses_us()
    if isinstance(claw, MotorClaw | ServoClaw):
        rest[claw.pca][claw.channel] = claw.rest_pulse_us()
    return rest


def _rest_of(
    pca: Pca9685, rest_pulses_us: Callable[[], dict[Pca9685, dict[int, float]]]
) -> Callable[[], dict[int, float]]:
    """The rest pulses of one chip, as they are when asked (a servo claw moves)."""
    return lambda: rest_pulses_us()[pca]


def _pwm_outputs(
    config: PiConfig, bus: I2cBus
) -> tuple[EscThrusters, MotorClaw | ServoClaw | _NoClaw]:
    """The PCA9685s of ``config`` on ``bus``, with their ESCs, and the claw (nothing written
    yet)."""
    chips = [
        Pca9685(bus, pwm.address, oscillator_hz=pwm.oscillator_hz) for pwm in config.pwm_boards
    ]
    escs = [
        (
            chips[config.pwm_board_index(esc.pca9685)],
            EscChannel(esc.channel, esc.reversed, esc.min_us, esc.neutral_us, esc.max_us),
        )
        for esc in config.escs
    ]
    claw = config.claw
    claw_chip = chips[0 if claw.kind is ClawKind.NONE else config.pwm_board_index(claw.pca9685)]
    return EscThrusters(chips, escs), _claw(config, claw_chip)


def _claw(config: PiConfig, pca: Pca9685) -> MotorClaw | ServoClaw | _NoClaw:
    claw = config.claw
    if claw.kind is ClawKind.MOTOR:
        return MotorClaw(
            pca,
            claw.channel,
            open_us=claw.open_us,
            close_us=claw.close_us,
            neutral_us=claw.neutral_us,
        )
    if claw.kind is ClawKind.SERVO:
        return ServoClaw(
            pca,
            claw.channel,
            open_us=claw.open_us,
            close_us=claw.close_us,
            start_us=claw.neutral_us,
            step_us=claw.step_us,
        )
    return _NoClaw()


def _pressure_source(
    config: PiConfig, bus: I2cBus, where: str, clock: MonotonicClock
) -> tuple[str, SensorSource[int]]:
    pressure = config.pressure
    depth = config.controller.depth
    scale = RawScale(depth.zero_raw, depth.k, pressure.surface_mbar, pressure.density_kg_m3)
    if pressure.sensor is PressureKind.MS5837:
        ms = pressure.ms5837
        sensor = Ms5837(
            bus, model=ms.model, address=ms.address, oversampling=ms.oversampling, clock=clock
        )
        name = f"pressure sensor MS5837-{ms.model.upper()} at {sensor.address:#04x}"
        _starting(f"{name} {where}", sensor.start)
        return name, Ms5837Pressure(sensor, scale)
    ads = pressure.ads1115
    adc = Ads1115(
        bus,
        address=ads.address,
        channel=ads.channel,
        full_scale_v=ads.full_scale_v,
        data_rate_sps=ads.data_rate_sps,
    )
    name = f"pressure transducer on ADS1115 at {adc.address:#04x} AIN{ads.channel}"
    _starting(f"{name} {where}", adc.start)
    transducer = AnalogTransducer(ads.min_volts, ads.max_volts, ads.min_mbar, ads.max_mbar)
    return name, AnalogPressure(adc, transducer, scale)


def _starting(what: str, action: Callable[[], _T]) -> _T:
    """Run a device's start-up; any failure becomes a :class:`BoardStartError` naming it."""
    try:
        return action()
    except ModuleNotFoundError as error:
        raise BoardStartError(
            f"{what}: the Python package {error.name} is missing; pip install 'rovlink[pi]'"
        ) from None
    except (OSError, RuntimeError, ValueError) as error:
        reason = error.strerror if isinstance(error, OSError) and error.strerror else error
        raise BoardStartError(f"{what}: {reason}") from None
    except Exception as error:  # a library's own (gpiozero's: a pin in use, a fixed pull)
        logger.debug("%s failed to start", what, exc_info=True)
        raise BoardStartError(f"{what}: {error}") from None


def _first_reading(what: str, source: SensorSource[_T], clock: MonotonicClock) -> _T:
    """Poll until the first reading (a conversion or two); :class:`BoardStartError` naming
    ``what`` (the device and its bus) if none."""
    deadline_s = clock.now_s() + _FIRST_READING_S
    error: Exception | None = None
    while clock.now_s() < deadline_s:
        try:
            reading = source.poll(clock.now_s())
        except OSError as failure:
            error = failure
            reading = None
        if reading is not None:
            return reading
        time.sleep(0.002)
    raise BoardStartError(f"{what}: no reading at start" + (f": {error}" if error else ""))
