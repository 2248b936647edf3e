"""An extra's library that a command imports: missing (install it) or broken (it is there).

A library that is not installed is said with the one line that installs it. One that is
installed but fails as it is imported (a compiled part built for another numpy or Python, a
dependency too old for it) is said as such, with that failure's first line: the install line
would change nothing. ``rovlink -v`` adds the traceback.
"""

from __future__ import annotations

import sys

from rovlink.cli.failure import CommandError

TYPE_CHECKING = False  # (typing stays off the command line's start-up path)
if TYPE_CHECKING:
    from types import TracebackType
    from typing import Literal

__all__ = ["needs_extra"]


def needs_extra(extra: str, what: str = "needs") -> _ExtraImports:
    """Around the imports of ``extra``'s libraries: one that fails ends the command with one
    line (a :class:`CommandError`), ``with needs_extra("plot"): import matplotlib``.

    ``what`` says what needs it (``"--plot needs"``; the default is ``"needs"``). A failure
    that comes from rovlink's own modules alone, naming no other library, is not an extra's
    and is left as it is (a bug, with its traceback).
    """
    return _ExtraImports(extra, what)


class _ExtraImports:
    # A class rather than contextlib.contextmanager: contextlib is not imported at start-up.
    def __init__(self, extra: str, what: str = "needs") -> None:
        self.extra = extra
        self.what = what

    def __enter__(self) -> None:
        return None

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> Literal[False]:
        if not isinstance(error, Exception):
            return False
        missing = _missing_library(error)
        if missing is not None:
            raise CommandError(
                f"{self.what} {missing}: pip install 'rovlink[{self.extra}]'"
            ) from None
        library = _failing_library(error)
        if library is None:
            return False
        import logging  # noqa: PLC0415 - only as an import has failed

        logging.getLogger(__name__).debug("importing %s failed", library, exc_info=error)
        first_line = (str(error).strip().splitlines() or [type(error).__name__])[0]
        raise CommandError(
            f"{library} is installed but cannot be imported: {first_line}; reinstall the "
            f"{self.extra} extra: pip install --upgrade --force-reinstall 'rovlink[{self.extra}]' "
            "(rovlink -v shows the traceback)"
        ) from None


def _missing_library(error: Exception) -> str | None:
    """The library that ``error`` says is not installed at all: a :class:`ModuleNotFoundError`
    for a top-level module that is nowhere to be found and not one of Python's own.

    A missing submodule of an installed package (``numpy.core._multiarray_umath``, compiled
    for another Python) or a module of Python's own (``_ctypes``, ``_ssl``, ``_lzma`` left out
    of a Python built without them) is a broken install, not a missing one.
    """
    if not isinstance(error, ModuleNotFoundError) or not error.name:
        return None
    top = error.name.partition(".")[0]
    if top != error.name or top in sys.stdlib_module_names:
        return None
    return top


def _failing_library(error: Exception) -> str | None:
    """The installed library whose import raised ``error``: the outermost module in its
    traceback that is neither rovlink's nor Python's own, else the module the error names (an
    ``ImportError`` of a name the library lacks) or whose file does not compile (a
    ``SyntaxError``: written for an older Python); ``None`` if it is rovlink's or Python's."""
    tb = error.__traceback__
    tb = tb and tb.tb_next  # (the frames under the ``with``, not the command's own)
    while tb is not None:
        library = _library(str(tb.tb_frame.f_globals.get("__name__", "")))
        if library is not None:
            return library
        tb = tb.tb_next
    name = getattr(error, "name", None) or ""
    if isinstance(error, SyntaxError) and error.filename:  # (the library's code never ran)
        name = _module_of_file(error.filename)
    return _library(name)


def _library(module: str) -> str | None:
    """The top-level name of ``module`` if it is another library's: not rovlink's, not one of
    Python's own (the import system's frames are ``importlib``'s)."""
    top = module.partition(".")[0]
    ours = {"rovlink", "", "_frozen_importlib", "_frozen_importlib_external"}
    return None if top in ours or top in sys.stdlib_module_names else top


def _module_of_file(path: str) -> str:
    """The top-level module that the file at ``path`` belongs to, found from the most specific
    ``sys.path`` entry holding it (``""`` if none does)."""
    from pathlib import Path  # noqa: PLC0415 - only as an import has failed

    file = Path(path).resolve()
    parts: tuple[str, ...] = ()
    for entry in sys.path:
        folder = Path(entry or ".").resolve()
        if file.is_relative_to(folder) and (not parts or len(folder.parts) > len(parts)):
            parts = folder.parts
    if not parts:
        return ""
    return file.parts[len(parts)].removesuffix(".py")
