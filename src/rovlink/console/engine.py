"""The console's engine: runs what the operator typed, in order, and says what happened.

Lines are queued and run one after another (a query waits for its replies before the next line
goes out), while the prompt stays live. :meth:`ConsoleEngine.stop_now` jumps the queue: it sends
``#stop!`` at once and drops whatever was typed before it but not sent yet; so does
:meth:`ConsoleEngine.leave` (``quit``, Ctrl-D), unless the motors are locked as last sent, and
the engine ends once the line running is done. :meth:`ConsoleEngine.interrupt` (Ctrl-C)
abandons the line running and drops those queued, sending nothing. Everything the engine has to
say goes to ``emit`` as :data:`~rovlink.console.transcript.Line` values.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable

from rovlink.client import ClientError
from rovlink.client.events import ClientEvent, LateReply, LinkState
from rovlink.console.actions import (
    Action,
    Quit,
    SendCommand,
    SendRaw,
    SetChecksum,
    ShowHelp,
    ShowStatus,
)
from rovlink.console.help import STOP_KEY_TEXT, command_help, overview
from rovlink.console.transcript import (
    Line,
    error_line,
    event_line,
    info_line,
    late_reply_line,
    notice_line,
    reply_line,
    sent_lines,
)
from rovlink.logs import get_logger
from rovlink.piloting import LockState, SentFrame, TrackedClient
from rovlink.piloting.tracked import REOPENED_NOTICE, STOP_KEPT_NOTICE, STOP_UNSENT_NOTICE
from rovlink.protocol import Event, Response, Setting, setting_command

__all__ = ["ConsoleEngine", "status_lines"]

logger = get_logger("rovlink.console")

Emit = Callable[[Line], None]


def status_lines(rov: TrackedClient) -> list[str]:
    """The state as last sent and the link's figures, for ``status``."""
    state = rov.commanded
    health = rov.health
    counters = rov.client.counters
    reply = "—" if health.last_reply_s is None else f"{health.last_reply_s * 1000:.1f} ms"
    mode = f"on ({rov.algorithm})" if rov.checksum_enabled else "off"
    link = health.status  # (as the toolbar says)
    if rov.client.closed:
        link = "link lost"
    elif rov.link_down:
        link = "link lost, reopening it"
    return [
        f"motors:     {state.lock_text()}",
        f"vertical:   {state.mode_text()}",
        f"horizontal: {state.horizontal_text()}",
        f"checksum:   {mode}",
        f"link:       {rov.client.description}, {link}, last reply {reply}",
        f"            {counters.frames_sent} frames sent, {counters.replies} replies, "
        f"{counters.timeouts} timeouts, {counters.retries} retries, "
        f"{counters.checksum_errors} checksum errors",
    ]


