"""Helpers of the flash tests: a plausible CM-530 application image, and the emulated
ROBOTIS bootloader served on a pty without pacing."""

from __future__ import annotations

import random
from pathlib import Path

from snakebot.link.flash.image import identity_block
from snakebot.sim.bootloader import APP_BASE, Bootloader, BootloaderPty


def make_image(path: Path, size: int, seed: int = 1) -> bytes:
    """A plausible CM-530 application: stack at the top of RAM, reset handler inside, the
    identity block after the eight vectors."""
    rng = random.Random(seed)
    vectors = [0x20010000, APP_BASE + 0x101, 0, 0, 0, 0, 0, APP_BASE + 32]
    head = b"".join(v.to_bytes(4, "little") for v in vectors) + identity_block("cm530", 1, size)
    data = head + bytes(rng.randrange(256) for _ in range(size - len(head)))
    path.write_bytes(data)
    return data


def serve(boot: Bootloader, **kwargs) -> BootloaderPty:
    kwargs.setdefault("pace", False)
    return BootloaderPty(boot, **kwargs)
