"""Printing above the live prompt with the terminal left in raw mode.

prompt_toolkit's own way (``print_formatted_text`` while an application runs, through
``run_in_terminal``) puts the terminal back in cooked mode for each line it prints. A key typed
in that moment is the terminal's, not the console's: Ctrl-Z suspends the console (with the robot
moving), Ctrl-C and Ctrl-\\ are signals, Ctrl-D is lost and typed letters are echoed in the
middle of the output. Replies and debug lines stream in while the operator types, so that moment
comes often. Here the prompt is erased, the line printed and the prompt drawn again, all on the
prompt's event loop, while the prompt goes on reading its keys in raw mode.

To an output that is not a terminal (a file, a pipe: prompt_toolkit's plain text output) a line
is its text and a line end, ``\n``: not the ``\r\n`` a terminal is given.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from prompt_toolkit.application import Application, get_app_or_none, get_app_session
from prompt_toolkit.formatted_text import FormattedText
from prompt_toolkit.output import Output
from prompt_toolkit.output.plain_text import PlainTextOutput
from prompt_toolkit.renderer import print_formatted_text as render_text
from prompt_toolkit.styles import BaseStyle

__all__ = ["output_is_plain_text", "print_above_prompt"]


def output_is_plain_text() -> bool:
    """Whether the console's output is not a terminal (a file, a pipe): plain text, no prompt."""
    return isinstance(get_app_session().output, PlainTextOutput)


def print_above_prompt(fragments: Sequence[tuple[str, str]], style: BaseStyle) -> None:
    """Print ``fragments`` and a line end: above the prompt while one runs (from any thread),
    else where the cursor is."""
    output = get_app_session().output
    app = get_app_or_none()
    loop = app.loop if app is not None else None
    if app is None or loop is None:
        _print(output, fragments, style)
        return
    loop.call_soon_threadsafe(_print_above, app, output, fragments, style)


def _print_above(
    app: Application[Any], output: Output, fragments: Sequence[tuple[str, str]], style: BaseStyle
) -> None:
    if not app.is_running:  # (ended since: the prompt is gone from the screen)
        _print(output, fragments, style)
        return
    renderer = app.renderer
    renderer.erase(leave_alternate_screen=False)  # (the cursor to where the prompt began)
    _print(output, fragments, style)
    # Where the prompt now begins, so that its menus know the rows below it.
    renderer.request_absolute_cursor_position()
    app.invalidate()


def _print(output: Output, fragments: Sequence[tuple[str, str]], style: BaseStyle) -> None:
    if isinstance(output, PlainTextOutput):  # (its text alone, and "\n" as a file's lines end)
        output.write("".join(text for _, text, *_ in fragments) + "\n")
    else:
        render_text(output, FormattedText([*fragments, ("", "\n")]), style)
    output.flush()
