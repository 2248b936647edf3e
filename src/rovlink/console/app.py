"""The prompt_toolkit console: a live prompt over :class:`~rovlink.console.engine.ConsoleEngine`.

The prompt never waits for the robot: a submitted line goes to the engine's queue and the next
prompt appears at once, replies print above it as they come. Ctrl-X is bound *eagerly* (it does
not wait to see whether a longer key sequence follows) to send ``#stop!`` without touching the
line being typed; the bottom toolbar says so, and shows the state as last sent, the link's health
and how to type the command at the cursor.
"""

from __future__ import annotations

import asyncio
import contextlib
import contextvars
import textwrap
from collections.abc import Awaitable, Callable, Iterable
from pathlib import Path

from prompt_toolkit import PromptSession
from prompt_toolkit.application import get_app_or_none
from prompt_toolkit.completion import CompleteEvent, Completer, Completion
from prompt_toolkit.document import Document
from prompt_toolkit.formatted_text import StyleAndTextTuples, fragment_list_width
from prompt_toolkit.history import FileHistory, History, InMemoryHistory
from prompt_toolkit.key_binding import KeyBindings, KeyPressEvent
from prompt_toolkit.output import DummyOutput
from prompt_toolkit.styles import Style
from prompt_toolkit.utils import get_cwidth, is_dumb_terminal
from prompt_toolkit.validation import ValidationError, Validator

from rovlink.aio import AsyncClient
from rovlink.client import ClientError
from rovlink.client.options import StrayCallback
from rovlink.console.above_prompt import output_is_plain_text, print_above_prompt
from rovlink.console.actions import InputError, Quit, parse_lines
from rovlink.console.completion import argument_hint, suggestions
from rovlink.console.engine import ConsoleEngine
from rovlink.console.help import STOP_KEY_TEXT
from rovlink.console.transcript import Line, error_line, info_line, is_notice, plain_text
from rovlink.logs import WarningsShownBy
from rovlink.piloting import LockState, TrackedClient
from rovlink.piloting.no_suspend import suspension_refused
from rovlink.piloting.tracked import LEAVING_REPLY_WAIT_S, STOP_UNSENT_NOTICE
from rovlink.protocol.visible import visible

__all__ = [
    "STYLE",
    "Connector",
    "ConsoleCompleter",
    "ConsoleValidator",
    "LinesFailedError",
    "RefusedLineError",
    "StopUnsentError",
    "run_console",
]

#: Opens the connection, given the callback for what the controller sends unasked.
Connector = Callable[[StrayCallback], Awaitable[AsyncClient]]

STYLE = Style.from_dict(
    {
        "prompt": "bold",
        "sent": "ansibrightblack",
        "reply": "ansigreen",
        "frame": "ansibrightblack",
        "alarm": "bold ansiwhite bg:ansired",
        "debug": "italic ansiyellow",
        "warning": "ansiyellow",
        "error": "bold ansired",
        "info": "",
        "notice": "",
        "stop": "bold ansiwhite bg:ansired",
        "bottom-toolbar": "noreverse bg:ansiblack ansiwhite",
        "toolbar.stop": "bold ansiwhite bg:ansired",
        "toolbar.locked": "ansigreen",
        "toolbar.unlocked": "bold ansiyellow",
        "toolbar.bad": "bold ansired",
        "toolbar.hint": "ansicyan",
    }
)

_TOOLBAR_REFRESH_S = 0.5

#: What the Ctrl-Z key does in the console.
NO_SUSPEND_TEXT = (
    "Ctrl-Z does not suspend the console (the robot would go on unattended): "
    f"{STOP_KEY_TEXT} stops it, Ctrl-D leaves"
)


class ConsoleCompleter(Completer):
    """Command names, console words, argument values and hints (see ``completion``)."""

    def get_completions(
        self, document: Document, complete_event: CompleteEvent
    ) -> Iterable[Completion]:
        """The suggestions for the text before the cursor, on its line (lines pasted at once
        are each a line of their own)."""
        for suggestion in suggestions(document.current_line_before_cursor):
            yield Completion(
                suggestion.text,
                start_position=suggestion.start,
                display=suggestion.display,
                display_meta=suggestion.meta,
            )


