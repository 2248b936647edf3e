"""Replies in words, for every response of the table."""

from __future__ import annotations

import pytest

from rovlink.piloting import reading_text, reply_text
from rovlink.protocol import RESPONSES, Response


@pytest.mark.parametrize(
    ("response", "expected"),
    [
        (Response("qd", (123,)), "qd → 123 cm"),
        (Response("qr", (530,)), "qr → 530 (raw)"),
        (Response("q.l", (0,)), "q.l → no leak"),
        (Response("q.l", (1,)), "q.l → LEAK: the sensor fired since the last reset"),
        (Response("qro", (-1,)), "qro → -1°"),
        (Response("qpi", (0,)), "qpi → +0°"),
        (Response("qhe", (275,)), "qhe → 275°"),
    ],
)
def test_reply_text(response: Response, expected: str) -> None:
    assert reply_text(response) == expected


@pytest.mark.parametrize("spec", RESPONSES, ids=lambda spec: spec.name)
def test_every_response_reads_its_value(spec: object) -> None:
    from rovlink.protocol import Spec

    assert isinstance(spec, Spec)
    value = spec.arguments[0].maximum
    text = reading_text(Response(spec.name, (value,)))
    assert text
    assert str(value) in text or spec.name == "q.l"
