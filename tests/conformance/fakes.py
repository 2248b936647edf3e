"""Deliberately broken controllers: the simulated one with one fault each, behind a port.

Each fault rewrites the bytes going into the simulated controller or coming out of it, the way a
firmware with that bug would behave on the wire. :data:`FAULTS` maps each fault's name to the
conformance check that must catch it.
"""

from __future__ import annotations

import dataclasses
import re
import threading
import time

from rovlink.controller import ControllerConfig
from rovlink.protocol import COMMANDS, get_algorithm
from rovlink.sim.port import SimulatedPort, open_port
from rovlink.sim.robot import SimConfig

__all__ = ["FAULTS", "NO_FAULT", "FaultyController"]

#: The wrapper without a fault: it must pass every check (so the faults alone fail them).
NO_FAULT = "none"

_CRC8 = get_algorithm("crc8")
_SETTERS = tuple(spec.name.encode() for spec in COMMANDS if not spec.is_query)
_FRAME = re.compile(rb"#([^#$!]*)!")
#: A frame whose checksum has a lowercase hex letter (P2 allows it).
_LOWERCASE_CHECKSUM = re.compile(rb"#[^#!]*(?:[a-f][0-9a-f]|[0-9][a-f])!")
#: The debug lines of settings the C reference left out before it was fixed: all but those
#: of dropped frames, the checksum and debug modes, the lock and the vertical mode.
_SETTING_LINE = re.compile(
    rb"debug: (?!dropped|checksum mode|debug output|motors|stop|vertical mode)[^\r]*\r\n"
)


