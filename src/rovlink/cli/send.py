"""``rovlink send URL COMMAND...``: send commands through the driver and print the replies."""

from __future__ import annotations

import json
import re

import typer

import rovlink
from rovlink.cli.link_options import (
    AlgorithmOption,
    BaudrateOption,
    ChecksumOption,
    RetriesOption,
    TimeoutOption,
    UrlArgument,
)
from rovlink.client import ClientError, CommandTextError, parse_command_text
from rovlink.protocol import DEFAULT_ALGORITHM, Command, Event, Response, Text

__all__ = ["describe_reply", "group_words", "register"]


def describe_reply(response: Response) -> str:
    """A reply with its values named from the command table, e.g. ``$qd.123!  depth_cm=123``.

    >>> describe_reply(Response("qro", (-1,)))
    '$qro.-1!  roll_deg=-1'
    """
    fields = "  ".join(
        f"{argument.name}={value}"
        for argument, value in zip(response.spec.arguments, response.values, strict=True)
    )
    return f"{response}  {fields}" if fields else str(response)


def _reply_json(response: Response) -> dict[str, object]:
    return {
        "frame": str(response),
        "name": response.name,
        "values": {argument.name: value for argument, value
                   in zip(response.spec.arguments, response.values, strict=True)},
    }


def group_words(arguments: list[str]) -> list[str]:
    """Command texts from the command line: a quoted command stays whole; unquoted words
    group as a name followed by its numbers, so ``th 270 25 qd`` is two commands.

    >>> group_words(["th", "270", "25", "qd", "mvs -50", "#qsa!"])
    ['th 270 25', 'qd', 'mvs -50', '#qsa!']
    """
    groups: list[list[str]] = []
    open_group = False
    for argument in arguments:
        if " " in argument.strip() or argument.startswith("#"):
            groups.append([argument])
            open_group = False
        elif open_group and _NUMBER.fullmatch(argument):
            groups[-1].append(argument)
        else:
            groups.append([argument])
            open_group = True
    return [" ".join(group) for group in groups]


_NUMBER = re.compile(r"[+-]?\d+")


def _parse_all(texts: list[str]) -> list[Command | bytes]:
    """Commands of the table from friendly text, and raw frames (``#…!``) as they are."""
    commands: list[Command | bytes] = []
    for position, text in enumerate(group_words(texts), start=1):
        if text.startswith("#"):
            if not (text.isascii() and text.endswith("!") and len(text) > 2):
                raise typer.BadParameter(
                    f"command {position} ({text!r}): a raw frame is '#', a body and '!'",
                    param_hint="COMMAND",
                )
            commands.append(text.encode("ascii"))  # sent exactly as given, checksum and all
            continue
        try:
            commands.append(parse_command_text(text))
        except CommandTextError as error:
            raise typer.BadParameter(
                f"command {position} ({text!r}): {error}", param_hint="COMMAND"
            ) from None
    return commands


def _print_text(event: Event) -> None:
    if isinstance(event, Text):
        typer.echo(f"controller: {event.text}", err=True)


def register(app: typer.Typer) -> None:
    """Add ``send`` to the command line."""

    # "mvs -50" unquoted: "-50" is a value, not an option.
    @app.command(context_settings={"ignore_unknown_options": True})
    def send(  # noqa: PLR0917 - Typer reads the options from the parameters
        url: UrlArgument,
        commands: list[str] = typer.Argument(
            ..., help="Commands: 'qd', 'th 270 25', 'mvs -50', or frames such as '#qd!'."
        ),
        checksum: ChecksumOption = False,
        algorithm: AlgorithmOption = DEFAULT_ALGORITHM,
        baudrate: BaudrateOption = None,
        timeout_s: TimeoutOption = 0.5,
        retries: RetriesOption = 2,
        as_json: bool = typer.Option(
            False, "--json", help="One JSON object per command instead of text."
        ),
    ) -> None:
        """Send each command in order and print the decoded replies.

        Every command is checked before anything is sent. Example:
        rovlink send sim:// start "th 270 25" qsa stop
        """
        parsed = _parse_all(commands)
        try:
            client = rovlink.connect(
                url, timeout=timeout_s, retries=retries, checksum=checksum,
                algorithm=algorithm, keepalive=None, baudrate=baudrate, on_stray=_print_text,
            )
        except ValueError as error:
            raise typer.BadParameter(str(error)) from None
        except ConnectionError as error:
            typer.echo(f"error: {error}", err=True)
            raise typer.Exit(1) from None
        with client:
            for command in parsed:
                # What goes on the wire, as it goes: with its checksum in checksum mode.
                sent = command if isinstance(command, bytes) else client.frame_for(command)
                try:
                    if isinstance(command, bytes):
                        replies = client.send_raw(command)
                    else:
                        replies = client.send(command)
                except (ClientError, TimeoutError) as error:
                    typer.echo(f"error: {error}", err=True)
                    raise typer.Exit(1) from None
                if as_json:
                    typer.echo(json.dumps({
                        "command": sent.decode("ascii"),
                        "replies": [_reply_json(reply) for reply in replies],
                    }, ensure_ascii=False))
                else:
                    typer.echo(f"> {sent.decode('ascii')}")
                    for reply in replies:
                        typer.echo(f"< {describe_reply(reply)}")
