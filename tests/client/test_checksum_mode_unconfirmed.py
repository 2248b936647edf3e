"""An open in checksum mode whose first checksummed query gets no valid reply says why it
thinks so: replies that failed the check (a noisy line) are not blamed on the algorithm."""

from __future__ import annotations

import contextlib

import pytest

from rovlink.aio import AsyncClient
from rovlink.client import Client, ClientOptions, ConnectError, QueryTimeoutError
from rovlink.client.links import SocketLink
from tests.client.conftest import NO_REPLY_TIMEOUT_S, client_options
from tests.client.fake_controller import FakeController

_NOISY = (
    "the controller answers in checksum mode, but no reply passed the crc8 check (a noisy line?"
)
_OTHER_ALGORITHM = "the controller answers, but not in checksum mode with crc8 (is that its"


def _options_in_checksum_mode() -> ClientOptions:
    return client_options(
        checksum=True, boot_timeout_s=1.0, retries=2, timeout_s=NO_REPLY_TIMEOUT_S
    )


def _fake(case: str) -> tuple[FakeController, SocketLink]:
    if case == "noisy line":  # the readiness probe is answered, every checksummed reply spoilt
        fake, sock = FakeController.on_socketpair()
        fake.then("reply", *["corrupt"] * 10)
    else:  # it checksums with xor: each crc8 query is dropped
        fake, sock = FakeController.on_socketpair(algorithm="xor")
    return fake, SocketLink(sock, "pair")


_CASES = [("noisy line", _NOISY), ("another algorithm", _OTHER_ALGORITHM)]


@pytest.mark.parametrize(("case", "says"), _CASES)
def test_the_blocking_client_tells_a_noisy_line_from_another_algorithm(
    case: str, says: str
) -> None:
    # Before, replies spoilt on a noisy line (fault://?ber=3e-3, rovlink send --checksum) were
    # reported as a controller not in checksum mode with crc8: "is that its algorithm?".
    fake, link = _fake(case)
    options = client_options(
        checksum=True, boot_timeout_s=1.0, retries=1, timeout_s=NO_REPLY_TIMEOUT_S
    )
    try:
        with pytest.raises(ConnectError) as raised:
            Client(link, options)
        assert says in str(raised.value)
    finally:
        fake.close()


@pytest.mark.parametrize(("case", "says"), _CASES)
async def test_the_asyncio_client_tells_a_noisy_line_from_another_algorithm(
    case: str, says: str
) -> None:
    fake, link = _fake(case)
    options = client_options(
        checksum=True, boot_timeout_s=1.0, retries=1, timeout_s=NO_REPLY_TIMEOUT_S
    )
    client = AsyncClient(link, options)
    try:
        with pytest.raises(ConnectError) as raised:
            await client.open()
        assert says in str(raised.value)
    finally:
        await client.close()
        fake.close()


@pytest.mark.parametrize("client", ["blocking", "asyncio"])
async def test_a_noisy_line_asks_a_program_for_more_retries_in_its_own_words(client: str) -> None:
    # Before, a program was told "more --retries": the command line's option, which a program
    # calling rovlink.connect has not got.
    fake, link = _fake("noisy line")
    options = client_options(
        checksum=True, boot_timeout_s=1.0, retries=1, timeout_s=NO_REPLY_TIMEOUT_S
    )
    opening = AsyncClient(link, options) if client == "asyncio" else None

    async def connect() -> None:
        if opening is not None:
            await opening.open()
        else:
            Client(link, options)

    try:
        with pytest.raises(ConnectError) as raised:
            await connect()
        assert "more attempts: retries=N;" in str(raised.value)
        assert "--retries" not in str(raised.value)
        assert raised.value.setting == "retries"
    finally:
        if opening is not None:
            await opening.close()
        fake.close()


def _reset_warnings(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if "reset suspected" in r.getMessage()]


def test_the_blocking_client_suspects_no_reset_of_a_controller_on_another_algorithm(
    caplog: pytest.LogCaptureFixture,
) -> None:
    # Before, `rovlink send --checksum --algorithm xor` on a crc8 controller first warned
    # "controller reset suspected after 2 consecutive timeouts: … the robot is locked after a
    # reset", then gave the error that says what the timeouts mean.
    fake, link = _fake("another algorithm")
    options = _options_in_checksum_mode()
    caplog.set_level("WARNING", logger="rovlink")
    try:
        with pytest.raises(ConnectError, match="is that its algorithm"):
            Client(link, options)
        assert _reset_warnings(caplog) == []
    finally:
        fake.close()


async def test_the_asyncio_client_suspects_no_reset_of_a_controller_on_another_algorithm(
    caplog: pytest.LogCaptureFixture,
) -> None:
    fake, link = _fake("another algorithm")
    options = _options_in_checksum_mode()
    caplog.set_level("WARNING", logger="rovlink")
    client = AsyncClient(link, options)
    try:
        with pytest.raises(ConnectError, match="is that its algorithm"):
            await client.open()
        assert _reset_warnings(caplog) == []
    finally:
        await client.close()
        fake.close()


def test_a_reset_suspected_once_connected_in_checksum_mode_is_still_a_warning(
    caplog: pytest.LogCaptureFixture,
) -> None:
    fake, sock = FakeController.on_socketpair()
    options = _options_in_checksum_mode()
    caplog.set_level("WARNING", logger="rovlink")
    try:
        with Client(SocketLink(sock, "pair"), options) as client:
            fake.then("drop", "drop", "drop")
            with contextlib.suppress(QueryTimeoutError):  # (answered once the fence went)
                client.depth_cm()
        assert len(_reset_warnings(caplog)) == 1
    finally:
        fake.close()
