"""How a servo finds instruction packets in what it hears: byte by byte, as the AX-12's
UART interrupt does, with nothing to look back at.

The host's parser (``snakebot.formats.protocol.PacketParser``) keeps the bytes of a packet that
failed its checksum and searches them again from the next byte, so a good packet hidden
inside a damaged one is still found: right for a master waiting for its reply. A servo
cannot work that way without doing harm: when noise turns a LEN byte into a large
value, the frame swallows the next instructions (the master's retries among them), and
rescanning it would execute them all at once, long after they were sent, and answer
with replies the master takes for answers to its current instruction. So here, as in a
byte-at-a-time state machine, a frame with a bad checksum is dropped whole and the
search for a header starts again after it. Headers follow the shared rule (``FF FF``,
and in a run of FFs the last two are the header), impossible LEN values (< 2, or a
packet over ``MAX_PACKET_LEN``) abandon the frame at once, and checksums are the codec's.
"""

from __future__ import annotations

from snakebot.formats.protocol import MAX_PACKET_LEN, Packet, Rejected, checksum

_HEADER1, _HEADER2, _ID, _LEN, _BODY = range(5)


class ServoReceiver:
    """A servo's receive state machine: ``feed`` bytes, get the packets they complete
    (and ``Rejected`` for damaged frames, so a servo can answer a bad checksum)."""

    def __init__(self) -> None:
        self.state = _HEADER1
        """Where in a frame the receiver is: 0 (false) between frames, else looking for
        the rest of one (the bus checks this on every packet; ``pending`` says more)."""
        self._frame = bytearray()
        self._need = 0

    @property
    def pending(self) -> int:
        """Bytes of a frame begun but not finished (0 between frames)."""
        return 0 if self.state == _HEADER1 else len(self._frame) or 1

    def reset(self) -> None:
        """Abandon a frame in progress (e.g. after a pause of over 100 ms)."""
        self.state = _HEADER1
        self._frame.clear()

    def feed(self, data: bytes) -> list[Packet | Rejected]:
        """Hear ``data``; return the events its bytes complete, in order."""
        n = len(data)
        if (
            self.state == _HEADER1
            and n >= 6
            and data[0] == 0xFF
            and data[1] == 0xFF
            and data[2] != 0xFF
            and data[3] + 4 == n
            and n <= MAX_PACKET_LEN
            and checksum(data[2:-1]) == data[-1]
        ):
            return [Packet(data[2], data[4], bytes(data[5:-1]))]  # one clean frame
        events: list[Packet | Rejected] = []
        for b in data:
            self._byte(b, events)
        return events

    def _byte(self, b: int, events: list[Packet | Rejected]) -> None:
        state = self.state
        if state == _HEADER1:
            if b == 0xFF:
                self.state = _HEADER2
        elif state == _HEADER2:
            self.state = _ID if b == 0xFF else _HEADER1
        elif state == _ID:
            if b != 0xFF:  # FF FF FF..: the last two FFs are the header
                self._frame[:] = b"\xff\xff" + bytes((b,))
                self.state = _LEN
        elif state == _LEN:
            self._frame.append(b)
            if b < 2 or b + 4 > MAX_PACKET_LEN:
                events.append(Rejected("length", bytes(self._frame)))
                self.reset()
            else:
                self._need = b
                self.state = _BODY
        else:
            frame = self._frame
            frame.append(b)
            self._need -= 1
            if self._need == 0:
                if checksum(frame[2:-1]) == frame[-1]:
                    events.append(Packet(frame[2], frame[4], bytes(frame[5:-1])))
                else:
                    events.append(Rejected("checksum", bytes(frame)))
                self.reset()
