"""The C reference and the Python controller take the same decisions on the same bytes.

Random streams (whole frames, damaged frames, checksummed frames, mode switches, noise, frames
around the length limit) go through the C layer (``host/replay.c``) and through the Python
controller. Both must dispatch the same commands with the same values, in the same order, and
answer the same queries with the same replies, checksummed or not.
"""

from __future__ import annotations

import itertools
import random
import subprocess
from collections.abc import Callable, Sequence
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rovlink.controller import Attitude, ControllerConfig, Hardware
from rovlink.controller.controller import Controller
from rovlink.protocol import (
    COMMANDS,
    Argument,
    Command,
    Decoder,
    Frame,
    Setting,
    Spec,
    Text,
    VerticalMode,
    encode,
    get_algorithm,
)
from tests.firmware.c_build import FIRMWARE, LAYER, STRICT, build, needs_gcc

pytestmark = needs_gcc

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
        checked = controller.state().checksum_enabled
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
    binary = tmp_path_factory.mktemp("c") / "replay"
    return build(binary, [FIRMWARE / "host" / "replay.c", *LAYER], *STRICT, "-O1")


@pytest.mark.integration
def test_c_and_python_take_the_same_decisions(replay: Path) -> None:
    rng = random.Random(15)
    for case in range(300):
        stream = _stream(rng)
        chunk = rng.choice((1, 3, 7, 64, 4096))
        expected = _python_decisions(stream, chunk)
        assert _c_decisions(replay, stream, chunk) == expected, (case, stream)


#: The C layer's algorithms by the number replay.c takes (rl_algorithm).
_C_ALGORITHMS = ("crc8", "xor", "sum8")
#: Debug lines the C layer writes itself (P5): compared word for word. Every "dropped" line is
#: compared by its presence only (the two name the reason in their own words); the lines of
#: settings the app writes, and the Python controller's lines about text between frames, are
#: not compared.
_LAYER_LINES = (
    "checksum mode",
    "debug output",
    "motors ",
    "stop command",
    "vertical mode",
    "start:",
)
#: Values at and past the range edges, signs, leading zeros, empty and malformed; and numbers
#: past 16 and 32 bits, which a parser that wraps would take for small ones (65541 for 5).
_VALUES: tuple[str, ...] = (
    *("0", "1", "00", "007", "-0", "+0", "+5", "-1", "99", "100", "+100", "-100", "101"),
    *("-101", "255", "256", "360", "361", "1024", "1025", "9999", "10000", "", "+", "x"),
    *("32768", "65541", "2147483648", "4294967301", "-2147483649", "9" * 30, "0" * 30 + "7"),
    *("+-5", "--5", "5+", "1e3", "0x10"),
)
#: Every spelling but the calibration's: replay.c's depth is fixed, the Python controller's
#: follows sdz and sdk (the decisions on those are compared above).
_SPELLINGS: tuple[tuple[Spec, str], ...] = tuple(
    (spec, name)
    for spec in COMMANDS
    if spec.name not in ("sdz", "sdk")
    for name in (spec.name, *spec.aliases)
)
_NAMES: tuple[str, ...] = (*(name for _, name in _SPELLINGS), *("Qd", "q", "mv", "h"))


