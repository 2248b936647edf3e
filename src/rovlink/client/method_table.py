"""The host driver's command methods, defined once for the blocking and the asyncio client.

Each :class:`Method` names the frames of the command table it sends and the function of
:mod:`rovlink.client.operations` that validates its arguments. From this table and the command
table, ``python -m rovlink.client.method_table`` writes:

* ``src/rovlink/client/command_methods.py`` — :class:`CommandMethods`, the blocking methods;
* ``src/rovlink/aio/command_methods.py`` — :class:`AsyncCommandMethods`, the same as coroutines;
* the method table of ``docs/driver.md`` (between its ``methods`` markers).

Descriptions, ranges and units in the docstrings come from the command table, so a fact about a
command is written once. A test checks that the generated files are current.

>>> [method.name for method in METHODS if "th" in method.frames]
['move']
"""

from __future__ import annotations

import re
import sys
from dataclasses import dataclass
from pathlib import Path

from rovlink.protocol import Argument, Spec, lookup
from rovlink.protocol.commands import Kind

__all__ = ["METHODS", "Method", "Parameter", "render_async", "render_blocking", "render_docs"]


@dataclass(frozen=True)
class Parameter:
    """One argument of a method, and the frame argument it fills (for its range and unit)."""

    name: str
    annotation: str
    frame: str = ""
    index: int = 0
    default: str | None = None

    def signature(self) -> str:
        """The parameter as written in a ``def``."""
        if self.default is None:
            return f"{self.name}: {self.annotation}"
        return f"{self.name}: {self.annotation} = {self.default}"

    def meaning(self) -> str:
        """What the parameter is, from the command table: description, range and unit."""
        if not self.frame:
            return "True or False"
        return _meaning(lookup(self.frame).arguments[self.index])


@dataclass(frozen=True)
class Method:
    """One command method of both clients.

    ``how`` is ``send`` (one set command), ``send_each`` (several, all validated first),
    ``ask`` (a query, retried), or ``switch_checksum`` (the mode switch, which waits for the
    queries on the wire); ``call`` is the expression of :mod:`operations` that makes the command,
    the commands or the query.
    """

    name: str
    frames: tuple[str, ...]
    how: str
    call: str
    example: str
    parameters: tuple[Parameter, ...] = ()
    returns: str = "None"
    note: str = ""

    def signature(self) -> str:
        """The parameters as written in a ``def``, after ``self``."""
        return "".join(f", {parameter.signature()}" for parameter in self.parameters)

    def specs(self) -> tuple[Spec, ...]:
        """The command-table entries of the frames the method sends."""
        return tuple(lookup(frame) for frame in self.frames)


def _meaning(argument: Argument) -> str:
    """``description, range unit``; the unit only where the description does not name it."""
    unit = argument.unit if argument.unit not in argument.description else ""
    space = " " if unit and unit != "°" else ""
    return f"{argument.description}, {argument.range_text()}{space}{unit}"


def _flag(name: str = "enabled") -> tuple[Parameter, ...]:
    return (Parameter(name, "bool"),)