class ConsoleValidator(Validator):
    """Refuses a line that is not valid input, with the cursor on the culprit; ``checksum``
    gives the algorithm while checksum mode is on (frames typed with their checksum are taken).
    """

    def __init__(self, checksum: Callable[[], str | None] = lambda: None) -> None:
        self._checksum = checksum

    def validate(self, document: Document) -> None:
        """Raise ValidationError naming what is wrong, e.g. which argument and its range."""
        try:
            parse_lines(document.text, self._checksum())
        except InputError as error:
            raise ValidationError(cursor_position=error.position, message=error.message) from None


class StopUnsentError(Exception):
    """Leaving (``quit``, Ctrl-D, the end of a script's lines), unlocked as last sent, the
    ``#stop!`` could not be sent: the link was lost (the console has said so)."""


class LinesFailedError(Exception):
    """Lines read from a file or a pipe failed as they ran (a query with no reply, a lost
    link): each was said as it failed; the lines after it ran all the same."""


class RefusedLineError(Exception):
    """A line read from a file or a pipe was not valid input: the console left after the lines
    before it, without running it or those after it (``#stop!`` first unless locked)."""


class _EndedBySignal(Exception):  # noqa: N818 - a way of leaving, not an error
    """SIGINT from outside (``kill -INT``; SIGTERM and SIGHUP arrive as it): leave the console.
    The Ctrl-C key, read as a key in the terminal's raw mode, only drops the line typed."""


def _stop_bindings(engine: ConsoleEngine) -> KeyBindings:
    bindings = KeyBindings()

    # eager: fire on Ctrl-X itself, not after waiting for a possible Ctrl-X Ctrl-E.
    @bindings.add("c-x", eager=True)
    async def _stop(event: KeyPressEvent) -> None:
        await engine.stop_now()

    # (Over the prompt's own binding, which takes the signal for the Ctrl-C key.)
    @bindings.add("<sigint>")
    def _leave(event: KeyPressEvent) -> None:
        event.app.exit(exception=_EndedBySignal())

    # Not a suspend (a stopped console could not stop the robot), nor a character in the line.
    @bindings.add("c-z")
    def _no_suspend(event: KeyPressEvent) -> None:
        engine.say(NO_SUSPEND_TEXT)

    return bindings


def _toolbar(rov: TrackedClient, queued: int) -> StyleAndTextTuples:
    state = rov.commanded
    lock_style = {
        LockState.LOCKED: "class:toolbar.locked",
        LockState.UNLOCKED: "class:toolbar.unlocked",
    }.get(state.latest_lock, "")  # (the lock the controller announced, if it did)
    health = rov.health
    link = f"link {health.status}"
    if health.last_reply_s is not None:
        link += f", reply {health.last_reply_s * 1000:.0f} ms"
    link_style = (
        "class:toolbar.bad"
        if health.consecutive_failures or rov.client.closed or rov.link_down
        else ""
    )
    if rov.client.closed:
        link = "link lost"
    elif rov.link_down:
        link = "link lost, reopening it"
    checksum = f"checksum {rov.algorithm}" if rov.checksum_enabled else "checksum off"
    parts: list[StyleAndTextTuples] = [
        [("", "as last sent: "), (lock_style, state.short_lock_text())],
        [("", state.short_mode_text())],
        [("", checksum)],
        [(link_style, link)],
    ]
    if queued:
        parts.append([("class:toolbar.bad", f"{queued} line(s) waiting")])
    app = get_app_or_none()
    width = app.output.get_size().columns if app else _TOOLBAR_WIDTH
    # (On the cursor's line: lines pasted at once are each a line of their own.)
    hint = argument_hint(app.current_buffer.document.current_line_before_cursor) if app else None
    refused = app.current_buffer.validation_error if app else None
    help_line: StyleAndTextTuples = (
        [("", "Tab completes · 'help' lists commands · 'help th' shows one · Ctrl-D quits")]
        if hint is None
        else [("class:toolbar.hint", hint.text())]
    )
    if refused is not None and get_cwidth(refused.message) >= width:
        # Its own row (prompt_toolkit's, one row high) cuts it at the edge, and with it the
        # value refused: here it is wrapped (in a few rows: see _wrapped).
        help_line = [("class:toolbar.bad", refused.message)]
    # A part that would run past the edge goes on the next line: cut, the link's state (at the
    # end) was what went first, at 80 columns.
    status = _fitted([("class:toolbar.stop", f" {STOP_KEY_TEXT}: STOP ")], parts, width)
    return [*status, ("", "\n"), *_wrapped(help_line, width)]


