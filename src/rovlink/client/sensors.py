"""Sensors: every sensor reading at once, from the six replies of ``#qsa!`` (P12)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from rovlink.protocol import Response, lookup

__all__ = ["Sensors"]


@dataclass(frozen=True, slots=True)
class Sensors:
    """One reading of every sensor, as ``sensors()`` returns it.

    >>> from rovlink.protocol import Response
    >>> replies = [Response("qd", (120,)), Response("qr", (530,)), Response("q.l", (0,)),
    ...            Response("qro", (-1,)), Response("qpi", (3,)), Response("qhe", (275,))]
    >>> Sensors.from_responses(replies).heading_deg
    275
    """

    depth_cm: int
    pressure_raw: int
    leak_detected: bool
    roll_deg: int
    pitch_deg: int
    heading_deg: int

    @classmethod
    def from_responses(cls, responses: Sequence[Response]) -> Sensors:
        """Build from the replies of ``#qsa!`` (any order; each of the six exactly once).

        >>> from rovlink.protocol import Response
        >>> values = {"qd": 120, "qr": 612, "q.l": 0, "qro": -2, "qpi": 1, "qhe": 275}
        >>> replies = [Response(name, (value,)) for name, value in values.items()]
        >>> Sensors.from_responses(replies).depth_cm
        120
        """
        values = {response.name: response.values[0] for response in responses}
        if len(values) != len(responses) or set(values) != set(_REPLY_NAMES):
            names = ", ".join(response.name for response in responses)
            raise ValueError(f"qsa needs one each of {', '.join(_REPLY_NAMES)}; got {names}")
        return cls(
            depth_cm=values["qd"],
            pressure_raw=values["qr"],
            leak_detected=bool(values["q.l"]),
            roll_deg=values["qro"],
            pitch_deg=values["qpi"],
            heading_deg=values["qhe"],
        )


_REPLY_NAMES = lookup("qsa").replies