METHODS: tuple[Method, ...] = (
    Method(
        "stop",
        ("stop",),
        "send",
        "operations.STOP",
        "rov.stop()",
        note="Always sent bare, so it is honoured whatever checksum mode the controller is in.",
    ),
    Method("start", ("start",), "send", "operations.START", "rov.start()"),
    Method(
        "set_checksum",
        ("crcon", "crcoff"),
        "switch_checksum",
        "operations.checksum(enabled)",
        "rov.set_checksum(True)",
        _flag(),
        note="Queries already on the wire are answered first, in the old mode; then the "
        "client's own encoder and decoder switch with the controller.",
    ),
    Method(
        "set_debug",
        ("debug1", "debug0"),
        "send",
        "operations.debug(enabled)",
        "rov.set_debug(True)",
        _flag(),
        note="The controller's debug text arrives through ``on_event``/``on_stray`` and logging.",
    ),
    Method(
        "set_max_pwm",
        ("mgmp",),
        "send",
        "operations.max_pwm(duty)",
        "rov.set_max_pwm(180)",
        (Parameter("duty", "int", "mgmp"),),
    ),
    Method(
        "set_depth_pid",
        ("mvpdp", "mvpdi", "mvpidd"),
        "send_each",
        "operations.depth_pid(p, i, d)",
        "rov.set_depth_pid(p=30, d=10)",
        (
            Parameter("p", "int | None", "mvpdp", default="None"),
            Parameter("i", "int | None", "mvpdi", default="None"),
            Parameter("d", "int | None", "mvpidd", default="None"),
        ),
        note="One frame for each gain given; all are checked before any is sent.",
    ),
    Method(
        "set_direct_mode",
        ("mvdirect",),
        "send",
        "operations.direct_mode(enabled)",
        "rov.set_direct_mode(True)\nrov.set_vertical_thrust(-30)",
        _flag(),
    ),
    Method(
        "set_vertical_thrust",
        ("mvs",),
        "send",
        "operations.vertical_thrust(percent)",
        "rov.set_vertical_thrust(+50)",
        (Parameter("percent", "int", "mvs"),),
    ),
    Method(
        "hold_depth",
        ("mvd",),
        "send",
        "operations.hold_depth(depth_cm)",
        "rov.hold_depth(100)   # one metre",
        (Parameter("depth_cm", "int", "mvd"),),
    ),
    Method(
        "move",
        ("th",),
        "send",
        "operations.move(direction_deg, power_percent)",
        "rov.move(270, 25)   # left at a quarter power",
        (Parameter("direction_deg", "int", "th", 0), Parameter("power_percent", "int", "th", 1)),
    ),
    Method(
        "set_depth_zero",
        ("sdz",),
        "send",
        "operations.depth_zero(raw)",
        "rov.set_depth_zero(rov.pressure_raw())   # calibrate at the surface",
        (Parameter("raw", "int", "sdz"),),
    ),
    Method(
        "set_depth_scale",
        ("sdk",),
        "send",
        "operations.depth_scale(k)",
        "rov.set_depth_scale(1000)",
        (Parameter("k", "int", "sdk"),),
    ),
    Method("reset_leak", ("slreset",), "send", "operations.RESET_LEAK", "rov.reset_leak()"),
    Method("claw_open", ("h+",), "send", "operations.CLAW_OPEN", "rov.claw_open()"),
    Method("claw_close", ("h-",), "send", "operations.CLAW_CLOSE", "rov.claw_close()"),
    Method(
        "depth_cm",
        ("qd",),
        "ask",
        "operations.DEPTH_CM",
        "if rov.depth_cm() > 500: rov.hold_depth(400)",
        returns="int",
    ),
    Method(
        "pressure_raw",
        ("qr",),
        "ask",
        "operations.PRESSURE_RAW",
        "zero = rov.pressure_raw()",
        returns="int",
    ),
    Method(
        "leak_detected",
        ("q.l",),
        "ask",
        "operations.LEAK_DETECTED",
        "if rov.leak_detected(): rov.hold_depth(0)",
        returns="bool",
    ),
    Method(
        "roll_deg", ("qro",), "ask", "operations.ROLL_DEG", "print(rov.roll_deg())", returns="int"
    ),
    Method(
        "pitch_deg",
        ("qpi",),
        "ask",
        "operations.PITCH_DEG",
        "print(rov.pitch_deg())",
        returns="int",
    ),
    Method(
        "heading_deg",
        ("qhe",),
        "ask",
        "operations.HEADING_DEG",
        "print(rov.heading_deg())",
        returns="int",
    ),
    Method(
        "sensors",
        ("qsa",),
        "ask",
        "operations.SENSORS",
        "reading = rov.sensors()\nprint(reading.depth_cm, reading.heading_deg)",
        returns="Sensors",
    ),
)

_BANNER = (
    "# Generated by `python -m rovlink.client.method_table` from the driver's method table and\n"
    "# the command table: do not edit by hand (a test checks that it is current).\n"
)


def _frame_text(spec: Spec) -> str:
    if len(spec.replies) == 1:
        return f"``{spec.template()}`` → ``{lookup(spec.replies[0], Kind.RESPONSE).template()}``"
    if spec.replies:
        replies = ", ".join(f"``${name}``" for name in spec.replies)
        return f"``{spec.template()}`` → {replies}"
    return f"``{spec.template()}``"


def _docstring(method: Method, asynchronous: bool) -> list[str]:
    specs = method.specs()
    lines = [f"{_frame_text(spec)}: {spec.description}." for spec in specs]
    if method.parameters:
        lines.append("")
        lines += [
            f"``{parameter.name}``: {parameter.meaning()}." for parameter in method.parameters
        ]
    if method.how == "ask" and len(specs[0].replies) == 1:
        argument = lookup(specs[0].replies[0], Kind.RESPONSE).arguments[0]
        as_bool = " (returned as True or False)" if method.returns == "bool" else ""
        lines += ["", f"The reply's ``{argument.name}``: {_meaning(argument)}{as_bool}."]
    if method.note:
        lines += ["", method.note]
    example = method.example
    if asynchronous:
        example = re.sub(r"\brov\.", "await rov.", example)
    lines += ["", "Example::", ""] + [f"    {line}" for line in example.splitlines()]
    return lines


def _wrap(text: str, indent: str, width: int = 100) -> list[str]:
    """Wrap one docstring paragraph line at ``width`` columns, keeping examples as they are."""
    if len(indent + text) <= width or text.startswith("    "):
        return [indent + text if text else ""]
    words = text.split(" ")
    lines: list[str] = []
    current = ""
    for word in words:
        candidate = f"{current} {word}" if current else word
        if len(indent + candidate) > width and current:
            lines.append(indent + current)
            current = word
        else:
            current = candidate
    lines.append(indent + current)
    return lines


