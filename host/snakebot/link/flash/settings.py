"""Every wait of the flasher has a name, a default, and an environment variable that
overrides it (a keyword argument overrides both), as esptool does.

===================================  ==================================  ======================
what                                 environment variable                default
===================================  ==================================  ======================
wait for the bootloader after '#'    SNAKEBOT_FLASH_RESET_TIMEOUT_S      ``RESET_TIMEOUT_S``
pause between two '#'                SNAKEBOT_FLASH_HASH_INTERVAL_S      ``HASH_INTERVAL_S``
silence that ends its banner         SNAKEBOT_FLASH_QUIET_S              ``QUIET_S``
longest it may talk after '#'        SNAKEBOT_FLASH_QUIET_TIMEOUT_S      ``QUIET_TIMEOUT_S``
wait for "Ready.." after L           SNAKEBOT_FLASH_READY_TIMEOUT_S      ``READY_TIMEOUT_S``
pause after "Ready.."                SNAKEBOT_FLASH_READY_SETTLE_S       ``READY_SETTLE_S``
wait for "Checksum:" (base)          SNAKEBOT_FLASH_CHECKSUM_TIMEOUT_S   ``CHECKSUM_TIMEOUT_S``
  ... plus, per 2 KB flash page      SNAKEBOT_FLASH_PAGE_TIME_S          ``PAGE_TIME_S``
wait for an answer to GO             SNAKEBOT_FLASH_GO_TIMEOUT_S         ``GO_TIMEOUT_S``
wait for the new firmware's PING     SNAKEBOT_FLASH_BOOT_TIMEOUT_S       ``BOOT_TIMEOUT_S``
===================================  ==================================  ======================

The checksum wait grows with the image, because the bootloader may still be erasing and
programming flash pages when the last byte has arrived (an STM32F103 page erase takes
up to 40 ms).

The variables, their range and defaults are rows of the one table in
:mod:`snakebot.settings`, which reads and checks them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from snakebot.errors import quoted
from snakebot.link.flash.errors import FlashSettingError
from snakebot.settings import default_float, lookup

RESET_TIMEOUT_S = default_float("SNAKEBOT_FLASH_RESET_TIMEOUT_S")
"""How long to keep sending '#' while the user presses MODE or power-cycles the CM-530."""

HASH_INTERVAL_S = default_float("SNAKEBOT_FLASH_HASH_INTERVAL_S")
"""Pause between two '#' characters (the bootloader only looks for one shortly after reset)."""

QUIET_S = default_float("SNAKEBOT_FLASH_QUIET_S")
"""Silence on the line that means the bootloader has finished its banner and prompt."""

QUIET_TIMEOUT_S = default_float("SNAKEBOT_FLASH_QUIET_TIMEOUT_S")
"""Longest the board may keep talking after it has answered '#'."""

READY_TIMEOUT_S = default_float("SNAKEBOT_FLASH_READY_TIMEOUT_S")
"""How long the bootloader may take to answer the load command with "Ready.."."""

READY_SETTLE_S = default_float("SNAKEBOT_FLASH_READY_SETTLE_S")
"""Pause after "Ready.." before the first image byte (users report the loader needs a moment)."""

CHECKSUM_TIMEOUT_S = default_float("SNAKEBOT_FLASH_CHECKSUM_TIMEOUT_S")
"""Base wait for the "Checksum:" report after the last byte (it reports after a silence)."""

PAGE_TIME_S = default_float("SNAKEBOT_FLASH_PAGE_TIME_S")
"""Added to the checksum wait per 2 KB flash page of the image (erase plus programming)."""

GO_TIMEOUT_S = default_float("SNAKEBOT_FLASH_GO_TIMEOUT_S")
"""How long to listen for the bootloader's answer to GO (not required: the application
may start at once and say nothing)."""

BOOT_TIMEOUT_S = default_float("SNAKEBOT_FLASH_BOOT_TIMEOUT_S")
"""How long the new firmware may take to answer PING after GO (it starts in well under a
second; the rest is for a loaded machine or a slow adapter)."""

CHUNK_SIZE = 256
"""Image bytes written (and flushed) at a time; the progress bar moves per chunk."""

FLASH_PAGE_SIZE = 2048
"""STM32F103RE (high density) flash page size in bytes."""


@dataclass(frozen=True)
class FlashTimeouts:
    """The flasher's waits in seconds (see the module's table)."""

    reset: float = RESET_TIMEOUT_S
    hash_interval: float = HASH_INTERVAL_S
    quiet: float = QUIET_S
    quiet_timeout: float = QUIET_TIMEOUT_S
    ready: float = READY_TIMEOUT_S
    ready_settle: float = READY_SETTLE_S
    checksum: float = CHECKSUM_TIMEOUT_S
    page_time: float = PAGE_TIME_S
    go: float = GO_TIMEOUT_S
    boot: float = BOOT_TIMEOUT_S

    @classmethod
    def resolve(cls, **overrides: float | None) -> FlashTimeouts:
        """Defaults, then the environment, then the keywords that are not None."""
        values: dict[str, float] = {}
        for f in fields(cls):
            value: object = overrides.pop(f.name, None)
            if value is None:
                value = lookup(ENV_NAMES[f.name])
            if value is not None:
                if not (isinstance(value, (int, float)) and 0 <= value < math.inf):
                    raise FlashSettingError(
                        f"flash timeout {f.name} must be a number of seconds >= 0, got "
                        f"{quoted(value)}"
                    )
                values[f.name] = float(value)
        if overrides:
            raise TypeError(f"unknown flash timeouts: {', '.join(sorted(overrides))}")
        return cls(**values)

    def checksum_wait(self, nbytes: int) -> float:
        """How long to wait for "Checksum:" after sending ``nbytes`` bytes."""
        pages = -(-nbytes // FLASH_PAGE_SIZE)
        return self.checksum + pages * self.page_time


ENV_NAMES = {
    "reset": "SNAKEBOT_FLASH_RESET_TIMEOUT_S",
    "hash_interval": "SNAKEBOT_FLASH_HASH_INTERVAL_S",
    "quiet": "SNAKEBOT_FLASH_QUIET_S",
    "quiet_timeout": "SNAKEBOT_FLASH_QUIET_TIMEOUT_S",
    "ready": "SNAKEBOT_FLASH_READY_TIMEOUT_S",
    "ready_settle": "SNAKEBOT_FLASH_READY_SETTLE_S",
    "checksum": "SNAKEBOT_FLASH_CHECKSUM_TIMEOUT_S",
    "page_time": "SNAKEBOT_FLASH_PAGE_TIME_S",
    "go": "SNAKEBOT_FLASH_GO_TIMEOUT_S",
    "boot": "SNAKEBOT_FLASH_BOOT_TIMEOUT_S",
}
