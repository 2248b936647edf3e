"""One control period of the Pi board: CPU time, and the I²C bus time it needs.

    PYTHONPATH=src python bench/board_period.py [--periods 5000] [--repeat 3]

Runs the board loop's control period (poll the MS5837 and the BNO055, the stale-sensor check,
the PCA9685 read-back when due, the controller's tick, the PCA9685 writes) on the fake I²C bus
of ``examples/rov.toml``, while holding a depth and moving (``#start!#mvd.100!#th.30.60!``), so
that the depth PID changes the vertical thrusters' pulses every period. The simulated robot's
step (the same controller's tick plus the physics) is measured in the same run as the peer, and
the ratio printed.

The fake bus costs little CPU; a real one costs bus time. From the transactions recorded, the
bench also prints the bytes on the bus per period and the time they take at 100 kHz and
400 kHz (9 bits a byte, plus start, repeated start and stop), against the 10 ms period.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from rovlink.board.pi.board import fake_bus_for, open_pi_board
from rovlink.board.pi.config import load_pi_config
from rovlink.board.server import BoardServer
from rovlink.sim import SimulatedRobot

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "rov.toml"
SCENARIO = b"#start!#mvd.100!#th.30.60!"
_BITS_PER_BYTE = 9  # eight data bits and the acknowledge
_FRAMING_BITS = 3  # start, stop, and a repeated start on a register read (roughly)


def _server(directory: Path) -> BoardServer:
    """The example's board on the fake bus: no leak pin, the scenario sent. The controller's
    clock is the machine's: the periods, run back to back, take well under the 10 s link-loss
    failsafe (a robot's longest), which then never trips."""
    text = EXAMPLE.read_text(encoding="utf-8")
    text = text.replace('backend = "smbus2"', 'backend = "fake"').replace("pin = 27", "pin = -1")
    text = text.replace("watchdog_s = 2.0", "watchdog_s = 10.0")
    path = directory / "rov.toml"
    path.write_text(text, encoding="utf-8")
    config = load_pi_config(path)
    board = open_pi_board(config, bus=fake_bus_for(config))
    server = BoardServer(config.controller, board)
    server.controller.receive(SCENARIO)
    return server


def board_periods(periods: int) -> tuple[float, float]:
    """(µs of CPU per control period, µs of bus time per period at 100 kHz)."""
    with tempfile.TemporaryDirectory() as directory:
        server = _server(Path(directory))
    bus = server.board.hardware.thrusters.chips[0].bus  # type: ignore[attr-defined]
    clock = server.clock
    before = len(bus.transactions)
    started = time.process_time()
    now = clock.now_s()
    for n in range(periods):
        server._control_period(now + n * 0.01)  # the loop's own period, on a 10 ms grid
    cpu_us = (time.process_time() - started) / periods * 1e6
    transactions = bus.transactions[before:]
    bits = sum(
        (1 + len(t.written) + (1 if t.read else 0) + len(t.read)) * _BITS_PER_BYTE + _FRAMING_BITS
        for t in transactions
    )
    return cpu_us, bits / periods / 100e3 * 1e6


def sim_steps(periods: int) -> float:
    """µs of CPU per step of the simulated robot (controller tick and physics)."""
    robot = SimulatedRobot(seed=1)
    robot.receive(SCENARIO)
    step = robot.step
    started = time.process_time()
    for _ in range(periods):
        step()
    return (time.process_time() - started) / periods * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--periods", type=int, default=5000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    board, bus, sim = [], [], []
    for _ in range(args.repeat):  # interleaved: both see the same machine load
        cpu_us, bus_us = board_periods(args.periods)
        board.append(cpu_us)
        bus.append(bus_us)
        sim.append(sim_steps(args.periods))
    board_us, sim_us, bus_us = (statistics.median(x) for x in (board, sim, bus))
    print(f"control period on the Pi board (fake bus): {board_us:8.1f} µs CPU")
    print(f"simulated robot step (tick + physics):     {sim_us:8.1f} µs CPU")
    print(f"ratio board / simulator:                   {board_us / sim_us:8.2f}")
    print(f"I²C bus time per period at 100 kHz:        {bus_us / 1000:8.2f} ms of 10 ms")
    print(f"I²C bus time per period at 400 kHz:        {bus_us / 4000:8.2f} ms of 10 ms")


if __name__ == "__main__":
    main()
