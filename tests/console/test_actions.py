"""The console's line parser: commands through the driver's parser, its own words, and errors
that point at the culprit in the line."""

from __future__ import annotations

import pytest

from rovlink.console.actions import (
    InputError,
    Quit,
    SendCommand,
    SendRaw,
    SetChecksum,
    ShowHelp,
    ShowStatus,
    parse_line,
    parse_lines,
)
from rovlink.protocol import Command


@pytest.mark.parametrize(
    ("line", "command"),
    [
        ("qd", Command("qd")),
        ("th 270 25", Command("th", (270, 25))),
        ("mvs -50", Command("mvs", (-50,))),
        ("mvpidd 11", Command("mvpidd", (11,))),
        ("h+", Command("h+")),
        ("#qd!", Command("qd")),
        ("  #th.270.25!  ", Command("th", (270, 25))),
        ("q.l", Command("q.l")),
        ("mvpdd 7", Command("mvpidd", (7,))),
    ],
)
def test_commands(line: str, command: Command) -> None:
    assert parse_line(line) == SendCommand(command)


@pytest.mark.parametrize(
    ("line", "action"),
    [
        ("help", ShowHelp()),
        ("help th", ShowHelp("th")),
        ("help #mvpdd!", ShowHelp("mvpidd")),
        ("help raw", ShowHelp("raw")),
        ("checksum on", SetChecksum(True)),
        ("checksum off", SetChecksum(False)),
        ("raw #bogus!", SendRaw("#bogus!")),
        ("status", ShowStatus()),
        ("quit", Quit()),
        ("exit", Quit()),
    ],
)
def test_console_words(line: str, action: object) -> None:
    assert parse_line(line) == action


def test_blank_lines_do_nothing() -> None:
    assert parse_line("") is None
    assert parse_line("   ") is None


@pytest.mark.parametrize(
    ("line", "culprit", "words"),
    [
        ("th 400 25", "400", ["direction_deg", "0–360", "400"]),
        ("th 270 250", "250", ["power_percent", "0–100", "250"]),
        ("#th.270.101!", "101", ["power_percent", "0–100"]),
        ("mvs -101", "-101", ["thrust_percent", "-100…+100"]),
        ("mvs up", "up", ["thrust_percent", "integer"]),
        ("mvd.10000", "10000", ["target_depth_cm", "0–9999"]),
        ("mvpidd 100", "100", ["gain", "0–99"]),
        ("qd 5", "5", ["qd takes 0"]),
        ("th 1 2 3", "3", ["th takes 2", "<power_percent 0–100>"]),
        ("thrust 50", "thrust", ["unknown command 'thrust'", "did you mean", "th"]),
        ("checksum maybe", "maybe", ["on or off"]),
        ("help nosuch", "nosuch", ["unknown command"]),
        ("quit now", "now", ["quit takes nothing"]),
    ],
)
def test_errors_name_the_argument_and_range_and_point_at_it(
    line: str, culprit: str, words: list[str]
) -> None:
    with pytest.raises(InputError) as caught:
        parse_line(line)
    error = caught.value
    assert line[error.position :].startswith(culprit)
    for word in words:
        assert word in error.message


#: A console word mistyped, and the message: before, only the robot's commands were suggested
#: ("stauts": did you mean start?, which a person trying to read the status would then send).
#: Before, "did you mean start?" (the command that unlocks the motors) for a typo of the
#: console's own "status", and no hint at all for its other words.
MISTYPED_CONSOLE_WORDS = [
    ("stauts", "stauts", "unknown command 'stauts'; did you mean status, start?"),
    ("hlep", "hlep", "unknown command 'hlep'; did you mean help?"),
    ("checksm on", "checksm", "unknown command 'checksm'; did you mean checksum?"),
    ("qiut", "qiut", "unknown command 'qiut'; did you mean quit?"),
    ("rwa #qd!", "rwa", "unknown command 'rwa'; did you mean raw?"),
    ("help stauts", "stauts", "unknown command 'stauts'; did you mean status, start?"),
    ("chksum on", "chksum", "unknown command 'chksum'; did you mean checksum?"),
    ("Status", "Status", "unknown command 'Status': commands are lower-case, did you mean status?"),
    ("QUIT", "QUIT", "unknown command 'QUIT': commands are lower-case, did you mean quit?"),
    # the robot's commands as before
    ("TH 90 30", "TH", "unknown command 'TH': commands are lower-case, did you mean th?"),
    ("thrust 1", "thrust", "unknown command 'thrust'; did you mean th?"),
    ("Start", "Start", "unknown command 'Start': commands are lower-case, did you mean start?"),
]


