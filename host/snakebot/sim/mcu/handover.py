"""The emulated bootloader's GO, on the emulated CM-530: the image the bootloader received
starts on the emulated STM32F103RE, and the bootloader's serial line is handed to its
USART3, as on the board, where bootloader and application share the PC link. An image the
board could not start (:func:`snakebot.sim.mcu.image.check_image`) is refused with
:class:`~snakebot.sim.mcu.errors.ImageError` before anything runs; the bootloader's server
then leaves the line silent, as a board whose application does not run.

The image starts from what a bootloader may leave running when it jumps
(:meth:`~snakebot.sim.mcu.board.Leftovers.every`: the PLL, USART3 armed with a byte
pending, SysTick, interrupts masked): the ROBOTIS bootloader's code is not run, so the
application is made to cope with all of it, as its cold-boot and leftover tests require."""

from __future__ import annotations

import socket

from snakebot.sim.mcu.board import Leftovers
from snakebot.sim.mcu.image import check_image
from snakebot.sim.mcu.runner import McuFirmware


class McuHandover:
    """A :data:`snakebot.sim.bootloader.Handover`: call it with the received image; it
    returns the connected socket of the running image's PC link."""

    def __init__(self) -> None:
        self.firmware: McuFirmware | None = None

    def __call__(self, image: bytes) -> socket.socket:
        check_image(image, "the image the bootloader received")
        self.close()  # a second GO restarts the board with the new image
        ours, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
        self.firmware = McuFirmware(image, pc_socket=theirs, leftovers=Leftovers.every()).start()
        ours.setblocking(False)
        return ours

    def close(self) -> None:
        if self.firmware is not None:
            self.firmware.stop()
            self.firmware = None
