"""The ready line's ``tcp HOST:PORT`` for a robot served on TCP: said loudly, and warned of in
the log, when other computers can reach it (the protocol has no authentication); and such an
address refused unless ``--allow-remote`` (``rovlink controller``, ``fault``, ``record --tap``)."""

from __future__ import annotations

from rovlink.cli.failure import UsageError

__all__ = ["REMOTE_MARK", "listen_address", "refuse_remote", "tcp_endpoint"]

#: Follows the address in the ready line when it is not a loopback address.
REMOTE_MARK = "(REMOTE, NO AUTHENTICATION)"


def listen_address(host: str, port: int) -> str:
    """``HOST:PORT`` as an error names an address it could not listen on (the host too when
    the user gave the port alone: which address is busy); an IPv6 host in brackets.

    >>> listen_address("::1", 5760)
    '[::1]:5760'
    """
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


def tcp_endpoint(host: str, port: int, logger_name: str) -> str:
    """``tcp HOST:PORT``; for a listener other computers reach (``0.0.0.0``, a LAN address),
    :data:`REMOTE_MARK` after it and a warning on ``logger_name`` that anyone can drive the robot.

    >>> tcp_endpoint("127.0.0.1", 5760, "rovlink.sim"), tcp_endpoint("::1", 5760, "rovlink.sim")
    ('tcp 127.0.0.1:5760', 'tcp [::1]:5760')
    """
    import logging  # noqa: PLC0415 - kept off the command line's start-up path

    from rovlink.controller.lines import is_loopback  # noqa: PLC0415

    address = listen_address(host, port)  # (an IPv6 host in brackets, as a URL takes it)
    if is_loopback(host):
        return f"tcp {address}"
    everywhere = " (every network interface)" if host in ("0.0.0.0", "::") else ""
    logging.getLogger(logger_name).warning(
        "listening on %s%s for any computer that reaches it; the protocol has no "
        "authentication: anyone connected can drive the robot",
        address,
        everywhere,
    )
    return f"tcp {address} {REMOTE_MARK}"


def refuse_remote(option: str, value: str, host: str, *, allow_remote: bool) -> None:
    """A usage error naming ``option`` and its ``value`` unless ``host`` (an IPv6 one in
    brackets or not) is a loopback address or ``allow_remote`` (``--allow-remote``) is set:
    whoever reaches a robot served there drives it, unauthenticated.

    >>> refuse_remote("--tcp", "5760", "127.0.0.1", allow_remote=False)
    >>> refuse_remote("--tcp", "0.0.0.0:5760", "0.0.0.0", allow_remote=True)
    """
    if allow_remote:
        return
    from rovlink.controller.lines import is_loopback  # noqa: PLC0415

    if not is_loopback(host.strip("[]")):
        raise UsageError(
            f"{option} {value}: {host} is not a loopback address, and the protocol has no "
            "authentication; add --allow-remote to let other computers drive the robot"
        )
