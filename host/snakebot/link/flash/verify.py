"""After GO: the new firmware answers, is the image that was sent, and says so itself.

The controller must answer PING at its ID within ``timeouts.boot``, report the model number
of a snakebot controller and the firmware version the image's identity block carries, and
then, asked with Upload Commit FIRMWARE_CHECK, compute the CRC-32 of its own image in
flash and find it equal to the CRC-32 of the bytes sent (protocol/controller.md).
"""

from __future__ import annotations

import time
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from snakebot.errors import SnakebotError
from snakebot.formats.protocol import DxlTimeout
from snakebot.formats.upload_writes import commit_write
from snakebot.link.controller import UploadResult
from snakebot.link.controller.client import ControllerClient
from snakebot.link.flash.bootloader import RESET_HINT, FlashResult
from snakebot.link.flash.errors import FlashError, FlashFailed
from snakebot.link.flash.image import ImageInfo, image_info
from snakebot.link.flash.settings import FlashTimeouts

PING_EVERY_S = 0.2
"""How often the new firmware is pinged while it starts."""

Waited = Callable[[float], None]

REFLASH = f"flash it again ({RESET_HINT} when asked)"


@dataclass(frozen=True)
class Verified:
    """What the running firmware confirmed."""

    controller_id: int
    model_number: int
    firmware_version: int
    crc: int  # CRC-32 of the image, as the controller computed it over its flash
    boot_seconds: float  # from the start of the wait until the first answer to PING


def _no_answer(controller_id: int, boot_s: float) -> str:
    """Why the started firmware may not answer PING, and what to do, in one line."""
    return (
        f"the new firmware did not answer PING at ID {controller_id} within {boot_s:g} s of "
        "GO: it may not run (an image for another board, damaged, or stopping at start-up) "
        "or the board may have lost power; flash the CM-530's image build/cm530/firmware.bin "
        f"({RESET_HINT} when asked) and check the board's power, or raise "
        "SNAKEBOT_FLASH_BOOT_TIMEOUT_S on a slow machine"
    )


def _wait_for_ping(ctl: ControllerClient, timeouts: FlashTimeouts, waited: Waited) -> float:
    start = time.monotonic()
    while True:
        try:
            ctl.link.ping(ctl.id, retries=0)
            return time.monotonic() - start
        except (DxlTimeout, SnakebotError):
            elapsed = time.monotonic() - start
            if elapsed >= timeouts.boot:
                raise FlashFailed(_no_answer(ctl.id, timeouts.boot)) from None
            waited(elapsed)
            time.sleep(PING_EVERY_S)


def verify_firmware(
    port: str,
    image: bytes,
    info: ImageInfo,
    timeouts: FlashTimeouts,
    waited: Waited = lambda _: None,
) -> Verified:
    """Check the firmware started from ``image`` on the controller at ``port`` (see the
    module), or raise :class:`FlashError` naming what differs and the fix. ``waited`` is
    called with the seconds waited so far while the firmware does not answer yet."""
    with ControllerClient.open(port, retries=1) as ctl:
        boot_s = _wait_for_ping(ctl, timeouts, waited)
        table = ctl.table
        length = table.register("Upload Length")
        if len(image) > length.max:
            raise FlashFailed(
                f"the image is {len(image)} bytes, more than the {length.max} the controller "
                "can be asked to check (Upload Length): it started but is not verified"
            )
        try:
            with ctl.link_errors("the firmware check"):
                found = ctl.read("Model Number", "Firmware Version")
                if found["Model Number"] != table.model_number:
                    raise FlashFailed(
                        f"the device answering at ID {ctl.id} after GO reports model number "
                        f"{found['Model Number']}, not a snakebot controller "
                        f"({table.model_number}): the new firmware did not start; {REFLASH}"
                    )
                if found["Firmware Version"] != info.firmware_version:
                    raise FlashFailed(
                        f"the controller runs firmware version {found['Firmware Version']}, "
                        f"the image sent is version {info.firmware_version}: the old firmware "
                        f"is still running (the bootloader kept it); {REFLASH}"
                    )
                ctl.write_block(*commit_write(image, table, what="FIRMWARE_CHECK"))
                result = ctl.read("Upload Result")["Upload Result"]
        except FlashError:
            raise
        except SnakebotError as exc:
            raise FlashFailed(f"checking the new firmware failed: {exc}") from None
    if result != UploadResult.OK:
        name = UploadResult(result).name if result in UploadResult._value2member_map_ else result
        raise FlashFailed(
            f"the controller finds its firmware in flash differs from the image sent "
            f"(Upload Result {name}): flash was written wrongly or another image runs; "
            f"{REFLASH}"
        )
    return Verified(ctl.id, found["Model Number"], info.firmware_version, zlib.crc32(image), boot_s)


def verify_flashed(
    port: str,
    image: bytes,
    app_base: int,
    timeouts: FlashTimeouts,
    say: Callable[[str], None] = lambda _: None,
) -> Verified | None:
    """Wait for the firmware started from ``image`` (linked at ``app_base``) and have it
    check its image (:func:`verify_firmware`), saying what happens; None when the image
    carries no identity block (flashed without the image checks): nothing to check it
    against."""
    info = image_info(image, app_base)
    if info is None:
        say(
            "Not verified: the image has no snakebot identity block (flashed without the "
            "image checks)."
        )
        return None
    say(f"Waiting up to {timeouts.boot:g} s for the new firmware to answer PING...")
    shown = [0]

    def waited(seconds: float) -> None:
        if int(seconds) > shown[0]:
            shown[0] = int(seconds)
            say(f"  no answer yet after {shown[0]} s")

    verified = verify_firmware(port, image, info, timeouts, waited)
    say(
        f"Verified: controller at ID {verified.controller_id} runs firmware version "
        f"{verified.firmware_version}, its image in flash has CRC-32 0x{verified.crc:08X} "
        "as sent"
    )
    return verified


def flash_summary(
    firmware: str, port: str, result: FlashResult, verified: Verified | None
) -> dict[str, Any]:
    """What one flash of ``firmware`` through ``port`` did, JSON-able: the transfer, the
    bootloader's checksum, GO, and what the started firmware confirmed (``verified``, if
    checked)."""
    return {
        "firmware": firmware,
        "port": port,
        "image_bytes": result.image_size,
        "bytes_sent": result.bytes_sent,
        "checksum_byte": result.checksum_byte,
        "checksum": result.reported_checksum,
        "checksum_meaning": result.checksum_meaning,
        "seconds": round(result.seconds, 4),
        "send_seconds": round(result.send_seconds, 4),
        "kbit_s": round(result.kbit_s, 2),
        "started": result.started,
        "banner": result.banner.decode("latin-1"),
        "go_reply": result.go_reply.decode("latin-1"),
        "verified": verified is not None,
        "firmware_crc": None if verified is None else verified.crc,
        "boot_seconds": None if verified is None else round(verified.boot_seconds, 3),
    }
