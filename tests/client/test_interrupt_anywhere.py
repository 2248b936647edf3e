"""Ctrl-C at every step of a blocking call, one step at a time: wherever it lands, the call
ends with ``KeyboardInterrupt`` and leaves the client as it found it (no lock held, no reader
role, no query counted as active), so that another thread's query is answered and ``stop()``
goes out at once.

Python runs a signal handler, and so raises ``KeyboardInterrupt``, where the interpreter looks
for pending signals: at a call (before it, or as a call into C returns) and at the top of a
loop. A tracing function that asks for every bytecode raises it at each of those places of the
client's own code in turn. The places between two calls (a lock just taken, the reader role
just claimed, before the ``try`` that would give them back) are the ones that matter: before
:meth:`Client._recover_after_error`, a Ctrl-C at some of them left the state lock or the wire
lock held for good, and the program hung in its own ``stop()``.
"""

from __future__ import annotations

import contextlib
import dis
import sys
import threading
from collections.abc import Callable, Iterator
from types import CodeType, FrameType
from typing import Any

import pytest

import rovlink.client.blocking
from rovlink.client.blocking import Client
from rovlink.client.links import SocketLink
from tests.client.conftest import CONDITION_TIMEOUT_S, client_options, wait_until
from tests.client.fake_controller import FakeController

pytestmark = pytest.mark.integration

_CLIENT_SOURCE = rovlink.client.blocking.__file__
#: The caller that never leaves, when a test keeps the background reader out: no thread's
#: identifier is negative.
_PHANTOM_CALLER = -1


def _signal_checks(code: CodeType) -> frozenset[int]:
    """The offsets in ``code`` where a pending signal can be raised: each call instruction
    (the signal came before it) and the instruction after it (it came during the call), and
    each jump back to the top of a loop."""
    offsets: set[int] = set()
    after_call = False
    for instruction in dis.get_instructions(code):
        name = instruction.opname
        if after_call or name.startswith("CALL") or name.startswith("JUMP_BACKWARD"):
            offsets.add(instruction.offset)
        after_call = name.startswith("CALL")
    return frozenset(offsets)


class _InterruptAt:
    """Raise KeyboardInterrupt at the ``nth`` signal check of the client's code that this
    thread runs (``fired`` tells whether the call got that far)."""

    def __init__(self, nth: int) -> None:
        self._left = nth
        self.fired_at: str | None = None
        self._checks: dict[CodeType, frozenset[int]] = {}

    def __enter__(self) -> _InterruptAt:
        sys.settrace(self._on_call)
        return self

    def __exit__(self, *exc_info: object) -> None:
        sys.settrace(None)

    def _on_call(self, frame: FrameType, event: str, arg: Any) -> Any:
        if self.fired_at is not None or frame.f_code.co_filename != _CLIENT_SOURCE:
            return None
        frame.f_trace = self._on_opcode  # (set on the frame too: 3.13 asks for it)
        frame.f_trace_opcodes = True
        frame.f_trace_lines = False
        return self._on_opcode

    def _on_opcode(self, frame: FrameType, event: str, arg: Any) -> Any:
        if event != "opcode" or self.fired_at is not None:
            return None
        code = frame.f_code
        checks = self._checks.get(code)
        if checks is None:
            checks = self._checks[code] = _signal_checks(code)
        if frame.f_lasti in checks:
            if self._left == 0:
                self.fired_at = f"{code.co_name} line {frame.f_lineno} (offset {frame.f_lasti})"
                raise KeyboardInterrupt
            self._left -= 1
        return self._on_opcode


@pytest.fixture
def fake_and_client(request: pytest.FixtureRequest) -> Iterator[tuple[FakeController, Client]]:
    """A client of a fake controller whose ``$qd.N!`` numbers the queries it received; the
    query timeout in seconds may be given as the fixture's parameter (``indirect``)."""
    fake, sock = FakeController.on_socketpair()
    fake.qd_counts_queries = True
    # Short: an interrupted query's fence, or a lost mode frame, costs a timeout or two.
    timeout_s = getattr(request, "param", 0.5)
    client = Client(SocketLink(sock, "socket pair"), client_options(retries=2, timeout_s=timeout_s))
    try:
        yield fake, client
    finally:
        client._callers.pop(_PHANTOM_CALLER, None)
        client.close()
        fake.close()


