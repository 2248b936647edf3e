"""The C reference and the Python controller take the same decisions on the same bytes.

Random streams (whole frames, damaged frames, checksummed frames, mode switches, noise, frames
around the length limit) go through the C layer (``host/replay.c``) and through the Python
controller. Both must dispatch the same commands with the same values, in the same order, and
answer the same queries with the same replies, checksummed or not.
"""

from __future__ import annotations

import random
import shutil
import subprocess
from collections.abc import Callable, Sequence
from pathlib import Path

import pytest

from rovlink.controller import Attitude, ControllerConfig, Hardware
from rovlink.controller.controller import Controller
from rovlink.protocol import COMMANDS, Command, Decoder, Frame, Setting, VerticalMode, encode

FIRMWARE = Path(__file__).resolve().parents[2] / "firmware" / "c"
GCC = shutil.which("gcc")
pytestmark = pytest.mark.skipif(GCC is None, reason="gcc is not installed (.ci/debian-packages)")

#: Settings the C layer keeps to itself (it tells the app nothing about them).
_LAYER_ONLY = (Setting.CHECKSUM, Setting.DEBUG)


class _Still:
    """Hardware that never changes: the decisions, not the physics, are compared."""

    def now_s(self) -> float:
        return 0.0

    def set_duties(self, duties: Sequence[int]) -> None:
        pass

    def read_raw(self) -> int:
        return 530

    def read_attitude(self) -> Attitude:
        return Attitude(-1.0, 3.0, 275.0)

    def fired_since_last_read(self) -> bool:
        return False

    def drive(self, direction: int) -> None:
        pass


def _python_decisions(stream: bytes, chunk: int) -> list[str]:
    still = _Still()
    hardware = Hardware(
        thrusters=still, pressure=still, imu=still, leak=still, claw=still, clock=still
    )
    lines: list[str] = []
    controller = Controller(ControllerConfig(), hardware, write=lambda data: None)
    for name, handler in list(controller._handlers.items()):
        spec = next(spec for spec in COMMANDS if spec.name == name)
        if spec.setting in _LAYER_ONLY:
            continue

        def recorded(command: Command, handler: Callable[[Command], None] = handler) -> None:
            if not _changes_something(controller, command):
                handler(command)  # (the C layer answers it itself: the app is not told)
                return
            index = next(i for i, spec in enumerate(COMMANDS) if spec is command.spec)
            lines.append(" ".join(["C", str(index), *(str(v) for v in command.values)]))
            handler(command)

        controller._handlers[name] = recorded
    reply = controller._reply

    def replied(names: tuple[str, ...]) -> None:
        checked = controller._checksum_enabled
        lines.extend(f"R {name} {'checksummed' if checked else 'plain'}" for name in names)
        reply(names)

    controller._reply = replied  # type: ignore[method-assign]
    for start in range(0, len(stream), chunk):
        controller.receive(stream[start : start + chunk])
    return lines


def _changes_something(controller: Controller, command: Command) -> bool:
    """False for a #start! while unlocked and an #mvdirect! to the mode in force: the Python
    controller writes "nothing changed"; the C layer does the same and tells the app nothing."""
    setting = command.setting
    if setting == (Setting.LOCKED, False):
        return controller.locked
    if setting is not None and setting[0] is Setting.DIRECT_MODE:
        return setting[1] != (controller.state().vertical_mode is VerticalMode.DIRECT)
    return True


def _c_decisions(binary: Path, stream: bytes, chunk: int) -> list[str]:
    result = subprocess.run(
        [str(binary), str(chunk)], input=stream, capture_output=True, check=True, timeout=60
    )
    lines = []
    checked = Decoder(checksum_enabled=True)
    for line in result.stdout.decode("ascii").splitlines():
        if line.startswith("R "):
            frame = line[2:].encode()
            events = checked.feed(frame)
            mode = "checksummed" if isinstance(events[0], Frame) else "plain"
            name = frame[1:].split(b".")[0].decode()
            name = "q.l" if name == "q" else name
            lines.append(f"R {name} {mode}")
        else:
            lines.append(line)
    return lines


_PIECES = (
    b"#qd!",
    b"#qsa!",
    b"#q.l!",
    b"#crcon!",
    b"#crcoff!",
    b"#stop!",
    b"#start!",
    b"#debug1!",
    b"#debug0!",
    b"#mvdirect.1!",
    b"#mvdirect.0!",
    b"#mvdirect.01!",
    b"#mvs.-50!",
    b"#mvs.50!",
    b"#mvs.+100!",
    b"#mvs.-0!",
    b"#mvd.250!",
    b"#th.90.40!",
    b"#th.361.0!",
    b"#mgmp.256!",
    b"#mvpdd.7!",
    b"#mvpidd.99!",
    b"#sdz.1024!",
    b"#sdk.0010000!",
    b"#h+!",
    b"#h-!",
    b"#QD!",
    b"#qd.1!",
    b"#mgmp.+5!",
    b"$qd.1!",
    b"#qd",
    b"!",
    b"#",
    b"\r\n",
    b" x ",
    b"#" + b"0" * 70 + b"!",
    b"#mgmp." + b"0" * 56 + b"7!",
    b"#mgmp." + b"0" * 57 + b"7!",
)


def _stream(rng: random.Random) -> bytes:
    parts = []
    for _ in range(rng.randrange(1, 40)):
        kind = rng.random()
        piece = rng.choice(_PIECES)
        if kind < 0.35 and piece.startswith(b"#") and piece.endswith(b"!") and len(piece) > 8:
            body = piece[1:-1]
            piece = encode(Command("qd"), "crc8") if body == b"qd" else piece
            if b"." in body or body.isalpha():  # a checksummed frame, sometimes damaged
                digits = b"%02X" % _crc8(body)
                if rng.random() < 0.3:
                    digits = digits.lower() if rng.random() < 0.5 else b"00"
                piece = b"#" + body + digits + b"!"
        elif kind < 0.4:
            piece = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 6)))
        parts.append(piece)
    return b"".join(parts)


def _crc8(body: bytes) -> int:
    from rovlink.protocol.checksum import crc8_smbus

    return crc8_smbus(body)


@pytest.fixture(scope="module")
def replay(tmp_path_factory: pytest.TempPathFactory) -> Path:
    assert GCC is not None
    binary = tmp_path_factory.mktemp("c") / "replay"
    subprocess.run(
        [
            GCC,
            "-std=c99",
            "-Wall",
            "-Wextra",
            "-Werror",
            "-pedantic",
            "-O1",
            f"-I{FIRMWARE}",
            "-o",
            str(binary),
            str(FIRMWARE / "host" / "replay.c"),
            str(FIRMWARE / "rovlink_proto.c"),
            str(FIRMWARE / "rovlink_commands.c"),
        ],
        check=True,
        timeout=120,
    )
    return binary


@pytest.mark.integration
def test_c_and_python_take_the_same_decisions(replay: Path) -> None:
    rng = random.Random(15)
    for case in range(300):
        stream = _stream(rng)
        chunk = rng.choice((1, 3, 7, 64, 4096))
        expected = _python_decisions(stream, chunk)
        assert _c_decisions(replay, stream, chunk) == expected, (case, stream)