#: Rows kept under the line for the completion menu, where the terminal has them.
_MENU_ROWS = 8


def _fit_menu(session: PromptSession[str], toolbar: StyleAndTextTuples) -> None:
    """Keep for the menu only the rows the line and the toolbar leave: in a short terminal (a
    split pane of 8 rows) the rows kept for it made the layout too high, and prompt_toolkit
    drew "Window too small..." in place of the line, the replies and the toolbar."""
    toolbar_rows = 1 + sum(fragment[1].count("\n") for fragment in toolbar)
    rows = session.app.output.get_size().rows
    session.reserve_space_for_menu = max(0, min(_MENU_ROWS, rows - toolbar_rows - 1))


#: The toolbar's width when no prompt is running to give the terminal's.
_TOOLBAR_WIDTH = 80


def _fitted(
    first: StyleAndTextTuples, parts: list[StyleAndTextTuples], width: int
) -> StyleAndTextTuples:
    """``first``, then ``parts`` separated by ``│`` (the first by ``,`` from the second),
    each part put on a new line where it would run past ``width``."""
    fragments: StyleAndTextTuples = list(first)
    used = fragment_list_width(fragments)
    for index, part in enumerate(parts):
        separator = " " if index == 0 else (", " if index == 1 else " │ ")
        part_width = fragment_list_width(part)
        if used + len(separator) + part_width >= width:
            fragments.append(("", "\n"))
            separator, used = " ", 0
        fragments.append(("", separator))
        fragments.extend(part)
        used += len(separator) + part_width
    return fragments


def _wrapped(line: StyleAndTextTuples, width: int) -> StyleAndTextTuples:
    """``line`` (one style) broken between words to lines of less than ``width`` columns, at
    most ``_TOOLBAR_HELP_ROWS`` of them (a refused value may be thousands of digits long)."""
    style = line[0][0]
    text = "".join(text for _, text, *_ in line)
    lines = textwrap.wrap(
        text, max(width - 2, 10), max_lines=_TOOLBAR_HELP_ROWS, placeholder=" …"
    ) or [""]
    return [(style, " " + "\n ".join(lines))]


#: The most rows the toolbar's second part (the hint, or a refused line's message) takes.
_TOOLBAR_HELP_ROWS = 3


def _print(line: Line) -> None:
    print_above_prompt(line, STYLE)