def _argument_texts(argument: Argument) -> tuple[str, ...]:
    """A value at each edge of the argument's range, inside and out, as a host might write it;
    and the edges past 16 and 32 bits (a parser that wraps takes 65536 + low for low)."""
    low, high = argument.minimum, argument.maximum
    texts: tuple[str, ...]
    texts = (str(low), str(high), str((low + high) // 2), f"0{high}", str(high + 1), str(low - 1))
    texts += (str(low + 2**16), str(low + 2**32), str(2**31), "0" * 20 + str(high))
    if argument.signed:
        texts += (f"{high:+d}", f"{low:+d}", "+0", "-0", str(-(2**31) - 1), str(low - 2**32))
    return texts


def _body_of(name: str, values: tuple[str, ...]) -> str:
    return ".".join((name, *values))


#: Bodies of every spelling with its own number of values, near the edges of their ranges.
_TABLE_BODY_LIST = tuple(
    _body_of(name, values)
    for spec, name in _SPELLINGS
    for values in itertools.product(*(_argument_texts(a) for a in spec.arguments))
)
_TABLE_BODIES = st.sampled_from(_TABLE_BODY_LIST)
#: Any spelling (and a few that are none) with any values.
_LOOSE_BODIES = st.builds(
    lambda name, values: _body_of(name, tuple(values)),
    st.sampled_from(_NAMES),
    st.lists(st.sampled_from(_VALUES), max_size=3),
)
_BODIES = st.one_of(_TABLE_BODIES, _TABLE_BODIES, _LOOSE_BODIES)
#: Noise, mode frames, a reply, the longest frame and one a byte too long; one of 257 bytes (a
#: length kept in a byte wraps past 255) and one too long that does not end.
_NOISE: tuple[bytes, ...] = (
    *(b"\r\n", b" ", b"\x00", b"\x7f", b"\xff", b"#", b"$", b"!", b"$qd.5!", b"#crcon!"),
    *(b"#crcoff!", b"#debug1!", b"#debug0!", b"#start!", b"#stop!", b"#crcon!", b"#crcoff!"),
    *(b"#" + b"1" * 62 + b"!", b"#" + b"1" * 63 + b"!"),
    *(b"#" + b"1" * 255 + b"!", b"#mvs.+" + b"0" * 70),
)
#: A frame's checksum: none, right, right in lowercase, wrong, one digit only, a digit that is
#: no hex digit, a third digit.
_CHECKSUMS = ("none", "none", "none", "right", "right", "right", "lower", "wrong", "short")
_BAD_CHECKSUMS = ("nonhex", "extra")


def _one_piece(
    which: int, frame: tuple[str, str], noise: bytes, junk: bytes
) -> tuple[str, str] | bytes:
    return frame if which < 4 else noise if which == 4 else junk


#: Mostly frames (with no checksum or the right one most often), some noise. (Drawn by an
#: index: one_of would draw its simpler branches far more often than the frames.)
_STREAM_PIECES: st.SearchStrategy[tuple[str, str] | bytes] = st.builds(
    _one_piece,
    st.integers(0, 5),
    st.tuples(_BODIES, st.sampled_from(_CHECKSUMS + _BAD_CHECKSUMS)),
    st.sampled_from(_NOISE),
    st.binary(min_size=1, max_size=4),
)


def _piece_bytes(piece: tuple[str, str] | bytes, algorithm: str) -> bytes:
    if isinstance(piece, bytes):
        return piece
    body, checksum = piece[0].encode(), piece[1]
    digits = get_algorithm(algorithm).digits(body)
    if checksum == "lower":
        digits = digits.lower()
    elif checksum == "wrong":
        digits = b"%02X" % (int(digits, 16) ^ 0x10)
    elif checksum == "short":
        digits = digits[:1]
    elif checksum == "nonhex":
        digits = b"G" + digits[1:]
    elif checksum == "extra":
        digits += b"0"
    elif checksum == "none":
        digits = b""
    return b"#" + body + digits + b"!"


def _layer_debug(text: str) -> str | None:
    if text.startswith("dropped "):
        return "dropped"
    return text if text.startswith(_LAYER_LINES) else None


def _python_output(stream: bytes, chunk: int, algorithm: str) -> tuple[list[bytes], list[str]]:
    still = _Still()
    hardware = Hardware(
        thrusters=still, pressure=still, imu=still, leak=still, claw=still, clock=still
    )
    controller = Controller(ControllerConfig(checksum_algorithm=algorithm), hardware)
    for start in range(0, len(stream), chunk):
        controller.receive(stream[start : start + chunk])
    replies: list[bytes] = []
    debug: list[str] = []
    for event in Decoder().feed(controller.read_output()):
        if isinstance(event, Text):
            line = _layer_debug(event.text.removeprefix("debug: "))
            if line is not None:
                debug.append(line)
        else:  # (a reply, checksummed or not: the events of a plain decoder are not needed)
            replies.append(event.raw)
    return replies, debug


def _c_output(
    binary: Path, stream: bytes, chunk: int, algorithm: str
) -> tuple[list[bytes], list[str]]:
    arguments = [str(binary), str(chunk), str(_C_ALGORITHMS.index(algorithm)), "debug"]
    result = subprocess.run(arguments, input=stream, capture_output=True, check=True, timeout=60)
    replies: list[bytes] = []
    debug: list[str] = []
    for line in result.stdout.decode("ascii").splitlines():
        if line.startswith("R "):
            replies.append(line[2:].encode())
        elif line.startswith("D "):
            text = _layer_debug(line[2:])
            if text is not None:
                debug.append(text)
    return replies, debug


@pytest.mark.integration
@settings(max_examples=200)
@given(
    pieces=st.lists(_STREAM_PIECES, min_size=1, max_size=30),
    chunk=st.sampled_from((1, 2, 5, 64, 4096)),
    algorithm=st.sampled_from(_C_ALGORITHMS),
    debug_first=st.booleans(),
)
def test_c_and_python_write_the_same_replies_and_debug_lines(
    replay: Path,
    pieces: list[tuple[str, str] | bytes],
    chunk: int,
    algorithm: str,
    debug_first: bool,
) -> None:
    # Byte for byte the same replies, the same debug lines of the layer's own states, a
    # "dropped" line for the same frames, with every checksum algorithm (P1-P7, P9, P12).
    stream = (b"#debug1!" if debug_first else b"") + b"".join(
        _piece_bytes(piece, algorithm) for piece in pieces
    )
    assert _c_output(replay, stream, chunk, algorithm) == _python_output(stream, chunk, algorithm)


#: The states a frame is tried in, each as the frames that set it up (P3, P5, P7, P9).
_STATES = (
    ("#debug1!",),
    ("#debug1!", "#start!"),
    ("#debug1!", "#start!", "#mvdirect.1!"),
    ("#debug1!", "#crcon!"),
    ("#debug1!", "#crcon!", "start", "mvdirect.1"),
)


@pytest.mark.integration
@pytest.mark.parametrize("algorithm", _C_ALGORITHMS)
@pytest.mark.parametrize("state", _STATES, ids="".join)
def test_every_frame_near_its_range_edges_gets_the_same_answer_in_every_state(
    replay: Path, algorithm: str, state: tuple[str, ...]
) -> None:
    # Every spelling with values at its range edges, with each kind of checksum, after the
    # frames of a state; the state is set again after each frame (a #stop! or #crcoff! ends it).
    setup = b"".join(
        part.encode() if part.startswith("#") else _piece_bytes((part, "right"), algorithm)
        for part in state
    )
    frames = [
        _piece_bytes((body, checksum), algorithm)
        for body in _TABLE_BODY_LIST
        for checksum in ("none", "right", "lower", "wrong", "short", *_BAD_CHECKSUMS)
    ]
    stream = setup + b"".join(frame + b"#qr!" + setup for frame in frames)
    if _c_output(replay, stream, 4096, algorithm) == _python_output(stream, 4096, algorithm):
        return
    for frame in frames:  # the first frame that differs on its own, for the message
        alone = setup + frame + b"#qr!"
        c_output = _c_output(replay, alone, 4096, algorithm)
        python_output = _python_output(alone, 4096, algorithm)
        assert c_output == python_output, alone
    pytest.fail("the C layer and the Python controller differ on the frames in sequence")


@pytest.mark.integration
@pytest.mark.parametrize(
    "after",
    [b"", b"1" * 300, b"!", b"#qd!", b"$qd.5!", b"\r\n#qd!", b" qd!#qd!"],
    ids=["unended", "more", "end", "start", "reply", "line-break", "space"],
)
def test_a_frame_is_dropped_as_it_outgrows_the_limit(replay: Path, after: bytes) -> None:
    # Before: the C layer said "dropped" only at the frame's end (or the next start), and so
    # never for a frame that does not end; the Python controller says it when the 65th byte
    # comes. Once: the rest of the frame, up to its end, is skipped (P1).
    stream = b"#debug1!#" + b"1" * 63 + after
    for chunk in (1, 4096):
        expected = _python_output(stream, chunk, "crc8")
        assert expected[1].count("dropped") == 1 + (b"$" in after)
        assert _c_output(replay, stream, chunk, "crc8") == expected


#: What random bytes are drawn from: any byte; the protocol's characters and hex digits only,
#: which make frames, checksums and numbers far more often.
_ALPHABETS = (bytes(range(256)), b"#$!.+-0123456789ABCDEFabcdef qdstarmvhl\r\n")


@pytest.mark.integration
def test_c_and_python_agree_on_random_bytes(replay: Path) -> None:
    # Line noise of up to 4 KB, in any chunks, with debug on and after each checksum switch:
    # the same replies, the same lines of the layer's states, a "dropped" line for the same
    # frames, the same commands dispatched.
    rng = random.Random(7)
    for case in range(24):
        alphabet = _ALPHABETS[case % 2]
        noise = bytes(rng.choice(alphabet) for _ in range(rng.choice((16, 300, 4096))))
        start = rng.choice((b"#debug1!", b"#debug1!#start!", b"#debug1!#crcon!#start!"))
        stream = start + noise + b"#qd!#stop!"
        chunk = rng.choice((1, 7, 64, 4096))
        algorithm = _C_ALGORITHMS[case % 3]
        expected = _python_output(stream, chunk, algorithm)
        assert _c_output(replay, stream, chunk, algorithm) == expected, (case, stream)
        if algorithm == "crc8":  # (the dispatch is compared with the default algorithm)
            assert _c_decisions(replay, stream, chunk) == _python_decisions(stream, chunk), case


@pytest.mark.integration
@pytest.mark.parametrize("state", [b"", b"#start!", b"#start!#mvdirect.1!"], ids=repr)
def test_every_command_at_its_range_edges_is_dispatched_alike(replay: Path, state: bytes) -> None:
    # The calibration (sdz, sdk) too, which the replies above leave out: the same commands with
    # the same values, the same queries answered, at and past each edge of every range.
    bodies = [
        _body_of(name, values)
        for spec in COMMANDS
        for name in (spec.name, *spec.aliases)
        for values in itertools.product(*(_argument_texts(a) for a in spec.arguments))
    ]
    stream = b"".join(state + b"#" + body.encode() + b"!" for body in bodies)
    assert _c_decisions(replay, stream, 4096) == _python_decisions(stream, 4096)


class _Reading(_Still):
    """Hardware whose sensors read the given raw pressure and attitude."""

    def __init__(self, raw: int, attitude: Attitude) -> None:
        self.raw = raw
        self.attitude = attitude

    def read_raw(self) -> int:
        return self.raw

    def read_attitude(self) -> Attitude:
        return self.attitude


@pytest.mark.integration
@pytest.mark.parametrize(
    ("raw", "roll_deg", "pitch_deg", "heading_deg"),
    [(530, -1, 3, 275), (1500, 120, -95, 360), (-5, -91, 91, -1), (1024, 90, -90, 359)],
)
def test_replies_out_of_their_ranges_are_written_as_the_python_controller_writes_them(
    replay: Path, raw: int, roll_deg: int, pitch_deg: int, heading_deg: int
) -> None:
    # Before: the C layer wrote what the app's sensors gave: $qhe.360! for a heading that
    # rounds to 360, $qro.+120! for a roll past 90 (P15: headings 0-359, attitude within ±90).
    stream = b"#qr!#qro!#qpi!#qhe!#crcon!#qsaB1!"
    still = _Reading(raw, Attitude(float(roll_deg), float(pitch_deg), float(heading_deg)))
    hardware = Hardware(
        thrusters=still, pressure=still, imu=still, leak=still, claw=still, clock=still
    )
    controller = Controller(ControllerConfig(), hardware)
    controller.receive(stream)
    # (Read plain: the checksummed replies come as bad frames, with their bytes.)
    events = Decoder().feed(controller.read_output())
    python_replies = [event.raw for event in events if not isinstance(event, Text)]
    assert len(python_replies) == len(events) == 10
    # The depth is the app's to compute (P13): the C app is given the Python controller's.
    depth_cm = Decoder(checksum_enabled=True).feed(python_replies[4])[0]
    assert isinstance(depth_cm, Frame)
    values = (depth_cm.message.values[0], raw, 0, roll_deg, pitch_deg, heading_deg)
    arguments = [str(replay), "4096", "0", "debug", *(str(value) for value in values)]
    result = subprocess.run(arguments, input=stream, capture_output=True, check=True, timeout=60)
    lines = result.stdout.decode("ascii").splitlines()
    assert [line[2:].encode() for line in lines if line.startswith("R ")] == python_replies
