"""Ctrl-C ends a command at once, after ``#stop!`` where the robot may have moved.

A KeyboardInterrupt raised in the middle of the driver's code (between taking a lock and
releasing it) could leave the driver unable to send anything, ``#stop!`` included. So a command
that drives the robot runs its work in a worker thread (:func:`run_in_worker`) while the main
thread only waits, where Ctrl-C lands harmlessly; the work talks to the robot through a
:class:`GatedClient`, which the main thread shuts (:meth:`GatedClient.stop_for_good`) so that
``#stop!`` is the last frame the command sends.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Callable
from types import FrameType
from typing import TYPE_CHECKING, Any, TextIO, TypeVar

from rovlink.protocol import Setting

if TYPE_CHECKING:
    from rovlink.protocol import Command

__all__ = [
    "GatedClient",
    "Interrupted",
    "ServingSignals",
    "may_move",
    "run_in_worker",
    "say_last",
    "say_ready",
    "say_stopped",
    "send_stop",
    "suspension_refused_by",
]

T = TypeVar("T")

#: How long the main thread waits for a call in progress to finish before it sends ``#stop!``.
#: A command that moves the robot is only written, never waits so long; a call that takes
#: longer is a query waiting for its reply, which moves nothing.
_CALL_IN_PROGRESS_WAIT_S = 0.2


def may_move(command: Command) -> bool:
    """Whether the robot may move after ``command`` (so a command that sent it ends with
    ``#stop!``): a motion command, or ``start``.

    >>> from rovlink.protocol import Command
    >>> may_move(Command("start")), may_move(Command("th", (90, 30))), may_move(Command("qd"))
    (True, True, False)
    """
    setting = command.setting
    return command.spec.motion or setting == (Setting.LOCKED, False)


class Interrupted(Exception):  # noqa: N818 - a state, not an error
    """The command was interrupted; its worker stops at its next call to the robot."""


class GatedClient:
    """A client whose calls stop for good after :meth:`stop_for_good` (they raise
    :class:`Interrupted`); attributes that are not methods pass through."""

    def __init__(self, client: Any) -> None:
        self._client = client
        self._lock = threading.Lock()  # held by a call in progress
        self._shut = False

    def __getattr__(self, name: str) -> Any:
        attribute = getattr(self._client, name)
        if not callable(attribute):
            return attribute

        def call(*args: Any, **kwargs: Any) -> Any:
            with self._lock:
                if self._shut:
                    raise Interrupted
                return attribute(*args, **kwargs)

        return call

    def stop_for_good(self) -> str:
        """Shut the gate and send ``#stop!``; no call through the gate sends anything after it.
        What became of the ``#stop!``, as :func:`send_stop` says it.

        Called from the main thread: a call in progress either finishes within a moment (a
        command, only written) or is a query (which moves nothing) still waiting.
        """
        self._shut = True
        taken = self._lock.acquire(timeout=_CALL_IN_PROGRESS_WAIT_S)
        try:
            return send_stop(self._client)
        finally:
            if taken:
                self._lock.release()


def send_stop(client: Any) -> str:
    """Send ``#stop!`` to end a command that may have set the robot moving (interrupted,
    failed, its output closed); what became of it, for the command's line on stderr:
    ``sent #stop!`` or ``could not send #stop!: <why>`` (a link that is gone: the controller's
    link-loss watchdog stops the robot then)."""
    from rovlink.client.errors import ClientError  # noqa: PLC0415 - the driver loads when used

    try:
        client.stop()
    except (ClientError, ConnectionError, TimeoutError) as error:
        return f"could not send #stop!: {error}"
    return "sent #stop!"


def suspension_refused_by(program: str) -> contextlib.AbstractContextManager[None]:
    """While in effect, SIGTSTP (Ctrl-Z, ``kill -TSTP``) does not suspend ``program``, a command
    that drives the robot: suspended, it could not stop it, and what it last sent would go on
    unattended (until the controller's watchdog, if it has one). Said on stderr instead."""
    from rovlink.piloting.no_suspend import suspension_refused  # noqa: PLC0415 - asyncio

    def say() -> None:
        # OSError: a terminal that hung up; RuntimeError: said from the signal handler while
        # the same thread was writing to stderr ("reentrant call"): the line is lost, and the
        # command goes on rather than ending mid-motion.
        with contextlib.suppress(OSError, RuntimeError):
            print(
                f"{program}: Ctrl-Z does not suspend it (the robot would go on unattended): "
                "Ctrl-C stops the robot and ends it",
                file=sys.stderr,
            )

    return suspension_refused(say)


def say_stopped(program: str, outcome: str, why: str = "") -> None:
    """``rovlink send: sent #stop!`` (with `` (why)``) on stderr, which may be closed too."""
    say_last(f"{program}: {outcome}{f' ({why})' if why else ''}")


def say_last(line: str) -> None:
    """``line`` on stderr as a command ends, if it can still be written: a closed terminal
    (SIGHUP) fails every write, and that error must not become the command's status (a
    serving command stopped so ends with 0, a driving one with 130, as documented)."""
    with contextlib.suppress(OSError):
        _write_line(sys.stderr, line)


def say_ready(line: str, *, stream: TextIO | None = None) -> None:
    """A serving command's ready line (``rovlink sim ready: …; Ctrl-C stops``), on standard
    output unless ``stream`` says otherwise, written whole at once.

    ``print`` writes a line and its end with two system calls on a terminal: one who closed the
    window as soon as the line showed made the second fail, and a service stopped by that
    (SIGHUP, status 0) ended with the write's error (status 1) instead."""
    _write_line(sys.stdout if stream is None else stream, line)


def _write_line(stream: TextIO, line: str) -> None:
    """``line`` and its end in one write, flushed."""
    stream.write(f"{line}\n")
    stream.flush()


def run_in_worker(work: Callable[[], T]) -> T:
    """``work()`` in a daemon thread; its result or exception, or KeyboardInterrupt at once
    when Ctrl-C comes (the worker is left behind: the process is ending)."""
    outcome: list[T] = []
    failure: list[BaseException] = []

    def target() -> None:
        try:
            outcome.append(work())
        except BaseException as error:  # re-raised in the main thread
            failure.append(error)

    worker = threading.Thread(target=target, name="rovlink command", daemon=True)
    worker.start()
    while worker.is_alive():
        worker.join(0.1)  # Ctrl-C interrupts the wait here, never the work
    if failure:
        raise failure[0]
    return outcome[0]


#: The signals a terminal's keys send (Ctrl-C, Ctrl-\\): a serving command they end says
#: "interrupted" (130), where a service manager's SIGTERM or a closed terminal's SIGHUP is a
#: clean stop (0), said ``PROGRAM stopped``.
_KEYS_OF_A_TERMINAL = frozenset(
    getattr(signal, name) for name in ("SIGINT", "SIGQUIT") if hasattr(signal, name)
)


class ServingSignals:
    """How a serving command (``sim``, ``controller``, ``record``, ``fault``) is ended: Ctrl-C,
    SIGTERM, SIGHUP and SIGQUIT set :attr:`stopping`, and its loop ends cleanly (a file
    finished, a ``#stop!`` sent). Then :meth:`finish` raises KeyboardInterrupt if it was Ctrl-C
    or Ctrl-\\ (SIGQUIT), so that the status is 130 as for every command; SIGTERM and SIGHUP,
    a service manager's way of stopping a service, end it with its own status (0). One line
    says which: ``rovlink sim: interrupted`` (the command line's, as for every command) or
    ``rovlink sim stopped`` (:meth:`say_stopped`). A signal ignored on entry (``nohup``, SIGINT
    in a background job) stays ignored.

    Example::

        signals = ServingSignals()
        try:
            server.serve(signals.stopping.is_set)
        finally:
            signals.restore()
        signals.say_stopped("rovlink sim")
        signals.finish()
    """

    def __init__(self) -> None:
        self.stopping = threading.Event()
        #: Whether Ctrl-C (SIGINT) or Ctrl-\\ (SIGQUIT) ended the command.
        self.interrupted = False
        #: Whether any of the signals came (the command may also end by itself: ``--duration``).
        self.signalled = False
        self._previous: dict[int, Any] = {}
        for name in ("SIGINT", "SIGTERM", "SIGHUP", "SIGQUIT"):
            number = getattr(signal, name, None)  # (no SIGHUP, SIGQUIT on Windows)
            if number is None or signal.getsignal(number) is signal.SIG_IGN:
                continue
            self._previous[number] = signal.signal(number, self._handle)

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        # (Any Ctrl-C counts, also one after another signal, as the web station's server does.)
        if signum in _KEYS_OF_A_TERMINAL:
            self.interrupted = True
        self.signalled = True
        self.stopping.set()

    @property
    def stopped_as_a_service(self) -> bool:
        """Whether SIGTERM or SIGHUP (and no Ctrl-C) ended the command: status 0."""
        return self.signalled and not self.interrupted

    def say_stopped(self, program: str, detail: str = "") -> None:
        """``PROGRAM stopped`` (with ``: DETAIL``) on stderr if SIGTERM or SIGHUP ended the
        command. After Ctrl-C, only ``PROGRAM: DETAIL`` if there is a detail: :meth:`finish`
        makes the end the command line's ``PROGRAM: interrupted``, which a ``stopped`` line
        before it contradicted."""
        if self.stopped_as_a_service:
            say_last(f"{program} stopped{f': {detail}' if detail else ''}")
        elif detail:
            say_last(f"{program}: {detail}")

    def restore(self) -> None:
        """Put the handlers before back."""
        for number, handler in self._previous.items():
            signal.signal(number, handler)
        self._previous.clear()

    def finish(self) -> None:
        """Restore the handlers; KeyboardInterrupt (status 130) if Ctrl-C ended the command."""
        self.restore()
        if self.interrupted:
            raise KeyboardInterrupt
