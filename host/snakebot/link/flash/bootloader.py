"""The ROBOTIS bootloader's upload sequence, as operations on an open serial port.

The sequence (docs/hardware.md, "Uploading firmware through the ROBOTIS bootloader"):

1. while the user resets the board, send ``#`` about every millisecond until the
   bootloader answers, then wait for it to go quiet at its prompt (:func:`enter_bootloader`);
2. send ``\\nL\\n`` and wait for ``Ready..`` (:func:`start_load`);
3. send the raw image, optionally followed by the low byte of its sum as RoboPlus
   Terminal does (:func:`send_image`);
4. read the bootloader's ``Checksum:`` report and compare it with ours (:func:`read_checksum`,
   :func:`~snakebot.link.flash.report.verify_checksum`; a report in an unknown format is put to
   the caller's ``confirm``);
5. send ``\\nGO\\n`` to start the application (:func:`start_application`).

:func:`flash` runs them all. Each step that fails raises :class:`FlashError` saying what
was sent, what came back, and what to try.
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable
from dataclasses import dataclass

import serial

from snakebot.facts.boards import PC_LINK_BAUD
from snakebot.link.flash.errors import FlashFailed, ImageError
from snakebot.link.flash.image import checksum
from snakebot.link.flash.report import (
    ChecksumMatch,
    ChecksumReport,
    unrecognised_message,
    verify_checksum,
)
from snakebot.link.flash.settings import CHUNK_SIZE, FlashTimeouts

HASH = b"#"
LOAD_COMMAND = b"\nL\n"
READY = b"Ready.."
GO_COMMAND = b"\nGO\n"
CHECKSUM_REPORT = re.compile(rb"Checksum([^\r\n]*)[\r\n]", re.IGNORECASE)
"""The bootloader's report, a whole line: nothing of it is still on its way."""

CHECKSUM_AT_END = re.compile(rb"Checksum([^\r\n]*)$", re.IGNORECASE)
"""The report as the last thing said, accepted once the wait is over."""

RESET_HINT = "press MODE or power-cycle the CM-530"
"""How a user resets the board into its bootloader: it has no button labelled RESET."""

SHOWN_REPLY = 100
"""At most this many characters of a reply, as escaped, are quoted in a message: its end
(what the bootloader said last), short enough that the message keeps its fix within an
error line's bound (``errors.LINE_LIMIT``)."""

WRITE_STALL_S = 2.0
"""The link counts as stalled when the writes fall this far behind the time the line
needs to carry them (10 bits a byte at its baud rate)."""

Say = Callable[[str], None]
Progress = Callable[[int], None]
Confirm = Callable[[str], bool]


def shown(data: bytes) -> str:
    """``data`` as text for a message: printable ASCII kept, the rest escaped."""
    if not data:
        return "(nothing)"
    # the last characters as printed (escapes counted), whole escapes only
    escaped = [repr(c)[1:-1] for c in data.decode("latin-1")]
    kept, size = [], 0
    for piece in reversed(escaped):
        if size + len(piece) > SHOWN_REPLY:
            kept.append("...")
            break
        kept.append(piece)
        size += len(piece)
    return "".join(reversed(kept))


def first_line(data: bytes) -> str:
    """The first line of ``data`` with text in it (leading '#' echoes skipped), for messages."""
    for line in data.replace(HASH, b"").splitlines():
        if line.strip():
            return shown(line.strip())
    return "(nothing)"


def last_line(data: bytes) -> str:
    """The last line of ``data`` with text in it, for messages."""
    lines = [line.strip() for line in data.splitlines() if line.strip()]
    return shown(lines[-1]) if lines else "(nothing)"


def _wire_s(nbytes: int, baudrate: float) -> float:
    return nbytes * 10 / baudrate


class _Listener:
    """Everything the board has said since the listener was made."""

    def __init__(self, port: serial.SerialBase) -> None:
        self.port = port
        self.heard = bytearray()
        self.last_heard = time.monotonic()

    def poll(self, wait: float = 0.0) -> bytes:
        """Read what is waiting, blocking up to ``wait`` seconds for the first byte."""
        port = self.port
        port.timeout = wait
        data = port.read(max(1, port.in_waiting))
        if data:
            more = port.in_waiting
            if more:
                port.timeout = 0
                data += port.read(more)
            self.heard += data
            self.last_heard = time.monotonic()
        return data

    def until(self, pattern: re.Pattern[bytes] | bytes, timeout: float) -> re.Match[bytes] | None:
        """Read until ``pattern`` shows up in what was heard, or ``timeout`` passes."""
        regex = pattern if isinstance(pattern, re.Pattern) else re.compile(re.escape(pattern))
        deadline = time.monotonic() + timeout
        while True:
            found = regex.search(self.heard)
            if found:
                return found
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return None
            self.poll(min(remaining, 0.05))