class FaultyController:
    """A pyserial-like port to the simulated controller, with one named fault."""

    def __init__(self, fault: str, *, seed: int = 1, late_s: float = 0.0) -> None:
        """``late_s``: every reply goes out this late (a controller slower than the suite
        waits), whatever the fault."""
        if fault not in FAULTS and fault != NO_FAULT:
            raise ValueError(f"unknown fault {fault!r}")
        self.fault = fault
        self._late_s = late_s
        if fault == "no-watchdog":  # a firmware without the link-loss failsafe (P17)
            config = SimConfig(controller=dataclasses.replace(ControllerConfig(), watchdog_s=0.0))
            self._inner = SimulatedPort(config, seed=seed, timeout=0)
            self._inner.start()
        else:
            self._inner = open_port(seed=seed, timeout=0)
        self.timeout: float | None = None
        self.name = f"faulty controller ({fault})"
        self._lock = threading.Condition()
        self._output = bytearray()
        self._release_at = 0.0
        self._checksum = False  # the mode as the faulty firmware tracks it
        self._frame_open = False  # no-resync: inside a frame that a start character spoilt
        self._spoilt = False
        # stop-keeps-set-points: the lock and the last direct-mode thrust, as that firmware
        # tracks them (its #stop! locks without clearing them).
        self._unlocked = False
        self._direct = False
        self._thrust: bytes | None = None
        self._zero: int | None = None  # the calibration sent (depth-off-by-one-count, -rounded)
        self._error_lines = b""  # error-line-with-debug-off: written after the next reply
        self._hung = False  # hangs-on-overlong: it took a frame over 64 bytes
        self._k: int | None = None
        if fault in ("watchdog-fed-by-noise", "watchdog-fed-by-motion-only"):
            # Its own failsafe: fed by any byte at all, or only by motion commands.
            config = SimConfig(controller=dataclasses.replace(ControllerConfig(), watchdog_s=0.0))
            self._inner.close()
            self._inner = SimulatedPort(config, seed=seed, timeout=0)
            self._inner.start()
            self._last_byte_s = time.monotonic()
            threading.Thread(target=self._own_watchdog, daemon=True).start()

    # -- the pyserial subset -------------------------------------------------------------------

    @property
    def is_open(self) -> bool:
        return self._inner.is_open

    @property
    def in_waiting(self) -> int:
        self._pull()
        return len(self._output) if time.monotonic() >= self._release_at else 0

    def write(self, data: bytes) -> int:
        if self.fault == "hangs-on-overlong" and re.search(rb"#[^#$!]{64,}!", data):
            self._hung = True  # a line buffer overrun that crashed it: it never answers again
        if self._hung:
            return len(data)
        with self._lock:
            before = self._checksum
            incoming = self._incoming(bytes(data))
            self._inner.write(incoming)
            reply = self._inner.read(self._inner.in_waiting)
            self._deliver(self._outgoing(reply, data, before))
        return len(data)

    def read(self, size: int = 1) -> bytes:
        deadline = time.monotonic() + (self.timeout or 0.0)
        while True:
            self._pull()
            with self._lock:
                if self._output and time.monotonic() >= self._release_at:
                    data = bytes(self._output[:size])
                    del self._output[:size]
                    return data
            if time.monotonic() >= deadline:
                return b""
            time.sleep(0.0005)

    def close(self) -> None:
        self._inner.close()

    # -- the faults ----------------------------------------------------------------------------

    def _pull(self) -> None:
        with self._lock:
            spontaneous = (
                self._inner.read(self._inner.in_waiting) if self._inner.in_waiting else b""
            )
            if spontaneous:
                self._deliver(self._outgoing(spontaneous, b"", self._checksum))

    def _deliver(self, data: bytes) -> None:
        if not data:
            return
        if self.fault == "slow-replies":
            self._release_at = time.monotonic() + 0.015
        if self._late_s:
            threading.Timer(self._late_s, self._deliver_late, args=(data,)).start()
            return
        self._output += data

    def _deliver_late(self, data: bytes) -> None:
        with self._lock:
            self._output += data

    def _own_watchdog(self) -> None:
        while self._inner.is_open:
            time.sleep(0.05)
            with self._lock:
                if self._unlocked and time.monotonic() - self._last_byte_s > _WATCHDOG_S:
                    self._inner.write(b"#stop!")
                    self._unlocked = False

    def _track_lock(self, data: bytes) -> bytes:
        """The lock and thrust as the faulty firmware keeps them; a #start! after #stop!
        brings the last thrust back (stop-keeps-set-points)."""
        out = bytearray()
        position = 0
        for match in _FRAME.finditer(data):
            out += data[position : match.end()]
            position = match.end()
            body = match[1]
            if self._checksum and body not in (b"crcon", b"crcoff", b"stop") and len(body) > 2:
                body = body[:-2]
            if body == b"stop":
                self._unlocked = False
            elif body == b"start":
                resumes = self.fault == "stop-keeps-set-points" and self._direct
                if resumes and self._thrust and not self._unlocked:
                    out += _frame(b"mvdirect.1", self._checksum)
                    out += _frame(b"mvs." + self._thrust, self._checksum)
                self._unlocked = True
            elif body.startswith(b"mvdirect."):
                self._direct = body.endswith(b"1")
            elif body.startswith(b"mvs.") and self._unlocked and self._direct:
                self._thrust = body[4:]
        out += data[position:]
        return bytes(out)

    def _while_locked(self, data: bytes) -> bytes:
        """locked-keeps-set-points: an ``mvs`` sent while locked is kept, and the next
        ``#start!`` obeys it. depth-hold-while-locked: the lock gates ``mvs``, ``th`` and the
        claw but not ``mvd``, whose depth hold drives the thrusters locked or not."""
        out = bytearray()
        position = 0
        for match in _FRAME.finditer(data):
            out += data[position : match.start()]
            position = match.end()
            body, frame = match[1], match[0]
            if body == b"stop":
                self._unlocked = False
            elif body == b"start":
                if self._thrust is not None and not self._unlocked:
                    frame += _frame(b"mvs." + self._thrust, False)
                self._thrust = None
                self._unlocked = True
            elif body.startswith(b"mvs.") and not self._unlocked:
                if self.fault == "locked-keeps-set-points":
                    self._thrust = body[4:]
            elif (
                body.startswith(b"mvd.")
                and not self._unlocked
                and self.fault == "depth-hold-while-locked"
            ):
                frame = b"#start!" + frame  # (the simulated controller's lock lifted)
            out += frame
        out += data[position:]
        return bytes(out)

    def _incoming(self, data: bytes) -> bytes:
        fault = self.fault
        if fault == "watchdog-fed-by-noise" or (
            fault == "watchdog-fed-by-motion-only" and _MOTION_FRAME.search(data)
        ):
            self._last_byte_s = time.monotonic()
        for name, value in re.findall(rb"#(sdz|sdk)\.(\d{1,5})!", data):
            if name == b"sdz" and int(value) <= 1024:
                self._zero = int(value)
            elif name == b"sdk" and int(value) <= 10000:
                self._k = int(value)
        if fault in (
            "stop-keeps-set-points",
            "watchdog-fed-by-noise",
            "watchdog-fed-by-motion-only",
        ):
            data = self._track_lock(data)
        if fault in ("locked-keeps-set-points", "depth-hold-while-locked"):
            data = self._while_locked(data)
        if fault == "mvd-enters-depth-mode":  # takes mvd in direct mode, switching mode
            data = re.sub(rb"#mvd\.(\d+)!", rb"#mvdirect.0!#mvd.\1!", data)
        if fault == "clamps-motion-out-of-range":
            data = _clamped(data)
        if fault == "clamps-gains-out-of-range":  # #mvpdp.100! taken as #mvpdp.99!
            data = re.sub(
                rb"#(mvpdp|mvpdi|mvpidd)\.(\d+)!",
                lambda m: b"#%s.%d!" % (m[1], min(int(m[2]), 99)),
                data,
            )
        if fault == "short-buffer":  # a 20-byte line buffer: longer frames are lost
            data = re.sub(rb"#[^#$!]{19,}!", b"", data)
        if fault == "mode-per-chunk":  # the checksum mode is switched after the whole chunk
            switch = re.search(rb"#crco(?:n|ff)!", data)
            if switch:
                rest = data[switch.end() :].replace(b"#stop!", b"\x00STOP")
                rest = _FRAME.sub(b"", rest).replace(b"\x00STOP", b"#stop!")
                data = data[: switch.end()] + rest
        if fault == "mode-reaches-back":
            for mode in (b"#crcon!", b"#crcoff!"):
                if mode in data:
                    data = mode + data.replace(mode, b"")
        if fault == "case-insensitive":
            data = data.lower()
        if fault == "no-resync":
            data = self._without_resync(data)
        if fault == "stop-needs-checksum" and self._checksum:
            data = data.replace(b"#stop!", b"")
        if fault == "ignores-stop":  # #stop! has no effect at all, in either mode
            data = data.replace(b"#stop!", b"")
        if fault == "direct-mode-only":
            data = data.replace(b"#mvdirect.0!", b"#mvdirect.1!")
        if fault == "debug-stuck-on":
            data = data.replace(b"#debug0!", b"")
        if fault == "no-checksum-mode":  # a firmware that never had one: #crcon! is unknown
            data = data.replace(b"#crcon!", b"")
        if fault == "uppercase-checksums-only" and self._checksum:
            data = _LOWERCASE_CHECKSUM.sub(
                lambda match: match[0] if match[0] == b"#crcoff!" else b"", data
            )
        if fault == "clamps-out-of-range":
            data = re.sub(rb"#sdz\.(\d{4,})!", lambda m: b"#sdz.%d!" % min(int(m[1]), 1024), data)
            data = re.sub(rb"#sdk\.(\d{5,})!", lambda m: b"#sdk.%d!" % min(int(m[1]), 10000), data)
        if fault == "range-ends-dropped":  # its ranges end one short: sdz 1–1023, sdk 1–9999
            data = data.replace(b"#sdz.1024!", b"#sdz.1025!").replace(b"#sdk.0!", b"#sdk.10001!")
        if fault == "no-length-limit":
            data = re.sub(rb"#sdz\.0{20,}(\d+)!", rb"#sdz.\1!", data)
        if fault == "error-line-with-debug-off" and self._checksum:
            # A line for every frame dropped for its checksum, whatever the debug mode.
            for body in _FRAME.findall(data):
                if body not in (b"crcon", b"crcoff", b"stop") and not _checksum_right(body):
                    self._error_lines += b"E01 bad checksum\r\n"
        if fault == "mode-frames-take-checksum":  # strips a right checksum off #crcon/#crcoff
            for body in (b"crcon", b"crcoff"):
                data = data.replace(b"#" + body + _CRC8.digits(body) + b"!", b"#" + body + b"!")
        if fault == "ignores-checksum-value" and self._checksum:
            data = _FRAME.sub(_recomputed, data)
        for frame in _FRAME.findall(data):
            if frame == b"crcon":
                self._checksum = True
            elif frame == b"crcoff":
                self._checksum = False
        return data

    def _outgoing(self, reply: bytes, sent: bytes, checksum: bool) -> bytes:
        fault = self.fault
        if fault == "acks-sets":
            acks = sum(1 for body in _FRAME.findall(sent) if body.split(b".")[0] in _SETTERS)
            reply += b"$ok!" * acks
        if fault == "text-acks-sets":  # an OK line for every setting, debug on or off
            acks = sum(
                1
                for body in _FRAME.findall(sent)
                if body.split(b".")[0] in _SETTERS and not body.startswith(b"debug")
            )
            reply += b"OK\r\n" * acks
        if fault == "qsa-wrong-order":
            reply = re.sub(rb"(\$qd\.[^!]*!)(\$qr\.[^!]*!)", rb"\2\1", reply)
        if fault == "leading-zeros":
            reply = re.sub(rb"\$qd\.(\d+)!", rb"$qd.0\1!", reply)
        if fault == "unsigned-attitude":
            reply = re.sub(rb"\$qro\.[+-](\d+)!", rb"$qro.\1!", reply)
        if fault == "late-extra-reply":  # answers #qd! again, 50 ms later
            for again in re.findall(rb"\$qd\.[^!$]*!", reply):
                threading.Timer(0.05, self._deliver_late, args=(again,)).start()
        if fault == "extra-reply":
            reply = re.sub(rb"(\$qd\.[^!]*!)", rb"\1\1", reply)
        if fault == "plain-replies-in-checksum-mode" and checksum:
            reply = re.sub(rb"\$([^!$]*)[0-9A-F]{2}!", rb"$\1!", reply)
        if fault == "debug-frame-characters":
            reply = reply.replace(b"<", b"#")
        if fault == "no-debug-lines":
            reply = re.sub(rb"debug: [^\r]*\r\n", b"", reply)
        if fault == "no-setting-debug-lines":
            reply = _SETTING_LINE.sub(b"", reply)
        if self._error_lines:
            reply, self._error_lines = reply + self._error_lines, b""
        if fault in ("depth-off-by-one-count", "depth-rounded") and not checksum:
            reply = re.sub(rb"\$qd\.(\d+)!\$qr\.(\d+)!", self._wrong_depth, reply)
        return reply

    def _wrong_depth(self, match: re.Match[bytes]) -> bytes:
        """P13's depth one raw count off, or rounded instead of floored."""
        raw = int(match[2])
        if self._zero is None or self._k is None:
            return match[0]
        if self.fault == "depth-off-by-one-count":
            depth = (raw - self._zero - 1) * self._k // 100
        else:
            depth = round((raw - self._zero) * self._k / 100)
        return b"$qd.%d!$qr.%d!" % (min(max(depth, 0), 9999), raw)

    def _without_resync(self, data: bytes) -> bytes:
        out = bytearray()
        frame = bytearray()
        for byte in data:
            if self._frame_open:
                frame.append(byte)
                if byte == ord("#"):
                    self._spoilt = True
                elif byte == ord("!"):
                    if not self._spoilt:
                        out += frame
                    self._frame_open = self._spoilt = False
                    frame.clear()
            elif byte == ord("#"):
                self._frame_open = True
                frame = bytearray(b"#")
            else:
                out.append(byte)
        if self._frame_open and not self._spoilt:
            out += frame  # an unfinished frame goes on in the next chunk
            self._frame_open = False
        return bytes(out)


