"""``StrEnum`` on every supported Python: members are strings and print as their values.

Python 3.11 added :class:`enum.StrEnum`; Python 3.10 (Jetson, Ubuntu 22.04) lacks it.

>>> class Colour(StrEnum):
...     RED = "red"
>>> str(Colour.RED), f"{Colour.RED}", Colour.RED == "red"
('red', 'red', True)
"""

from __future__ import annotations

import sys
from enum import Enum

__all__ = ["StrEnum"]

if sys.version_info >= (3, 11):
    from enum import StrEnum
else:  # pragma: no cover - exercised by the Python 3.10 CI job

    class StrEnum(str, Enum):
        """A string-valued enumeration whose ``str()`` and ``format()`` give the value."""

        def __str__(self) -> str:
            return str(self.value)

        def __format__(self, format_spec: str) -> str:
            return str(self.value).__format__(format_spec)