async def run_console(
    connect: Connector,
    *,
    algorithm: str = "crc8",
    history_path: Path | None = None,
    emit: Callable[[Line], None] = _print,
    from_terminal: bool = True,
    notices: Callable[[str], None] | None = None,
) -> None:
    """Connect and run the console until ``quit`` or Ctrl-D; the client is closed on the way out.

    ``history_path`` keeps the lines typed between sessions (``None``: this session only);
    lines read from a file or a pipe are not kept.
    ``from_terminal``: the lines are typed at a terminal, where ``quit`` and Ctrl-D leave at
    once; ``False`` (lines read from a file or a pipe), they run in order, each to its end, and
    when the output is not a terminal either (a file, a pipe) it is their replies alone: no
    prompt, no line echoed, and the console's own notice (what it is connected to) goes to
    ``notices`` if given.
    Raises what ``connect`` raises if the connection cannot be opened,
    :class:`RefusedLineError` for a bad line read from a file or a pipe, and
    :class:`StopUnsentError` when leaving found the link lost, the motors not locked as last
    sent: the ``#stop!`` never went, and :class:`LinesFailedError` when lines read from a file
    or a pipe failed as they ran.
    """
    # The driver calls back (debug text, stray frames) in a context copied from its reader
    # thread, which knows nothing of this prompt; print in the console's own context, so that
    # lines go above the prompt of this app session.
    console_context = contextvars.copy_context()
    # To a file or a pipe, the output of a script's lines is what was sent and what came
    # back; the console's own remarks (leaving, a warning, an error) go to ``notices``.
    replies_alone = not from_terminal and output_is_plain_text()
    notices_apart = notices if replies_alone else None

    def emit_in_console(line: Line) -> None:
        if notices_apart is not None and is_notice(line):
            notices_apart(plain_text(line).strip())
        else:
            console_context.run(emit, line)

    # Written to stderr, the library's warnings (a lost link, a suspected reset) would land in
    # the middle of the prompt: they are printed above it as the console's own lines.
    def show_warning(message: str, level: int) -> None:
        emit_in_console(info_line(f"  ! {visible(message)}", "class:warning"))

    warnings = WarningsShownBy(show_warning)
    warnings.attach()
    engine = ConsoleEngine(emit_in_console)
    try:
        # Ctrl-Z is a key while a prompt reads them; between prompts (the terminal in cooked mode
        # for a moment), or while a script's lines run, it is a signal: said as the key is.
        with suspension_refused(lambda: engine.say(NO_SUSPEND_TEXT)):
            await _run_connected(
                connect,
                engine,
                emit_in_console,
                algorithm=algorithm,
                history_path=history_path,
                from_terminal=from_terminal,
                notices=notices_apart,
            )
    finally:
        warnings.detach()