#: The frames that feed the failsafe of the watchdog-fed-by-motion-only firmware.
_MOTION_FRAME = re.compile(rb"#(?:start|th\.|mvs\.|mvd\.|h[+-])")
#: The watchdog of the watchdog-fed-by-noise firmware, s.
_WATCHDOG_S = 2.0
#: The ranges a clamping firmware forces motion and PWM arguments into.
_CLAMP_RANGES: dict[bytes, tuple[int, int]] = {
    b"mgmp": (0, 255),
    b"mvs": (-100, 100),
    b"mvd": (0, 9999),
}


def _frame(body: bytes, checksum: bool) -> bytes:
    return b"#" + body + (_CRC8.digits(body) if checksum else b"") + b"!"


def _clamped(data: bytes) -> bytes:
    """Out-of-range mgmp, mvs and mvd set to the nearest end of their range (P6 forbids it)."""

    def clamp(match: re.Match[bytes]) -> bytes:
        name, value = match[1], int(match[2])
        low, high = _CLAMP_RANGES[name]
        clamped = min(max(value, low), high)
        text = b"%+d" % clamped if name == b"mvs" else b"%d" % clamped
        return b"#" + name + b"." + text + b"!"

    return re.sub(rb"#(mgmp|mvs|mvd)\.([-+]?\d+)!", clamp, data)


