"""Text from the controller made safe to print: its control characters shown, not obeyed.

A controller's debug lines and line noise reach the user's terminal (``send``, the console, the
monitor, the client's errors); an escape sequence or a bell among them would recolour, move or
retitle that terminal. Imports nothing: ``rovlink send`` loads it.
"""

from __future__ import annotations

__all__ = ["visible"]

_TAB = 0x09
#: C0 (but tab), DEL and C1 (0x9b is a one-character CSI to some terminals) → ``\x1b`` style.
_ESCAPES = {
    code: f"\\x{code:02x}" for code in (*range(0x20), 0x7F, *range(0x80, 0xA0)) if code != _TAB
}


def visible(text: str) -> str:
    r"""``text`` with every control character but tab written as a ``\xNN`` escape.

    >>> print(visible("\x1b[31mRED\x07"))
    \x1b[31mRED\x07
    >>> visible("depth\t12 cm\r")
    'depth\t12 cm\\x0d'
    """
    return text.translate(_ESCAPES)
