"""How long a Protocol 1.0 transaction may take on the wire, from first principles.

A reply is due after the instruction has been clocked out, the servo has waited its
Return Delay Time, and the status packet has been clocked back in; a USB-serial adapter
then holds received bytes for up to its latency timer before the host sees them, and
the host itself may be scheduled late. Each of those terms is named here, so a timeout
grows with the baud rate and the packet lengths instead of being one magic number.

The defaults a user may override (latency, margin, return delay, echo probe) are rows of
the one table of environment variables, :mod:`snakebot.settings`, in the variables'
units; they are named here in seconds.

8N1 framing puts 10 bits on the wire per byte (start, 8 data, stop). On a half-duplex
bus the echo of the instruction is heard while it is being sent, so it adds no time.
"""

from __future__ import annotations

from dataclasses import dataclass

from snakebot.formats.protocol.instructions import BITS_PER_BYTE
from snakebot.settings import default_float

DEFAULT_BAUDRATE = 1_000_000
"""AX-12 factory setting (Baud Rate register = 1)."""

DEFAULT_RETURN_DELAY_US = default_float("SNAKEBOT_RETURN_DELAY_US")
"""AX-12 factory Return Delay Time: register value 250 x 2 us."""

USB_LATENCY_S = default_float("SNAKEBOT_LATENCY_MS") / 1e3
"""An FTDI adapter's default latency timer: received bytes may wait this long in the
adapter before they are sent to the host. Override with ``SNAKEBOT_LATENCY_MS``
(1 ms suits an adapter whose latency timer was lowered, 0 a native UART)."""

HOST_MARGIN_S = default_float("SNAKEBOT_MARGIN_MS") / 1e3
"""Allowance for the host operating system scheduling us late. Override with
``SNAKEBOT_MARGIN_MS``."""

PROGRAM_MARGIN_S = 0.5
"""Allowance when the device at the far end is a program on this host (the emulated
controller under QEMU behind a pseudo-terminal): it answers within a millisecond or two,
unless the host deschedules it for a while on a busy machine, for far longer than a UART
ever stalls. ``SNAKEBOT_MARGIN_MS`` overrides it too."""

ECHO_PROBE_MIN_S = default_float("SNAKEBOT_ECHO_PROBE_MS") / 1e3
"""The shortest wait for the echo of the broadcast PING that "auto" echo detection sends
once, when its first exchange is ambiguous. Missing that echo would make the client
believe the bus does not echo, so this wait is generous; it is paid at most once per
connection, and only on a bus that does not echo. Override with
``SNAKEBOT_ECHO_PROBE_MS``."""

STATUS_OVERHEAD = 6
"""Bytes in a status packet besides its parameters: FF FF ID LEN ERR ... CHK."""


def wire_time_s(nbytes: int, baudrate: int) -> float:
    """Seconds to clock ``nbytes`` bytes through an 8N1 UART at ``baudrate``."""
    if baudrate <= 0:
        raise ValueError(f"baud rate must be positive, got {baudrate}")
    if nbytes < 0:
        raise ValueError(f"byte count must not be negative, got {nbytes}")
    return nbytes * BITS_PER_BYTE / baudrate


def reply_timeout_s(
    tx_len: int,
    rx_len: int,
    baudrate: int,
    *,
    return_delay_us: float = DEFAULT_RETURN_DELAY_US,
    latency_s: float = USB_LATENCY_S,
    margin_s: float = HOST_MARGIN_S,
) -> float:
    """The longest a healthy servo may take to answer, counted from the host's write.

    ``tx_len`` is the instruction packet's length and ``rx_len`` the expected status
    packet's, both in bytes::

        (tx_len + rx_len) * 10 / baudrate + return_delay_us * 1e-6 + latency_s + margin_s
    """
    if return_delay_us < 0 or latency_s < 0 or margin_s < 0:
        raise ValueError("return delay, latency and margin must not be negative")
    return wire_time_s(tx_len + rx_len, baudrate) + return_delay_us * 1e-6 + latency_s + margin_s


@dataclass(frozen=True)
class BusTiming:
    """The timing terms of one bus, applied to each transaction's packet lengths."""

    baudrate: int = DEFAULT_BAUDRATE
    return_delay_us: float = DEFAULT_RETURN_DELAY_US
    latency_s: float = USB_LATENCY_S
    margin_s: float = HOST_MARGIN_S

    def reply_timeout_s(self, tx_len: int, params_len: int) -> float:
        """Timeout for an instruction of ``tx_len`` bytes answered with ``params_len``
        parameter bytes."""
        return reply_timeout_s(
            tx_len,
            STATUS_OVERHEAD + params_len,
            self.baudrate,
            return_delay_us=self.return_delay_us,
            latency_s=self.latency_s,
            margin_s=self.margin_s,
        )