def _checksum_right(body: bytes) -> bool:
    """Whether ``body`` ends in the right checksum of the rest (either case, P2)."""
    return len(body) > 2 and _CRC8.digits(body[:-2]) == body[-2:].upper()


def _recomputed(match: re.Match[bytes]) -> bytes:
    body = match[1]
    if body in (b"crcon", b"crcoff") or len(body) < 3:
        return match[0]
    stripped = body[:-2]
    return b"#" + stripped + _CRC8.digits(stripped) + b"!"


#: Each fault and the check that catches it.
FAULTS: dict[str, str] = {
    "acks-sets": "set-mgmp",
    "text-acks-sets": "set-mgmp",
    "qsa-wrong-order": "query-qsa",
    "leading-zeros": "query-qd",
    "unsigned-attitude": "query-qro",
    "extra-reply": "query-qd",
    "late-extra-reply": "query-qd",
    "slow-replies": "reply-time",
    "ignores-checksum-value": "checksum-bad-dropped",
    "error-line-with-debug-off": "checksum-bad-dropped",
    "mode-reaches-back": "checksum-on-per-frame",
    "mode-frames-take-checksum": "checksum-mode-frames-exact",
    "plain-replies-in-checksum-mode": "checksum-replies",
    "no-checksum-mode": "checksum-replies",
    "uppercase-checksums-only": "checksum-lowercase-accepted",
    "debug-frame-characters": "debug-text-clean",
    "no-debug-lines": "debug-text-clean",
    "no-setting-debug-lines": "debug-setting-lines",
    "debug-stuck-on": "debug-off-silent",
    "no-length-limit": "overlong-frame-dropped",
    "hangs-on-overlong": "overlong-frame-dropped",
    "no-resync": "resync-on-start",
    "case-insensitive": "unknown-and-malformed-dropped",
    "clamps-out-of-range": "calibration-out-of-range-not-clamped",
    "range-ends-dropped": "calibration-range-ends-taken",
    "stop-needs-checksum": "stop-locks",
    "ignores-stop": "stop-locks",
    "direct-mode-only": "motion-mode-gating",
    "no-watchdog": "motion-link-loss-failsafe",
    "watchdog-fed-by-noise": "motion-link-loss-failsafe",
    "watchdog-fed-by-motion-only": "motion-link-loss-failsafe",
    "stop-keeps-set-points": "motion-stop-halts",
    "locked-keeps-set-points": "motion-locked-after-stop",
    "depth-hold-while-locked": "motion-locked-after-stop",
    "mvd-enters-depth-mode": "motion-mode-gating",
    "clamps-motion-out-of-range": "motion-out-of-range-not-clamped",
    "clamps-gains-out-of-range": "motion-gains-out-of-range-not-clamped",
    "short-buffer": "longest-frame-accepted",
    "mode-per-chunk": "checksum-on-next-frame",
    "depth-off-by-one-count": "calibration-applies",
    "depth-rounded": "calibration-applies",
}
