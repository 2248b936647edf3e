"""Who may use the station: loopback, Host, Origin and token rules."""

from __future__ import annotations

import pytest

from rovlink.station.access import Access, generate_token

LOCAL = Access(bind_host="127.0.0.1", port=8600)
TOKEN = "a-good-long-token"
NETWORK = Access(bind_host="0.0.0.0", port=8600, token=TOKEN)


def headers(host: str = "127.0.0.1:8600", **more: str) -> list[tuple[bytes, bytes]]:
    return [(b"host", host.encode())] + [
        (name.encode(), value.encode()) for name, value in more.items()
    ]


def test_loopback_needs_no_token_but_a_loopback_host():
    assert LOCAL.check(headers(), "", websocket=False).allowed
    assert LOCAL.check(headers("localhost:8600"), "", websocket=False).allowed
    refused = LOCAL.check(headers("attacker.example:8600"), "", websocket=False)
    assert not refused.allowed
    assert "this computer only" in refused.reason


def test_websockets_from_another_origin_are_refused():
    same = headers(origin="http://127.0.0.1:8600")
    assert LOCAL.check(same, "", websocket=True).allowed
    other = LOCAL.check(headers(origin="https://evil.example"), "", websocket=True)
    assert not other.allowed
    assert "origin" in other.reason
    port = LOCAL.check(headers(origin="http://127.0.0.1:9999"), "", websocket=True)
    assert not port.allowed
    assert LOCAL.check(headers(), "", websocket=True).allowed  # a program sends no Origin


def test_beyond_loopback_a_token_is_needed():
    assert not NETWORK.check(headers("10.0.0.5:8600"), "", websocket=False).allowed
    assert not NETWORK.check(headers("10.0.0.5:8600"), "token=wrong", websocket=True).allowed
    in_url = NETWORK.check(headers("10.0.0.5:8600"), f"token={TOKEN}", websocket=False)
    assert in_url.allowed
    assert in_url.token_in_url
    cookie = headers("10.0.0.5:8600", cookie=f"other=1; rovlink-station-8600={TOKEN}")
    assert NETWORK.check(cookie, "", websocket=True).allowed
    wrong_port = headers("10.0.0.5:8600", cookie=f"rovlink-station-8601={TOKEN}")
    assert not NETWORK.check(wrong_port, "", websocket=True).allowed
    broken = headers("10.0.0.5:8600", cookie='"\x00;;=')
    assert not NETWORK.check(broken, "", websocket=True).allowed


def test_serving_beyond_loopback_without_a_token_is_refused():
    with pytest.raises(ValueError, match="needs a token"):
        Access(bind_host="0.0.0.0", port=8600)
    with pytest.raises(ValueError, match="at least 8"):
        Access(bind_host="0.0.0.0", port=8600, token="short")


def test_generated_tokens_differ_and_are_long():
    first, second = generate_token(), generate_token()
    assert first != second
    assert len(first) >= 32
