"""A serial line between QEMU and a pseudo-terminal that never makes QEMU wait.

Given the pty master directly, QEMU writes the firmware's output with a call that retries
until the bytes are taken: once the terminal's buffer is full (a client sends READs and
never reads the replies) the emulated CPU stops inside that write, and the firmware's
control loop with it, which no CM-530 does: its USART sends at the line rate whether or
not the PC reads, and the USB adapter drops what the PC does not take. Here QEMU gets one
end of a socket pair; a thread reads it as fast as QEMU writes and hands the bytes to the
pty master without waiting, dropping (and counting) what the terminal cannot take. The
other way, bytes from the terminal are passed to QEMU as it accepts them, and no faster
than the line's rate where one is given (QEMU's UART takes bytes as fast as they come: a
client that writes without pause would otherwise reach the firmware many times faster
than any wire carries, which no board sees); while QEMU is not accepting, the relay stops
reading the terminal (the client's writes wait, as they would on a full adapter) but keeps
draining QEMU's output.
"""

from __future__ import annotations

import errno
import os
import select
import socket
import time

from snakebot.sim.transports.pump import ServerThread

CHUNK = 65536

TO_QEMU_CHUNK = 256
"""The most the relay takes from the terminal before QEMU has accepted it: what a client
wrote stays in the terminal (where the client can still flush it) rather than here."""

BATCH_S = 0.001
"""The shortest time between two passes of the relay. QEMU writes the firmware's output a
byte at a time: relaying each byte as it comes would keep this thread (and the GIL the
emulated servos' threads need) busy; a pass a millisecond at most takes whatever
accumulated, far below the 0.17 ms a byte takes at 57600 baud times the bytes of a reply."""


BURST_S = 0.004
"""At a line's rate, the most the relay hands QEMU at once: the bytes of this long on the
wire (a pass may come late; what it missed is made up, up to this much)."""


class PtyRelay:
    """Relays between ``sock`` (our end of QEMU's socket pair) and the pty ``master``
    on a daemon thread, from :meth:`start` until :meth:`stop` or either side closes.
    ``rate``: the line's bytes a second towards QEMU (None: as fast as QEMU takes them)."""

    def __init__(
        self, sock: socket.socket, master: int, name: str, rate: float | None = None
    ) -> None:
        self.sock = sock
        self.master = master
        self.rate = rate
        self.dropped = 0
        """Bytes from QEMU the terminal had no room for (lost, as on an adapter)."""
        self.relayed = 0
        """Bytes from QEMU delivered to the terminal."""
        self._thread = ServerThread(name)

    def start(self) -> PtyRelay:
        self.sock.setblocking(False)
        os.set_blocking(self.master, False)
        self._thread.start(self._run)
        return self

    @property
    def error(self) -> BaseException | None:
        """What stopped the thread, if it died."""
        return self._thread.error

    def stop(self) -> None:
        self._thread.stop()
        self.sock.close()

    def _to_terminal(self, data: bytes) -> None:
        try:
            written = os.write(self.master, data)
        except BlockingIOError:
            written = 0
        self.relayed += written
        self.dropped += len(data) - written

    def _run(self) -> None:
        wake = self._thread.wake_fd
        to_qemu = b""
        last_pass = 0.0
        rate = self.rate
        burst = max(1.0, rate * BURST_S) if rate is not None else 0.0
        credit = burst  # bytes the line could carry to QEMU by now
        while True:
            rest = last_pass + BATCH_S - time.monotonic()
            if rest > 0:
                time.sleep(rest)
            now = time.monotonic()
            if rate is not None:
                credit = min(burst, credit + (now - last_pass) * rate)
            last_pass = now
            readers = [self.sock, wake] + ([] if to_qemu else [self.master])
            writers = [self.sock] if to_qemu else []
            ready, writable, _ = select.select(readers, writers, [])
            if wake in ready:
                return
            if self.sock in ready:
                try:
                    data = self.sock.recv(CHUNK)
                except BlockingIOError:
                    data = None
                if data == b"":
                    return  # QEMU has gone
                if data:
                    self._to_terminal(data)
            if self.master in ready:
                try:
                    to_qemu = os.read(self.master, TO_QEMU_CHUNK)
                except BlockingIOError:
                    pass
                except OSError as exc:
                    if exc.errno != errno.EIO:  # EIO: no client has the terminal open
                        raise
            if to_qemu and (self.sock in writable or self.master in ready):
                allowed = len(to_qemu) if rate is None else int(credit)
                try:
                    sent = self.sock.send(to_qemu[:allowed]) if allowed else 0
                except BlockingIOError:
                    sent = 0
                credit -= sent
                to_qemu = to_qemu[sent:]