def enter_bootloader(
    port: serial.SerialBase, timeouts: FlashTimeouts, say: Say = lambda _: None
) -> bytes:
    """Send ``#`` until the bootloader answers, then wait until it goes quiet.

    Returns everything it said (banner and prompt). Raises :class:`FlashError` if nothing
    answers within ``timeouts.reset`` or the board keeps talking past
    ``timeouts.quiet_timeout``.
    """
    port.reset_input_buffer()
    listener = _Listener(port)
    say(
        f"Press MODE on the CM-530 or power-cycle it now (sending '#' for up to "
        f"{timeouts.reset:g} s to catch its bootloader)."
    )
    deadline = time.monotonic() + timeouts.reset
    sent = 0
    while not listener.heard:
        if time.monotonic() >= deadline:
            raise FlashFailed(
                f"no answer from the CM-530 bootloader on {port.name} after {sent} '#' in "
                f"{timeouts.reset:g} s: check the cable and the port, that the board is "
                f"powered, and {RESET_HINT} while this command waits; "
                "close any other program using the port (RoboPlus, a terminal). Allow more "
                "time with SNAKEBOT_FLASH_RESET_TIMEOUT_S"
            )
        _write(port, HASH)
        sent += 1
        listener.poll(timeouts.hash_interval)
    answered = time.monotonic()
    while time.monotonic() - listener.last_heard < timeouts.quiet:
        if time.monotonic() - answered > timeouts.quiet_timeout:
            raise FlashFailed(
                f"the board answered '#' but kept sending for more than "
                f"{timeouts.quiet_timeout:g} s ({shown(bytes(listener.heard))}): that is not "
                f"the bootloader's prompt (an application that prints?); {RESET_HINT} "
                "while snakebot flash waits, or raise SNAKEBOT_FLASH_QUIET_TIMEOUT_S"
            )
        listener.poll(min(timeouts.quiet, 0.05))
    return bytes(listener.heard)


def start_load(port: serial.SerialBase, timeouts: FlashTimeouts) -> bytes:
    """Send the load command and wait for ``Ready..``; returns what the bootloader said."""
    port.reset_input_buffer()
    listener = _Listener(port)
    _write(port, LOAD_COMMAND)
    if listener.until(READY, timeouts.ready) is None:
        raise FlashFailed(
            f"the bootloader did not answer the load command (\\nL\\n) with 'Ready..' "
            f"within {timeouts.ready:g} s; it said: {shown(bytes(listener.heard))}. Run "
            f"snakebot flash again and {RESET_HINT} when asked; if it keeps failing, open the "
            f"port in a terminal at {PC_LINK_BAUD} baud, send '#' while resetting and type L "
            "to see what the bootloader says"
        )
    time.sleep(timeouts.ready_settle)
    return bytes(listener.heard)


def _write(port: serial.SerialBase, data: bytes) -> None:
    """Write a command; a port that will not take it within WRITE_STALL_S is an error."""
    port.write_timeout = _wire_s(len(data), float(port.baudrate)) + WRITE_STALL_S
    try:
        port.write(data)
    except serial.SerialTimeoutException:
        raise FlashFailed(
            f"the port {port.name} does not take data (a {len(data)} byte write did not "
            f"finish in {port.write_timeout:.1f} s): check that the adapter is working and "
            "that no flow control is holding it"
        ) from None
    finally:
        port.write_timeout = None


def _unsent(port: serial.SerialBase) -> int:
    """Bytes the driver still holds for the wire (0 where the port cannot tell)."""
    try:
        return int(port.out_waiting)
    except (AttributeError, NotImplementedError, OSError, serial.SerialException):
        return 0


def send_image(
    port: serial.SerialBase,
    payload: bytes,
    progress: Progress = lambda _: None,
    chunk_size: int = CHUNK_SIZE,
) -> float:
    """Write ``payload`` in chunks and wait until the driver has sent it all.

    ``progress(n)`` is called with the number of bytes newly gone from the driver (written
    and no longer waiting in its output queue), so a progress bar shows the wire, not the
    buffer. Returns the seconds from the first write until the driver says the last byte
    left (a pseudo-terminal or an adapter's FIFO may still hold some).
    """
    baud = float(port.baudrate)
    start = time.monotonic()
    reported = 0
    written = 0
    try:
        for offset in range(0, len(payload), chunk_size):
            chunk = payload[offset : offset + chunk_size]
            # Buffers on the way (driver, pty, adapter) may take bytes far ahead of the
            # wire and then hold the writer back: a stall is only being behind the
            # line's own schedule by more than WRITE_STALL_S.
            due = start + _wire_s(written + len(chunk), baud) + WRITE_STALL_S
            port.write_timeout = max(0.05, due - time.monotonic())
            port.write(chunk)
            written += len(chunk)
            gone = written - _unsent(port)
            if gone > reported:
                progress(gone - reported)
                reported = gone
        deadline = start + _wire_s(written, baud) + WRITE_STALL_S
        while True:
            gone = written - _unsent(port)
            if gone > reported:
                progress(gone - reported)
                reported = gone
            if reported >= written:
                break
            if time.monotonic() > deadline:
                raise serial.SerialTimeoutException("output queue not draining")
            time.sleep(min(0.01, _wire_s(written - reported, baud)))
        port.flush()  # and wait for the driver to put it on the wire (tcdrain)
    except serial.SerialTimeoutException:
        raise FlashFailed(
            f"the link stopped taking data after {reported} of {len(payload)} bytes: check "
            f"the cable, and that nothing else holds the port; then {RESET_HINT} and flash "
            "again"
        ) from None
    finally:
        port.write_timeout = None
    return time.monotonic() - start


