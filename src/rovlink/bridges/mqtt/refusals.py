"""What the broker refuses the bridge (its access control), told rather than lost.

A broker's access control refuses quietly: mosquitto drops a publication it does not allow and
answers it "Not authorized" in its MQTT 5 PUBACK, which aiomqtt does not pass on (the publish
returns as if it had gone); a subscription refused comes back as a reason code in the SUBACK.
Without this a robot whose user may not publish its state or its replies, or read its commands,
would look online to its bridge, and nothing would say why nobody hears it.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

__all__ = ["first_refusal", "watch_publications"]


def watch_publications(client: Any, on_refused: Callable[[str, str], None]) -> None:
    """Have ``on_refused(topic, reason)`` called for each publication of ``client`` (an
    ``aiomqtt.Client``, before it connects) that the broker answers with a failure."""
    paho = getattr(client, "_client", None)
    if paho is None:
        return  # (an aiomqtt built otherwise: nothing to watch)
    inner = paho.on_publish

    def on_publish(
        paho_client: Any, userdata: Any, mid: int, reason_code: Any, properties: Any
    ) -> None:
        if getattr(reason_code, "is_failure", False):
            # paho calls this before it forgets the message: its topic is still there.
            message = getattr(paho_client, "_out_messages", {}).get(mid)
            on_refused(str(getattr(message, "topic", "?")), str(reason_code))
        if inner is not None:
            inner(paho_client, userdata, mid, reason_code, properties)

    paho.on_publish = on_publish


def first_refusal(reason_codes: Iterable[Any]) -> str | None:
    """The first failure among a SUBACK's reason codes (MQTT 5), or ``None``."""
    for code in reason_codes:
        if getattr(code, "is_failure", False):
            return str(code)
    return None
