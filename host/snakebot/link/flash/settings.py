"""Every wait of the flasher has a name, a default, and an environment variable that
overrides it (a keyword argument overrides both), as esptool does.

===================================  ==================================  =======
what                                 environment variable                default
===================================  ==================================  =======
wait for the bootloader after '#'    SNAKEBOT_FLASH_RESET_TIMEOUT_S      20 s
pause between two '#'                SNAKEBOT_FLASH_HASH_INTERVAL_S      1 ms
silence that ends its banner         SNAKEBOT_FLASH_QUIET_S              0.2 s
longest it may talk after '#'        SNAKEBOT_FLASH_QUIET_TIMEOUT_S      3 s
wait for "Ready.." after L           SNAKEBOT_FLASH_READY_TIMEOUT_S      3 s
pause after "Ready.."                SNAKEBOT_FLASH_READY_SETTLE_S       0.05 s
wait for "Checksum:" (base)          SNAKEBOT_FLASH_CHECKSUM_TIMEOUT_S   3 s
  ... plus, per 2 KB flash page      SNAKEBOT_FLASH_PAGE_TIME_S          0.05 s
wait for an answer to GO             SNAKEBOT_FLASH_GO_TIMEOUT_S         0.5 s
wait for the new firmware's PING     SNAKEBOT_FLASH_BOOT_TIMEOUT_S       10 s
===================================  ==================================  =======

The checksum wait grows with the image, because the bootloader may still be erasing and
programming flash pages when the last byte has arrived (an STM32F103 page erase takes
up to 40 ms).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, fields

from snakebot.link.flash.errors import FlashSettingError

RESET_TIMEOUT_S = 20.0
"""How long to keep sending '#' while the user presses MODE or power-cycles the CM-530."""

HASH_INTERVAL_S = 0.001
"""Pause between two '#' characters (the bootloader only looks for one shortly after reset)."""

QUIET_S = 0.2
"""Silence on the line that means the bootloader has finished its banner and prompt."""

QUIET_TIMEOUT_S = 3.0
"""Longest the board may keep talking after it has answered '#'."""

READY_TIMEOUT_S = 3.0
"""How long the bootloader may take to answer the load command with "Ready.."."""

READY_SETTLE_S = 0.05
"""Pause after "Ready.." before the first image byte (users report the loader needs a moment)."""

CHECKSUM_TIMEOUT_S = 3.0
"""Base wait for the "Checksum:" report after the last byte (it reports after a silence)."""

PAGE_TIME_S = 0.05
"""Added to the checksum wait per 2 KB flash page of the image (erase plus programming)."""

GO_TIMEOUT_S = 0.5
"""How long to listen for the bootloader's answer to GO (not required: the application
may start at once and say nothing)."""

BOOT_TIMEOUT_S = 10.0
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
            value = overrides.pop(f.name, None)
            if value is None:
                value = _env_seconds(ENV_NAMES[f.name])
            if value is not None:
                if not (isinstance(value, (int, float)) and 0 <= value < math.inf):
                    raise FlashSettingError(
                        f"flash timeout {f.name} must be a number of seconds >= 0, got {value!r}"
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


def _env_seconds(name: str) -> float | None:
    text = os.environ.get(name, "").strip()
    if not text:
        return None
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0 <= value < 3600:  # also rejects nan
        raise FlashSettingError(
            f"{name}={text!r} is not a number of seconds from 0 to 3600; "
            "set it to e.g. 5 or unset it"
        )
    return value