def _body(method: Method, asynchronous: bool) -> list[str]:
    wait = "await " if asynchronous else ""
    # The asyncio client lets a slow serial line catch up before a frame, in a coroutine; the
    # blocking client does in its _send. A #stop! never waits for the line.
    send = "await self._send_paced" if asynchronous and method.frames != ("stop",) else "self._send"
    if method.how == "send":
        return [f"{send}({method.call})"]
    if method.how == "send_each":
        return [f"for command in {method.call}:", f"    {send}(command)"]
    if method.how == "ask":
        return [f"return {wait}self._ask({method.call})"]
    if method.how == "switch_checksum":
        return [f"{wait}self._switch_checksum({method.call})"]
    raise ValueError(f"{method.name}: unknown kind of method {method.how!r}")


def _render(asynchronous: bool) -> str:
    class_name = "AsyncCommandMethods" if asynchronous else "CommandMethods"
    client = "asyncio client" if asynchronous else "blocking client"
    out = [_BANNER.rstrip("\n")]
    out += [
        f'"""The {client}\'s command methods: one per command of the protocol."""',
        "",
        "from __future__ import annotations",
        "",
        "from typing import TypeVar",
        "",
        "from rovlink.client import operations",
        "from rovlink.client.sensors import Sensors",
        "from rovlink.protocol import Command",
        "",
        f'__all__ = ["{class_name}"]',
        "",
        'T = TypeVar("T")',
        "",
        "",
        f"class {class_name}:",
        f'    """The command methods of the {client}; the client supplies how to send and ask."""',
        "",
        "    def _send(self, command: Command) -> None:",
        "        raise NotImplementedError",
        "",
    ]
    if asynchronous:
        out += [
            "    async def _send_paced(self, command: Command) -> None:",
            "        raise NotImplementedError",
            "",
        ]
    prefix = "async " if asynchronous else ""
    out += [
        f"    {prefix}def _ask(self, query: operations.Query[T]) -> T:",
        "        raise NotImplementedError",
        "",
        f"    {prefix}def _switch_checksum(self, command: Command) -> None:",
        "        raise NotImplementedError",
    ]
    for method in METHODS:
        out.append("")
        header = f"    {prefix}def {method.name}(self{method.signature()}) -> {method.returns}:"
        if len(header) > 100:
            joined = ", ".join(parameter.signature() for parameter in method.parameters)
            out += [
                f"    {prefix}def {method.name}(",
                f"        self, {joined}",
                f"    ) -> {method.returns}:",
            ]
        else:
            out.append(header)
        doc = _docstring(method, asynchronous)
        first = _wrap('"""' + doc[0], "        ")
        out += first
        for line in doc[1:]:
            out += _wrap(line, "        ") if line else [""]
        out.append('        """')
        out += [f"        {line}" for line in _body(method, asynchronous)]
    return "\n".join(out) + "\n"


def render_blocking() -> str:
    """The source of ``rovlink/client/command_methods.py``."""
    return _render(asynchronous=False)


def render_async() -> str:
    """The source of ``rovlink/aio/command_methods.py``."""
    return _render(asynchronous=True)


def _returns_text(method: Method) -> str:
    if method.returns == "None":
        return ""
    return f"`{method.returns}`"


def render_docs() -> str:
    """The method table of ``docs/driver.md`` (without its markers)."""
    rows = ["| method | frames | arguments | returns |", "|---|---|---|---|"]
    for method in METHODS:
        names = ", ".join(parameter.name for parameter in method.parameters)
        frames = ", ".join(_frame_text(spec).replace("``", "`") for spec in method.specs())
        arguments = "; ".join(
            f"`{parameter.name}`: {parameter.meaning()}" for parameter in method.parameters
        )
        rows.append(
            f"| `{method.name}({names})` | {frames} | {arguments} | {_returns_text(method)} |"
        )
    return "\n".join(rows) + "\n"


DOCS_START = "<!-- methods:start (generated by python -m rovlink.client.method_table) -->\n"
DOCS_END = "<!-- methods:end -->\n"


def docs_with_table(text: str) -> str:
    """``text`` (docs/driver.md) with its method table replaced by the current one."""
    start = text.index(DOCS_START) + len(DOCS_START)
    end = text.index(DOCS_END)
    return text[:start] + render_docs() + text[end:]


def main(root: Path) -> None:
    """Write the generated files under the source tree ``root``."""
    (root / "src/rovlink/client/command_methods.py").write_text(render_blocking())
    (root / "src/rovlink/aio/command_methods.py").write_text(render_async())
    docs = root / "docs/driver.md"
    docs.write_text(docs_with_table(docs.read_text()))


if __name__ == "__main__":  # pragma: no cover - the generator's command line
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path.cwd())