def _keep_the_background_reader_out(client: Client) -> None:
    """Count a caller that never leaves: every query then reads its own reply in the test's
    thread (the path a polling program takes), not through the background reader."""
    with client._state_lock:
        client._callers[_PHANTOM_CALLER] = None
    client._link.wake()
    assert wait_until(lambda: client._reader_ident is None)


def _interrupt_every_step(client: Client, call: Callable[[], object]) -> int:
    """Run ``call`` once per signal check it passes, interrupted there, and check the client
    after each; the number of steps."""
    me = threading.get_ident()
    step = 0
    while True:
        with _InterruptAt(step) as interrupt, contextlib.suppress(KeyboardInterrupt):
            call()
        if interrupt.fired_at is None:
            return step
        where = f"Ctrl-C at step {step}, {interrupt.fired_at}"
        assert not client._state_lock._is_owned(), f"{where}: the state lock stays held"  # type: ignore[attr-defined]
        assert not client._wire_lock._is_owned(), f"{where}: the wire lock stays held"  # type: ignore[attr-defined]
        assert client._reader_ident != me, f"{where}: the reader role stays taken"
        assert me not in client._callers, f"{where}: the caller still counts as active"
        _another_thread_is_answered(client, where)
        step += 1


def _another_thread_is_answered(client: Client, where: str) -> None:
    answers: list[object] = []

    def query() -> None:
        answers.append(client.depth_cm())

    other = threading.Thread(target=query, daemon=True)
    other.start()
    other.join(CONDITION_TIMEOUT_S)
    assert answers, f"{where}: another thread's query is not answered (the client hangs)"


def test_ctrl_c_anywhere_in_a_query_read_by_its_caller(
    fake_and_client: tuple[FakeController, Client],
) -> None:
    fake, client = fake_and_client
    _keep_the_background_reader_out(client)
    steps = _interrupt_every_step(client, client.depth_cm)
    assert steps > 20  # (the tracing reached the client's code)
    assert client.depth_cm() == fake.query_count  # its own reply, not an interrupted one's
    client.stop()
    assert fake.wait_for(
        lambda controller: controller.frames()[-1:] == ["#stop!"], CONDITION_TIMEOUT_S
    )


def test_ctrl_c_anywhere_in_a_query_the_background_reader_hands_over(
    fake_and_client: tuple[FakeController, Client],
) -> None:
    fake, client = fake_and_client
    assert _interrupt_every_step(client, client.depth_cm) > 20
    assert client.depth_cm() == fake.query_count
    client.stop()
    assert fake.wait_for(
        lambda controller: controller.frames()[-1:] == ["#stop!"], CONDITION_TIMEOUT_S
    )


def test_ctrl_c_anywhere_in_a_raw_query(fake_and_client: tuple[FakeController, Client]) -> None:
    fake, client = fake_and_client
    _keep_the_background_reader_out(client)
    assert _interrupt_every_step(client, lambda: client.send_raw("#qd!")) > 20
    assert client.depth_cm() == fake.query_count


# A Ctrl-C around the write of a mode frame leaves the mode unknown: the client finds it again
# after two timeouts in a row (P21), so these timeouts are short.
@pytest.mark.parametrize("fake_and_client", [0.3], indirect=True)
def test_ctrl_c_anywhere_in_a_checksum_switch(
    fake_and_client: tuple[FakeController, Client],
) -> None:
    _, client = fake_and_client
    switches = iter([True, False] * 1000)
    assert _interrupt_every_step(client, lambda: client.set_checksum(next(switches))) > 10
    client.set_checksum(True)
    assert client.depth_cm() >= 1