async def _run_connected(
    connect: Connector,
    engine: ConsoleEngine,
    emit_in_console: Callable[[Line], None],
    *,
    algorithm: str,
    history_path: Path | None,
    from_terminal: bool,
    notices: Callable[[str], None] | None,
) -> None:
    client = await connect(engine.on_event)
    rov = TrackedClient(client, algorithm=algorithm)
    engine.attach(rov)

    def checksum() -> str | None:  # (a frame typed with its checksum is taken in that mode)
        return rov.algorithm if rov.checksum_enabled else None

    # A line is refused in place, the cursor on the culprit, where the operator can mend it: not
    # in lines read from a file (the next lines would be typed into the refused one), nor on a
    # dumb terminal (which cannot show the message under the line).
    check_in_place = from_terminal and not is_dumb_terminal()
    history: History = InMemoryHistory()
    if history_path is not None and from_terminal:  # (a script's lines are not lines typed)
        history_path.parent.mkdir(parents=True, exist_ok=True)
        history = FileHistory(str(history_path))
    # Lines read from a file: nobody types, so no menus, and no toolbar (drawn again and again
    # into the transcript) with a stop key that no key reaches; Ctrl-C is a signal then. Nor,
    # to a file or a pipe, a prompt: drawn as plain text it is the line echoed after
    # "rovlink> " and the blank lines of the rows it moves through.
    replies_alone = not from_terminal and output_is_plain_text()  # (as run_console says)
    session: PromptSession[str] = PromptSession(
        [("class:prompt", "rovlink> ")],
        style=STYLE,
        history=history,
        completer=ConsoleCompleter() if from_terminal else None,
        complete_while_typing=from_terminal,
        reserve_space_for_menu=_MENU_ROWS if from_terminal else 0,
        validator=ConsoleValidator(checksum) if check_in_place else None,
        validate_while_typing=False,
        key_bindings=_stop_bindings(engine),
        bottom_toolbar=(lambda: _toolbar(rov, engine.queued)) if from_terminal else None,
        refresh_interval=_TOOLBAR_REFRESH_S if from_terminal else 0,
        output=DummyOutput() if replies_alone else None,
    )
    if from_terminal:
        session.app.before_render += lambda app: _fit_menu(session, _toolbar(rov, engine.queued))
    stop_text = (
        f"{STOP_KEY_TEXT} sends #stop! at any time; 'help' lists commands"
        if from_terminal
        else "its lines run in order; Ctrl-C sends #stop! and ends the console"
    )
    connected = f"connected to {client.description}; {stop_text}"
    if notices is not None:
        notices(connected)
    else:
        emit_in_console(info_line(connected, "class:info"))
    runner = asyncio.create_task(engine.run())
    refused: RefusedLineError | None = None
    lines_read = 0
    try:
        while not runner.done():
            try:
                text = await session.prompt_async()
            except EOFError:  # Ctrl-D, or the end of the lines read from a file
                if from_terminal:
                    await engine.leave()
                else:
                    engine.submit(Quit())
                break
            except KeyboardInterrupt:  # the Ctrl-C key: drop the line, as in a shell...
                engine.interrupt()  # ...and the line running and those queued
                continue
            except _EndedBySignal:
                raise KeyboardInterrupt from None  # (after the finally: #stop!, then closed)
            first_line = lines_read + 1
            lines_read += text.count("\n") + 1
            # (Lines pasted at once arrive as one text: each runs as if typed on its own.)
            try:
                actions = parse_lines(text, checksum())
            except InputError as error:  # (not checked in place)
                if from_terminal:
                    emit_in_console(error_line(error.message))
                    continue
                refused = RefusedLineError(
                    f"line {first_line}: {error.message} (the lines after it were not run)"
                )
                actions = [Quit()]
            for action in actions:
                if isinstance(action, Quit):
                    break
                engine.submit(action)
            if any(isinstance(action, Quit) for action in actions):
                if from_terminal:
                    # At once, not behind the lines queued: a query waiting out a long
                    # timeout would keep the robot moving, and the console open, until it ended.
                    await engine.leave()
                else:
                    engine.submit(Quit())
                break
        if from_terminal:
            # #stop! has gone: the line running (a query waiting for its reply) gets a moment
            # to end, not the whole reply timeout of a controller that does not answer.
            await asyncio.wait({runner}, timeout=LEAVING_REPLY_WAIT_S)
        else:
            await asyncio.wait({runner})  # (a script's lines run to their end)
        if runner.done():
            runner.result()  # (an error of the engine's own is raised)
    finally:
        if not runner.done():
            runner.cancel()
        # Ended by a signal or an error with the link down: said once the rest is done (the
        # terminal may be the one that hung up).
        unsent = not engine.left and _stop_wanted(rov) and rov.link_down
        await _stop_unless_locked(rov)
        await rov.close()
        if unsent:
            engine.say_stop_unsent()
    if refused is not None:
        raise refused
    if engine.stop_unsent:
        raise StopUnsentError(STOP_UNSENT_NOTICE)
    if not from_terminal and engine.failed_lines:
        raise LinesFailedError(
            f"{engine.failed_lines} line(s) failed as they ran (each said above)"
        )


#: How long leaving may wait for ``#stop!`` to be written (it is not acknowledged).
_STOP_WRITE_TIMEOUT_S = 1.0


async def _stop_unless_locked(rov: TrackedClient) -> None:
    """``#stop!`` on the way out unless the motors are locked as last sent: leaving by
    ``quit`` has sent it already; leaving by Ctrl-C (SIGINT) or an error has not."""
    if not _stop_wanted(rov):
        return
    with contextlib.suppress(ClientError, TimeoutError, ConnectionError):
        await asyncio.wait_for(rov.stop(), _STOP_WRITE_TIMEOUT_S)


def _stop_wanted(rov: TrackedClient) -> bool:
    """Whether leaving sends ``#stop!``: the link is open and not locked as last sent."""
    return not rov.client.closed and rov.commanded.sent_lock is not LockState.LOCKED
