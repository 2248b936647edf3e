"""Completion and argument hints come from the command table; the prompt_toolkit completer
passes them on unchanged."""

from __future__ import annotations

import pytest
from prompt_toolkit.completion import CompleteEvent
from prompt_toolkit.document import Document

from rovlink.console.actions import BUILTINS
from rovlink.console.app import ConsoleCompleter
from rovlink.console.completion import argument_hint, suggestions
from rovlink.protocol import COMMANDS


def test_an_empty_line_offers_every_command_and_console_word() -> None:
    offered = [suggestion.text for suggestion in suggestions("")]
    assert offered == [spec.name for spec in COMMANDS] + [builtin.name for builtin in BUILTINS]


def test_names_complete_with_their_descriptions() -> None:
    found = suggestions("mv")
    assert [s.text for s in found] == ["mvpdp", "mvpdi", "mvpidd", "mvdirect", "mvs", "mvd"]
    assert all(s.start == -2 for s in found)
    assert found[-1].meta == "depth mode: hold this depth, cm from the surface"


def test_frames_complete_to_a_whole_frame_or_up_to_the_first_value() -> None:
    assert [s.text for s in suggestions("#qh")] == ["#qhe!"]
    assert [s.text for s in suggestions("#mvd")] == ["#mvdirect.", "#mvd."]
    assert suggestions("#qh")[0].start == -3


def test_help_completes_names_and_checksum_on_off() -> None:
    assert [s.text for s in suggestions("help qs")] == ["qsa"]
    assert [s.text for s in suggestions("checksum o")] == ["on", "off"]
    assert [s.text for s in suggestions("checksum of")] == ["off"]


@pytest.mark.parametrize(
    ("before", "display"),
    [
        ("th ", "<direction_deg 0–360>"),
        ("th 27", "<direction_deg 0–360>"),
        ("th 270 ", "<power_percent 0–100>"),
        ("mvs ", "<thrust_percent -100…+100>"),
        ("sdk ", "<k 0–10000>"),
    ],
)
def test_arguments_get_a_hint_with_their_range_that_inserts_nothing(
    before: str, display: str
) -> None:
    (hint,) = suggestions(before)
    assert (hint.text, hint.start, hint.display) == ("", 0, display)


def test_flags_offer_their_two_values() -> None:
    assert [s.text for s in suggestions("mvdirect ")] == ["0", "1"]


def test_nothing_after_the_last_argument_or_for_unknown_words() -> None:
    assert suggestions("th 270 25 ") == []
    assert suggestions("qd ") == []
    assert suggestions("nosuch ") == []


def test_hint_marks_the_argument_being_typed() -> None:
    hint = argument_hint("th 270")
    assert hint is not None
    assert hint.current == 0
    assert (
        hint.text() == "th [<direction_deg 0–360>] <power_percent 0–100>: "
        "degrees clockwise from the bow"
    )
    after = argument_hint("#th.270.")
    assert after is not None
    assert after.current == 1
    done = argument_hint("th 270 25 ")
    assert done is not None
    assert done.current is None
    assert argument_hint("") is None
    assert argument_hint("nosuch 5") is None


def test_prompt_toolkit_completer_passes_suggestions_through() -> None:
    document = Document("help mvp")
    completions = list(ConsoleCompleter().get_completions(document, CompleteEvent()))
    assert [c.text for c in completions] == ["mvpdp", "mvpdi", "mvpidd"]
    assert completions[0].start_position == -3
    assert completions[0].display_meta_text == "vertical (depth) PID proportional gain"


def test_on_the_second_line_of_a_paste_the_completer_looks_at_that_line_only() -> None:
    # Before, the words of the lines above counted: "start\nmvp" offered nothing (mvp was
    # taken for a value of start).
    completions = ConsoleCompleter().get_completions(Document("start\nmvp"), CompleteEvent())
    assert [completion.text for completion in completions] == ["mvpdp", "mvpdi", "mvpidd"]


def test_exit_is_completed_and_hinted_as_quit() -> None:
    # Before, "ex" completed to nothing and "exit" had no hint, though it is quit's other name.
    assert [suggestion.text for suggestion in suggestions("ex")] == ["exit"]
    assert "exit" not in [suggestion.text for suggestion in suggestions("")]  # (quit is there)
    hint = argument_hint("exit")
    assert hint is not None
    assert hint.text().startswith("quit: leave (sends #stop! first")
