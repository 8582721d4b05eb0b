"""What a UART set to one baud rate makes of bytes sent at another.

The line is rebuilt bit by bit (8N1: a low start bit, eight data bits LSB first, a
high stop bit, idle high between frames) and sampled the way a UART receiver does:
wait for a falling edge, check the start bit half a bit later, sample the data bits
at their middles, then the stop bit. A low stop bit is a framing error; like most
UARTs this one still hands the byte over. Receivers within a couple of per cent of
the sender's rate read the bytes correctly (the model gets that right by itself, the
:data:`SAME_BAUD_TOLERANCE` shortcut only saves the work); far off, they read garbage,
which is what an AX-12 left on another baud rate hears.
"""

from __future__ import annotations

SAME_BAUD_TOLERANCE = 0.01
"""Relative baud mismatch below which bytes are passed through unchanged."""

_FRAME_BITS = 10


def same_baud(a: float, b: float) -> bool:
    """Whether receivers at ``a`` and ``b`` read each other's bytes without sampling."""
    return abs(a - b) <= SAME_BAUD_TOLERANCE * max(a, b)


def _level(data: bytes, bit_index: int) -> int:
    frame, bit = divmod(bit_index, _FRAME_BITS)
    if bit_index < 0 or frame >= len(data):
        return 1  # idle
    if bit == 0:
        return 0  # start bit
    if bit == 9:
        return 1  # stop bit
    return (data[frame] >> (bit - 1)) & 1


def resample(data: bytes, tx_baud: float, rx_baud: float) -> list[tuple[float, int]]:
    """The bytes a receiver at ``rx_baud`` hears when ``data`` is sent back to back at
    ``tx_baud`` starting at time 0: a list of (time the byte is complete, byte)."""
    t_tx = 1.0 / tx_baud
    t_rx = 1.0 / rx_baud
    total_bits = len(data) * _FRAME_BITS
    heard: list[tuple[float, int]] = []
    bit = 0  # search for a falling edge from this transmitter bit onwards
    while True:
        # a falling edge: a low bit whose predecessor is high
        while bit < total_bits and not (_level(data, bit) == 0 and _level(data, bit - 1) == 1):
            bit += 1
        if bit >= total_bits:
            return heard
        edge = bit * t_tx

        def sample(k: float, edge: float = edge) -> int:
            return _level(data, int((edge + k * t_rx) / t_tx))

        if sample(0.5) != 0:
            bit += 1  # a glitch, not a start bit
            continue
        value = 0
        for k in range(8):
            value |= sample(1.5 + k) << k
        stop_time = edge + 9.5 * t_rx
        heard.append((stop_time, value))
        # look for the next edge from the stop-bit sample onwards
        bit = max(bit + 1, int(stop_time / t_tx))
