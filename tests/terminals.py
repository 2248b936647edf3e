"""Terminals as another program sees them, and commands run on a pseudo-terminal of their own."""

from __future__ import annotations

import contextlib
import fcntl
import os
import select
import struct
import subprocess
import sys
import termios
import threading
from collections.abc import Callable
from pathlib import Path

#: How long a test waits for a command to show something or to end.
WAIT_S = 15.0


def open_as_another_user(device: str) -> str:
    """Open ``device`` from a shell of another user (nobody, when the tests run as root, since
    root passes a terminal's exclusive mode); what the shell said: "opened", or its error."""
    command = ["/bin/sh", "-c", 'exec 3<>"$0" && echo opened', device]
    user = 65534 if os.geteuid() == 0 else None
    result = subprocess.run(
        command, capture_output=True, text=True, timeout=30, check=False, user=user
    )
    return result.stdout + result.stderr


def _own_terminal() -> None:
    """In the child: a session of its own with the pseudo-terminal (its standard input) as its
    controlling terminal, as a login shell has, so that closing the terminal hangs it up."""
    os.setsid()
    fcntl.ioctl(0, termios.TIOCSCTTY, 0)


class Terminal:
    """A ``rovlink`` command on a pseudo-terminal of its own, as a user runs it; what it shows
    is drained (a full terminal would block it) and kept. :meth:`hang_up` closes the terminal,
    as closing its window does: the command gets SIGHUP and its terminal fails every write.
    ``term``: the terminal's type (``TERM``); ``env``: more environment variables; ``size``:
    columns and rows; ``job_control``: the command is a job of a shell with job control (its
    own process group, in the foreground, that a SIGTSTP can stop: the kernel discards one sent
    to the process group of a session's leader, which has no shell to continue it); ``script``:
    a Python program to run in place of ``rovlink``, with the arguments."""

    def __init__(
        self,
        *arguments: str,
        stderr_on_terminal: bool = False,
        term: str = "xterm-256color",
        env: dict[str, str] | None = None,
        size: tuple[int, int] = (80, 24),
        job_control: bool = False,
        script: Path | None = None,
    ) -> None:
        self._master, slave = os.openpty()
        columns, rows = size
        fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", rows, columns, 0, 0))
        source = str(Path(__file__).resolve().parents[1] / "src")
        environment = {**os.environ, "PYTHONPATH": source, "TERM": term, **(env or {})}
        environment.pop("NO_COLOR", None)
        program = [str(script)] if script is not None else ["-m", "rovlink"]
        command = [sys.executable, *program, *arguments]
        if job_control:  # (the shell says how the job ended: 148 if SIGTSTP stopped it)
            shell = 'set -m; "$@"; status=$?; echo "[job ended: $status]"; exit $status'
            command = ["bash", "--norc", "--noprofile", "-i", "-c", shell, "bash", *command]
        self.process = subprocess.Popen(
            command,
            stdin=slave,
            stdout=slave,
            stderr=slave if stderr_on_terminal else subprocess.PIPE,
            env=environment,
            preexec_fn=_own_terminal,  # noqa: PLW1509 - no threads yet
        )
        os.close(slave)
        self.shown = bytearray()
        self._changed = threading.Condition()
        self._wake_r, self._wake_w = os.pipe()
        self._reader = threading.Thread(target=self._drain, daemon=True)
        self._reader.start()

    def _drain(self) -> None:
        with contextlib.suppress(OSError):
            while True:
                ready, _, _ = select.select([self._master, self._wake_r], [], [])
                if self._wake_r in ready:
                    return
                data = os.read(self._master, 4096)
                if not data:
                    return
                with self._changed:
                    self.shown += data
                    self._changed.notify_all()

    def wait_shown(self, text: bytes, timeout_s: float = WAIT_S) -> bool:
        """Whether ``text`` appeared on the terminal within ``timeout_s``."""
        return self.wait_until(lambda shown: text in shown, timeout_s)

    def wait_until(self, holds: Callable[[bytes], bool], timeout_s: float = WAIT_S) -> bool:
        """Whether what the terminal was sent made ``holds`` true within ``timeout_s``."""
        with self._changed:
            return self._changed.wait_for(lambda: holds(bytes(self.shown)), timeout_s)

    def type(self, text: str) -> None:
        os.write(self._master, text.encode())

    def signal_keys_on(self) -> None:
        """Turn the terminal's signal keys on (``ISIG``) as a program's cooked mode has them:
        Ctrl-C, Ctrl-Z and Ctrl-\\ typed next are signals to its foreground process group."""
        attributes = termios.tcgetattr(self._master)  # (a master's are its terminal's)
        attributes[3] |= termios.ISIG
        termios.tcsetattr(self._master, termios.TCSANOW, attributes)

    def hang_up(self) -> None:
        """Close the terminal: the last descriptor of its master side goes."""
        os.write(self._wake_w, b"x")
        self._reader.join(WAIT_S)
        assert not self._reader.is_alive()
        if self._master >= 0:
            os.close(self._master)
            self._master = -1

    def close(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
        self.process.communicate(timeout=WAIT_S)
        self.hang_up()
        os.close(self._wake_r)
        os.close(self._wake_w)


#: A shell stand-in: a session of its own whose controlling terminal is the path it is given.
_SHELL = (
    "import os, sys; os.setsid(); fd = os.open(sys.argv[1], os.O_RDWR); "
    "print(os.getpid(), flush=True); sys.stdin.read()"
)


class TerminalWindow:
    """A pseudo-terminal that is the controlling terminal of a child process, as a terminal
    window's is its shell's; ``master`` is the window's side (what a program writes shows there)."""

    def __init__(self) -> None:
        self.master, terminal = os.openpty()
        self.path = os.ttyname(terminal)
        os.close(terminal)
        self.shell = subprocess.Popen(
            [sys.executable, "-c", _SHELL, self.path],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        assert self.shell.stdout is not None
        self.pid = int(self.shell.stdout.readline())
        self.modes = termios.tcgetattr(self.master)

    def shown(self) -> bytes:
        """What programs wrote on the terminal so far."""
        ready, _, _ = select.select([self.master], [], [], 0)
        return os.read(self.master, 4096) if ready else b""

    def close(self) -> None:
        self.shell.kill()
        self.shell.communicate()
        os.close(self.master)


def refusal(window: TerminalWindow, path: str | None = None) -> str:
    """The one line a client refusing ``window`` says (``path``: the name it was given)."""
    name = Path(sys.executable).name[:15]  # (the kernel keeps 15 characters of a name)
    return (
        f"{path or window.path} is the terminal of process {window.pid} ({name}), not a "
        "controller's port (a pseudo-terminal's number is reused once its program ends)"
    )