@pytest.mark.parametrize(("line", "culprit", "message"), MISTYPED_CONSOLE_WORDS)
def test_a_mistyped_console_word_is_named_in_the_suggestion(
    line: str, culprit: str, message: str
) -> None:
    with pytest.raises(InputError) as caught:
        parse_line(line)
    assert caught.value.message == message
    assert caught.value.position == line.index(culprit)


@pytest.mark.parametrize(
    ("line", "position"),
    [
        ("th 270", 6),  # a value missing: where it goes
        ("#qd", 3),  # no end of frame
        ("raw", 3),
    ],
)
def test_errors_about_something_missing_point_at_the_end(line: str, position: int) -> None:
    with pytest.raises(InputError) as caught:
        parse_line(line)
    assert caught.value.position == position


@pytest.mark.parametrize(
    ("line", "command"),
    [
        ("#th.270.25CA!", Command("th", (270, 25))),  # (25CA is not read as a value)
        ("#qd8C!", Command("qd")),
        ("  #mvd.1004B!", Command("mvd", (100,))),
        ("#th.270.25!", Command("th", (270, 25))),  # typed without: the console adds it
    ],
)
def test_in_checksum_mode_a_frame_typed_with_its_checksum_is_taken(
    line: str, command: Command
) -> None:
    assert parse_line(line, checksum="crc8") == SendCommand(command)


def test_a_frame_with_a_wrong_checksum_says_so_and_points_at_it() -> None:
    with pytest.raises(InputError) as raised:
        parse_line("#th.270.25CB!", checksum="crc8")
    assert raised.value.message == "missing or wrong crc8 checksum"
    assert raised.value.position == len("#th.270.25")
    with pytest.raises(InputError, match="not a number"):  # checksum mode off: a bad value
        parse_line("#th.270.25CA!")


def test_pasted_lines_are_each_a_line_of_their_own() -> None:
    # Before, a paste of several lines was one line: "start takes 0 value(s), got 4", and
    # "th 0\n50" was sent as th 0 50.
    assert parse_lines("start\r\nth 0 40\n\n  qd  \n") == [
        SendCommand(Command("start")),
        SendCommand(Command("th", (0, 40))),
        SendCommand(Command("qd")),
    ]
    with pytest.raises(InputError, match=r"^line 1: th takes 2 value") as refused:
        parse_lines("th 0\n50")
    assert refused.value.position == len("th 0")


def test_a_bad_pasted_line_refuses_them_all_naming_it_and_pointing_into_it() -> None:
    text = "start\nth 0 40\nmvs 500\nqd"
    with pytest.raises(InputError) as refused:
        parse_lines(text)
    assert refused.value.message == "line 3: mvs: thrust_percent must be in -100…+100, got 500"
    assert text[refused.value.position :].startswith("500")
    with pytest.raises(InputError, match=r"^mvs: thrust") as alone:  # one line: no number
        parse_lines("\nmvs 500\n")
    assert alone.value.position == len("\nmvs ")


def test_frames_pasted_on_one_line_run_one_after_another() -> None:
    # Frames copied from a capture or a log come as one line: before, it was refused ("one
    # frame at a time: '#start!#th.90.30!' holds more than one") with no way on but retyping.
    assert parse_lines("#start!#th.90.30!  #qd8C!", "crc8") == [
        SendCommand(Command("start")),
        SendCommand(Command("th", (90, 30))),
        SendCommand(Command("qd")),
    ]
    text = "qd\n #start!#th.400.30!#qd!"
    with pytest.raises(InputError) as refused:  # checked whole first: none runs
        parse_lines(text)
    assert refused.value.message == "line 2: th: direction_deg must be in 0–360, got 400"
    assert text[refused.value.position :].startswith("400.30!")
    with pytest.raises(InputError, match="must end with '!'"):  # (not frames, each whole)
        parse_line("#start!#th.90.30")


@pytest.mark.parametrize(
    ("line", "culprit"),
    [("#qd!$qd.5!", "$qd.5!"), ("#qd!!", "!"), ("##qd!", "#"), ("#th.90.30!junk", "junk")],
)
def test_a_line_of_frames_with_something_else_in_it_points_at_what_is_not_a_frame(
    line: str, culprit: str
) -> None:
    # Before, "one frame at a time: '#qd!$qd.5!' holds more than one", the cursor at the start
    # (and in a console that runs several frames on a line).
    with pytest.raises(InputError) as refused:
        parse_lines(line)
    assert refused.value.message.startswith(f"not a whole frame: {culprit!r}")
    assert line[refused.value.position :].startswith(culprit)
