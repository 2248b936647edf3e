"""Message classes declare each slot once, on every supported Python.

On Python 3.10, ``@dataclass(slots=True)`` on a subclass declares the inherited fields' slots
again; the subclass's empty descriptors then shadow the base's, and a field set in the base's
``__post_init__`` (``spec``) reads as missing.
"""

from __future__ import annotations

import pytest

from rovlink.protocol import Command, Response
from rovlink.protocol.messages import Message


@pytest.mark.parametrize("message_class", [Command, Response])
def test_a_subclass_declares_no_slot_of_its_base(message_class: type[Message]) -> None:
    inherited = set(Message.__slots__)
    assert not inherited & set(message_class.__dict__.get("__slots__", ()))


def test_fields_set_by_the_base_are_readable_on_each_subclass() -> None:
    assert Command("qd").spec.name == "qd"
    assert Response("qd", (5,)).spec.name == "qd"
    assert not hasattr(Command("qd"), "__dict__")