class ConsoleEngine:
    """Runs console actions on a :class:`~rovlink.piloting.TrackedClient`, in order.

    Make it first (its :meth:`on_event` is the client's ``on_stray``), then :meth:`attach` the
    client, then run :meth:`run` while the prompt :meth:`submit`s lines.
    """

    def __init__(self, emit: Emit) -> None:
        self._emit = emit
        self._rov: TrackedClient | None = None
        self._queue: asyncio.Queue[Action] = asyncio.Queue()
        self._left = False
        self._stop_unsent = False
        #: Lines that failed (no reply, a lost link, a frame refused by the driver).
        self.failed_lines = 0
        self._running: asyncio.Future[None] | None = None
        #: Set by :meth:`interrupt` while it cancels the line running: what else it dropped.
        self._interrupted: str | None = None
        self.finished = asyncio.Event()

    def attach(self, rov: TrackedClient) -> None:
        """Drive ``rov``; every frame sent through it is shown."""
        self._rov = rov
        rov.add_sent_listener(self._on_sent)
        rov.client.subscribe(self._on_client_event)

    @property
    def rov(self) -> TrackedClient:
        """The client being driven."""
        if self._rov is None:
            raise RuntimeError("no client attached")
        return self._rov

    # -- from the prompt and the driver ---------------------------------------------------------

    @property
    def queued(self) -> int:
        """Lines waiting behind the one running."""
        return self._queue.qsize()

    def submit(self, action: Action) -> None:
        """Queue an action behind those already waiting."""
        self._queue.put_nowait(action)

    def say(self, text: str) -> None:
        """Show a message of the console's own."""
        self._emit(info_line(text, "class:warning"))

    def on_event(self, event: Event) -> None:
        """Show what came from the controller unasked: debug text, dropped or stray frames."""
        self._emit(event_line(event))

    async def stop_now(self) -> None:
        """``#stop!`` at once, dropping the lines queued and not yet sent (keeps a ``quit``)."""
        dropped = self._drop_queued()
        note = f"; {dropped} queued line(s) dropped" if dropped else ""
        self._emit(info_line(f"■ STOP ({STOP_KEY_TEXT}){note}", "class:stop"))
        try:
            await self.rov.stop()
        except ClientError as error:
            self._emit(error_line(f"#stop! could not be sent: {error}"))
            return
        if self.rov.link_down and not self.rov.client.closed:  # (kept: no "→ #stop!" yet)
            self._emit(info_line(f"  ! {STOP_KEPT_NOTICE}", "class:error"))

    async def leave(self) -> None:
        """Leave now (``quit``, Ctrl-D): the lines queued and not yet sent are dropped, and
        ``#stop!`` goes at once unless the motors are locked as last sent, not after a query
        still waiting for its reply; :meth:`run` ends once the line running is done."""
        dropped = self._drop_queued()
        if dropped:
            self._emit(notice_line(f"leaving: {dropped} queued line(s) dropped, not sent"))
        self._queue.put_nowait(Quit())
        await self._quit()

    @property
    def left(self) -> bool:
        """Whether ``quit`` (or Ctrl-D) has been run: its ``#stop!`` has been seen to."""
        return self._left

    @property
    def stop_unsent(self) -> bool:
        """Whether leaving, unlocked, found the ``#stop!`` could not go (the link lost)."""
        return self._stop_unsent

    def say_stop_unsent(self) -> None:
        """Leaving, unlocked, with the link down: the ``#stop!`` cannot go, said so."""
        self._stop_unsent = True
        self._emit(error_line(STOP_UNSENT_NOTICE))

    def _drop_queued(self) -> int:
        """Empty the queue but for a ``quit``; how many lines were dropped."""
        dropped = 0
        keep: list[Action] = []
        while not self._queue.empty():
            action = self._queue.get_nowait()
            if isinstance(action, Quit):
                keep.append(action)
            else:
                dropped += 1
        for action in keep:
            self._queue.put_nowait(action)
        return dropped

    # -- running --------------------------------------------------------------------------------

    async def run(self) -> None:
        """Run queued actions until a :class:`Quit`."""
        try:
            while True:
                action = await self._queue.get()
                if isinstance(action, Quit):
                    await self._quit()
                    return
                self._running = asyncio.ensure_future(self.execute(action))
                try:
                    await self._running
                except asyncio.CancelledError:
                    if self._interrupted is None:
                        raise  # (run() itself was cancelled)
                    self._interrupted = None
                finally:
                    self._running = None
        finally:
            self.finished.set()

    def interrupt(self) -> None:
        """Ctrl-C: abandon the line running (a query waiting for its reply is not waited for)
        and drop the lines queued; nothing is sent. Nothing to do if no line is running."""
        dropped = self._drop_queued()
        running = self._running
        if running is None or running.done():
            if dropped:
                self._emit(notice_line(f"  ^C: {dropped} queued line(s) dropped, not sent"))
            return
        note = f"; {dropped} queued line(s) dropped, not sent" if dropped else ""
        self._interrupted = note
        running.cancel()

    async def execute(self, action: Action) -> None:
        """Run one action now and show its outcome; link errors are shown, not raised."""
        try:
            await self._execute(action)
        except asyncio.CancelledError:
            note = self._interrupted
            if note is not None:
                self._emit(
                    info_line(f"  ^C: {_action_text(action)} abandoned{note}", "class:warning")
                )
            raise

    async def _execute(self, action: Action) -> None:
        try:
            if isinstance(action, SendCommand):
                self._show_replies(await self.rov.send(action.command))
            elif isinstance(action, SendRaw):
                try:
                    replies = await self.rov.send_raw(action.frame)
                except ValueError as error:  # (more than one frame: nothing was sent)
                    self.failed_lines += 1
                    self._emit(error_line(str(error)))
                    return
                self._show_replies(replies)
            elif isinstance(action, SetChecksum):
                await self.rov.send(setting_command(Setting.CHECKSUM, action.enabled))
                self._emit(info_line(self._checksum_text(), "class:info"))
            elif isinstance(action, ShowHelp):
                lines = overview() if action.name is None else command_help(action.name)
                for line in lines:
                    self._emit(info_line(line))
            elif isinstance(action, ShowStatus):
                for line in status_lines(self.rov):
                    self._emit(info_line(line))
        except (ClientError, TimeoutError, ConnectionError) as error:
            self.failed_lines += 1
            self._emit(error_line(str(error)))

    async def _quit(self) -> None:
        if self._left:  # (leave() has sent it: a quit queued behind it only ends run())
            return
        self._left = True
        state = self.rov.commanded
        if self.rov.client.closed or state.sent_lock is LockState.LOCKED:
            return
        if self.rov.link_down:  # (kept for a link that will not be reopened now)
            self.say_stop_unsent()
        else:
            self._emit(notice_line(f"leaving: sending #stop! (motors {state.lock_text()})"))
        try:
            await self.rov.stop()
        except ClientError as error:
            self._stop_unsent = True
            self._emit(error_line(f"#stop! could not be sent: {error}"))

    # -- output ---------------------------------------------------------------------------------

    def _on_client_event(self, event: ClientEvent) -> None:
        # A reply after its query timed out (the driver drops it): the link is slow, not dead.
        # Not one to a keep-alive or a fence of the driver's own: nobody typed those (the
        # link's counters have it).
        if isinstance(event, LateReply):
            if event.by_session:
                return
            algorithm = self.rov.algorithm if self.rov.checksum_enabled else None
            self._emit(late_reply_line(event.response, algorithm))
        elif isinstance(event, LinkState) and event.state == "reconnected":
            self._emit(info_line(f"  ! {REOPENED_NOTICE}", "class:warning"))

    def _on_sent(self, sent: SentFrame) -> None:
        for line in sent_lines(sent):
            self._emit(line)

    def _show_replies(self, replies: tuple[Response, ...]) -> None:
        algorithm = self.rov.algorithm if self.rov.checksum_enabled else None
        for reply in replies:
            self._emit(reply_line(reply, algorithm))

    def _checksum_text(self) -> str:
        if self.rov.checksum_enabled:
            return f"  checksum mode on: every frame now carries a {self.rov.algorithm} checksum"
        return "  checksum mode off"


def _action_text(action: Action) -> str:
    """The line running, in a few words: ``#qd!``, ``raw #qd!``, ``checksum on``."""
    if isinstance(action, SendCommand):
        return str(action.command)
    if isinstance(action, SendRaw):
        return f"raw {action.frame}"
    if isinstance(action, SetChecksum):
        return f"checksum {'on' if action.enabled else 'off'}"
    return "the line running"