def read_checksum(port: serial.SerialBase, nbytes: int, timeouts: FlashTimeouts) -> ChecksumReport:
    """Wait for the ``Checksum:`` report that follows an image of ``nbytes`` bytes."""
    listener = _Listener(port)
    wait = timeouts.checksum_wait(nbytes)
    found = listener.until(CHECKSUM_REPORT, wait) or CHECKSUM_AT_END.search(listener.heard)
    if found is None:
        raise FlashFailed(
            f"the bootloader sent no 'Checksum:' report within {wait:.1f} s after the "
            f"{nbytes} byte image; it said: {shown(bytes(listener.heard))}. The upload did "
            f"not complete: {RESET_HINT} and flash again (a slow adapter may need a longer "
            "SNAKEBOT_FLASH_CHECKSUM_TIMEOUT_S)"
        )
    return ChecksumReport(found.group(1).decode("latin-1"), bytes(listener.heard))


def start_application(port: serial.SerialBase, timeouts: FlashTimeouts) -> bytes:
    """Send GO; returns whatever the board said within ``timeouts.go`` (may be nothing)."""
    port.reset_input_buffer()
    listener = _Listener(port)
    _write(port, GO_COMMAND)
    deadline = time.monotonic() + timeouts.go
    while (remaining := deadline - time.monotonic()) > 0:
        listener.poll(min(remaining, 0.05))
    return bytes(listener.heard)


@dataclass(frozen=True)
class FlashResult:
    """What one flash did, for the CLI to print or emit as JSON."""

    port: str
    image_size: int
    bytes_sent: int
    checksum_byte: int | None  # the appended byte, or None when not sent
    seconds: float  # from the first image byte until the bootloader's checksum report
    send_seconds: float  # from the first image byte until the driver had sent the last
    banner: bytes
    reported_checksum: int | None  # None: a report in an unknown format, accepted by confirm
    checksum_meaning: str
    started: bool
    go_reply: bytes

    @property
    def kbit_s(self) -> float:
        """Payload throughput in kbit/s (8 bits a byte) over :attr:`seconds`: confirmed
        delivery, so it includes the silence after which the bootloader reports."""
        return self.bytes_sent * 8 / 1000 / max(self.seconds, 1e-6)


def flash(
    port: serial.SerialBase,
    image: bytes,
    *,
    checksum_byte: bool = True,
    go: bool = True,
    timeouts: FlashTimeouts | None = None,
    say: Say = lambda _: None,
    progress: Progress = lambda _: None,
    confirm: Confirm = lambda _: False,
) -> FlashResult:
    """Flash ``image`` through the bootloader on the open ``port`` (57600 8N1).

    A checksum report in a format this module does not know is put to ``confirm`` (the
    warning as its argument): True starts the firmware anyway, False (the default) stops
    with :class:`FlashError`, the board left in its bootloader."""
    timeouts = timeouts or FlashTimeouts.resolve()
    if not image:
        raise ImageError("the firmware image is empty: nothing to flash")
    banner = enter_bootloader(port, timeouts, say)
    say(f"Bootloader answered: {first_line(banner)}")
    start_load(port, timeouts)
    trailer = checksum(image) if checksum_byte else None
    payload = image + (bytes([trailer]) if trailer is not None else b"")
    started = time.monotonic()
    send_seconds = send_image(port, payload, progress)
    report = read_checksum(port, len(payload), timeouts)
    seconds = time.monotonic() - started
    match = _check_report(image, payload, report, confirm)
    go_reply = start_application(port, timeouts) if go else b""
    return FlashResult(
        port=port.name or "",
        image_size=len(image),
        bytes_sent=len(payload),
        checksum_byte=trailer,
        seconds=seconds,
        send_seconds=send_seconds,
        banner=banner,
        reported_checksum=None if match is None else match.value,
        checksum_meaning="unverified (accepted)" if match is None else match.meaning,
        started=go,
        go_reply=go_reply,
    )


def _check_report(
    image: bytes, sent: bytes, report: ChecksumReport, confirm: Confirm
) -> ChecksumMatch | None:
    """The match for a recognised report; None for an unknown one ``confirm`` accepted."""
    if report.recognised:
        return verify_checksum(image, sent, report)
    warning = unrecognised_message(image, sent, report)
    if confirm(warning):
        return None
    raise FlashFailed(
        f"{warning}: the application was NOT started. If the bootloader printed a sum that "
        f"matches ours, flash again accepting an unknown report to start it anyway; "
        f"otherwise {RESET_HINT} and flash again"
    ).about("yes")
