"""Link counters: what went over the link and what went wrong, for tools to show."""

from __future__ import annotations

from dataclasses import dataclass, fields

__all__ = ["LinkCounters"]


@dataclass(slots=True)
class LinkCounters:
    """Counts since the client connected; ``client.counters`` returns a copy.

    >>> counters = LinkCounters()
    >>> counters.frames_sent += 1
    >>> counters.as_dict()["frames_sent"]
    1
    """

    #: Frames written to the controller (commands and queries, keep-alives and retries included).
    frames_sent: int = 0
    #: Valid response frames received.
    frames_received: int = 0
    #: Queries answered completely.
    replies: int = 0
    #: Query attempts that got no reply in time.
    timeouts: int = 0
    #: Query attempts that were sent again (after a timeout, a corrupt or a lost reply).
    retries: int = 0
    #: Received frames whose checksum was missing or wrong.
    checksum_errors: int = 0
    #: Received frames dropped for any reason (checksum errors included).
    bad_frames: int = 0
    #: Valid frames that answered no pending query.
    stray_frames: int = 0
    #: Lines of text between frames (the controller's debug output, or line noise).
    text_lines: int = 0
    #: Keep-alive queries sent because the link was idle.
    keepalives: int = 0
    #: Replies that came after their query had failed: discarded, never handed on (P20).
    late_replies: int = 0
    #: Fence queries sent to resynchronise after a failed query (P20).
    fences: int = 0
    #: Times consecutive timeouts made the session suspect a controller reset (P21).
    resets_suspected: int = 0
    #: Times an unrenewed motion command was expired with zero thrust (P23).
    motion_expiries: int = 0
    #: Bytes of line noise: dropped frames and text that is not printable (not debug output).
    noise_bytes: int = 0
    bytes_sent: int = 0
    bytes_received: int = 0

    def copy(self) -> LinkCounters:
        """An independent snapshot.

        >>> LinkCounters(timeouts=2).copy().timeouts
        2
        """
        return LinkCounters(**self.as_dict())

    def as_dict(self) -> dict[str, int]:
        """The counters by name, in declaration order.

        >>> list(LinkCounters().as_dict())[:3]
        ['frames_sent', 'frames_received', 'replies']
        """
        return {field.name: getattr(self, field.name) for field in fields(self)}
