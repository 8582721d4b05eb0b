"""Uploading a gait table to the controller, checked end to end.

    report = upload_gait(ctl, read_gait("walk.gait"), on_progress=print)

1. Before anything is sent: the device must be a snakebot controller of our control-table
   version; the table must fit what its control table takes (Upload Length's range, Joint
   Count's range) and what its board holds (Table Capacity); and, when the controller
   already has a roster, the table may name only servos in it (``allow_new_servos``
   lifts that).
2. The chunk WRITEs and the commit go out as one stream with several packets in flight
   (:mod:`snakebot.controller.transfer`); each is acknowledged. A shortfall of
   acknowledgements, or a commit that found the staged bytes incomplete or damaged,
   sends the whole table again, up to ``retries`` times.
3. Success only once the controller's own figures agree: Upload Result OK, and the active
   table's size and CRC-32 (``Table Size``, ``Table CRC``) equal the file's.

On failure the Error Flags and Upload Result are read and given in words with the fix.
The controller replaces its table only after a commit has checked the whole new one, so
whatever happens on the wire, it keeps either its previous table or the complete new one.
"""

from __future__ import annotations

import time
import zlib
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

from snakebot import protocol
from snakebot.controller import words
from snakebot.controller.client import ControllerClient, JointRecord
from snakebot.controller.errors import ControllerError, ControllerLinkError, UploadError
from snakebot.controller.settings import resolve_upload_retries, resolve_upload_window
from snakebot.controller.transfer import StreamResult, stream_writes
from snakebot.controller.upload import LONG_CHUNK_PAGE, chunk_limit, chunk_writes, commit_write
from snakebot.gaittable import GaitTable
from snakebot.program import Program
from snakebot.transport.timing import BITS_PER_BYTE

VERIFY_REGISTERS = (
    "State",
    "Upload Result",
    "Error Flags",
    "Joint Count",
    "Table Size",
    "Table CRC",
    "Table Joints",
    "Table Flags",
    "Table Frames",
    "Table Period",
)

BEFORE_REGISTERS = ("State", "Joint Count", "Table Size", "Table CRC")
"""What the upload needs to know beforehand (one READ; every byte costs link time)."""

CAPACITY = "Table Capacity"
"""The register (Program page) with the largest table this controller's board takes."""

ProgressCallback = Callable[[int, int], None]  # (table bytes acknowledged, table bytes)
RetryCallback = Callable[[int, int, str], None]  # (attempt about to start, attempts, why)


@dataclass
class UploadReport:
    """What an upload did, in the controller's own figures."""

    bytes: int
    crc: int
    chunks: int
    packets: int
    seconds: float
    attempts: int
    baudrate: int
    joints: int
    frames: int
    period_ms: int
    loop: bool
    roster_before: list[int] = field(default_factory=list)
    new_servos: list[int] = field(default_factory=list)
    playback_stopped: bool = False
    previous_crc: int | None = None
    sent_bytes: int = 0
    """Bytes of the chunk and commit WRITEs put on the link, every attempt counted."""
    chunk_bytes: int = 0
    """Table bytes per chunk WRITE (long chunks when the controller has the page)."""

    @property
    def bytes_per_s(self) -> float:
        """Table bytes per second of the whole upload: checks, transfer and verification."""
        return self.bytes / self.seconds if self.seconds > 0 else float("inf")

    @property
    def paced(self) -> bool:
        """Whether the link ran no faster than its baud rate allows: what was sent took
        at least its wire time. A pseudo-terminal to an emulator (QEMU) carries bytes as
        fast as the processes move them, and then a share of the wire means nothing."""
        return self.seconds >= self.sent_bytes * BITS_PER_BYTE / self.baudrate

    @property
    def wire_fraction(self) -> float:
        """Table bytes per second over what the wire can carry (baud / 10 bits a byte)."""
        return self.bytes_per_s / (self.baudrate / BITS_PER_BYTE)

    def as_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["crc"] = f"0x{self.crc:08x}"
        if self.previous_crc is not None:
            out["previous_crc"] = f"0x{self.previous_crc:08x}"
        out["bytes_per_s"] = round(self.bytes_per_s, 1)
        out["paced"] = self.paced
        if self.paced:
            out["wire_percent"] = round(100 * self.wire_fraction, 1)
        return out

    def summary(self) -> str:
        rate = (
            f"Uploaded {self.bytes} bytes in {self.seconds:.3f} s ({self.bytes_per_s:.0f} bytes/s"
        )
        if not self.paced:
            return (
                f"{rate}; the link carried them faster than {self.baudrate} baud allows, so "
                "it is not a paced serial line and no share of the wire is given)"
            )
        return f"{rate}, {100 * self.wire_fraction:.1f} % of the {self.baudrate} baud wire)"


def check_fits(
    ctl: ControllerClient, table: GaitTable | Program, size: int, capacity: int | None = None
) -> None:
    """ControllerError unless the controller can take ``table``: its control table (Upload
    Length's range, the largest board's) and, when given, the ``capacity`` it reports
    (Table Capacity on the Program page: this board's)."""
    largest = ctl.table.register("Upload Length").max or 0
    if capacity is None or capacity > largest:
        capacity = largest
    if size > capacity:
        raise ControllerError(
            f"the table is {size} bytes but the controller holds at most {capacity} "
            "(its Table Capacity): generate it with fewer frames (a lower rate or a "
            "shorter duration); nothing was sent"
        )
    max_joints = ctl.table.register("Joint Count").max or 0
    if table.joint_count > max_joints:
        raise UploadError(
            f"the table drives {table.joint_count} joints but the controller's roster "
            f"holds at most {max_joints}; nothing was sent"
        )


def check_servos(
    table: GaitTable | Program, roster: list[JointRecord], allow_new: bool
) -> list[int]:
    """The table's servo IDs that the controller's roster does not list; UploadError if
    there are any and ``allow_new`` is False. An empty roster knows no servos: anything
    goes (the commit makes the table's servos the roster)."""
    known = [j.id for j in roster]
    unknown = [i for i in table.joint_ids if i not in known] if known else []
    if unknown and not allow_new:
        raise UploadError(
            f"the table drives servo {_ids(unknown)}, which the controller does not have: "
            f"its roster (from its active table, or set by hand) is servo {_ids(known)}. "
            "Generate the gait for this robot's description, or, if the servos really are "
            "on this robot now, pass --new-servos to let the table replace the roster; "
            "nothing was sent"
        )
    return unknown


def _ids(ids: list[int]) -> str:
    return ("ID " if len(ids) == 1 else "IDs ") + ", ".join(str(i) for i in ids)


def _old_table_words(after: dict[str, int] | None, before: dict[str, int]) -> str:
    if after is None:
        return (
            "The controller only replaces its table after checking the whole new one, so it "
            "still has its previous table"
            + (
                " (none)"
                if before["Table Size"] == 0
                else f" ({before['Table Size']} bytes, CRC 0x{before['Table CRC']:08x})"
            )
            + " unless the commit got through complete; `snakebot monitor` shows which."
        )
    if after["Table Size"] == 0 and before["Table Size"]:
        return (
            "The upload took the place of the controller's previous table in its memory, "
            "so it has no table until an upload completes (a CM-530 loads the one it keeps "
            "in flash at its next start)."
        )
    if after["Table Size"] == 0:
        return "The controller has no table, as before."
    return (
        f"The controller's previous table stays active ({after['Table Size']} bytes, "
        f"CRC 0x{after['Table CRC']:08x})."
    )


def upload_gait(
    ctl: ControllerClient,
    table: GaitTable | Program,
    *,
    retries: int | None = None,
    window: int | None = None,
    allow_new_servos: bool = False,
    on_progress: ProgressCallback | None = None,
    on_retry: RetryCallback | None = None,
) -> UploadReport:
    """Upload ``table`` to the controller and make it the active table (see the module);
    a Program is committed as PROGRAM and takes the table's place."""
    start = time.monotonic()  # the whole command: checks, transfer, verification
    retries = resolve_upload_retries(retries)
    window = resolve_upload_window(window)
    data = table.encode()
    crc = zlib.crc32(data)
    check_fits(ctl, table, len(data))

    ctl.identify()
    before = ctl.read(*BEFORE_REGISTERS, CAPACITY)
    check_fits(ctl, table, len(data), before[CAPACITY])
    roster = ctl.roster(before["Joint Count"]) if before["Joint Count"] else []
    new_servos = check_servos(table, roster, allow_new_servos)

    size = chunk_size(ctl)
    chunks = chunk_writes(data, size, ctl.table, long_chunks=True)
    acked_bytes = [min(len(data), k * size) for k in range(len(chunks) + 1)]
    what = "PROGRAM" if isinstance(table, Program) else "TABLE"
    commit_address, commit_payload = commit_write(data, ctl.table, what=what)
    packets = [protocol.write(ctl.id, address, payload) for address, payload in chunks]
    packets.append(protocol.write(ctl.id, commit_address, commit_payload))

    def on_ack(count: int) -> None:
        # Acknowledgements come in packet order, so the first len(chunks) - 1 can only be
        # for chunks; the next one may be the commit's if a chunk was lost, so it proves
        # one chunk less; the last one proves everything.
        if on_progress is not None:
            confirmed = count if count < len(chunks) else len(chunks) - (count == len(chunks))
            on_progress(acked_bytes[confirmed], len(data))

    attempts = 1 + retries
    why = ""
    after: dict[str, int] | None = None
    sent_bytes = 0
    for attempt in range(1, attempts + 1):
        if attempt > 1 and on_retry is not None:
            on_retry(attempt, attempts, why)
        result = stream_writes(ctl.link, ctl.id, packets, window, on_ack)
        sent_bytes += sum(len(p) for p in packets[: result.sent])
        try:
            after = ctl.read(*VERIFY_REGISTERS)
            elapsed = time.monotonic() - start
        except ControllerLinkError:
            after = None
            why = (
                f"{result.acked} of {len(packets)} WRITEs were acknowledged, then the "
                "controller stopped answering"
            )
            continue
        result_name = words.upload_result_name(after["Upload Result"], ctl.table)
        active = after["Table Size"] == len(data) and after["Table CRC"] == crc
        if active and result_name == "OK" and not result.error:
            return UploadReport(
                bytes=len(data),
                crc=crc,
                chunks=len(chunks),
                packets=len(packets),
                seconds=elapsed,
                attempts=attempt,
                baudrate=ctl.baudrate,
                joints=after["Table Joints"],
                frames=after["Table Frames"],
                period_ms=after["Table Period"],
                loop=bool(after["Table Flags"] & 1),
                roster_before=[j.id for j in roster],
                new_servos=new_servos,
                playback_stopped=words.state_name(before["State"], ctl.table)
                in ("PLAYING", "SERPENOID"),
                previous_crc=before["Table CRC"] if before["Table Size"] else None,
                sent_bytes=sent_bytes,
                chunk_bytes=size,
            )
        if result.error:
            raise _refused(ctl, result, len(packets), after, before)
        if result.complete and result_name not in words.RETRYABLE_RESULTS:
            raise _commit_failed(ctl, after, before)
        why = _shortfall(ctl, result, len(packets), after["Upload Result"])
    raise UploadError(
        f"upload failed after {attempts} attempt{'s' if attempts != 1 else ''}: {why}. "
        + (_flags_words(ctl, after) if after else "")
        + "Check the USB cable and that nothing else uses the port, then upload again "
        "(SNAKEBOT_UPLOAD_RETRIES sets the attempts). " + _old_table_words(after, before)
    )


def chunk_size(ctl: ControllerClient) -> int:
    """Table bytes per chunk WRITE: Upload Data and the window together when the controller
    has window page Upload Data 2, asked with one WRITE of Window Page (a firmware without
    the page refuses it with RANGE); Upload Data alone otherwise."""
    try:
        ctl.show_page(ctl.table.page(LONG_CHUNK_PAGE).number)
    except ControllerLinkError:
        raise
    except ControllerError:
        return chunk_limit(ctl.table)
    return chunk_limit(ctl.table, long_chunks=True)


def _shortfall(ctl: ControllerClient, result: StreamResult, packets: int, code: int) -> str:
    if not result.complete:
        lost = packets - result.acked
        return (
            f"{lost} of {packets} WRITEs got no acknowledgement (lost or damaged on the "
            f"wire{f'; {result.damaged} damaged replies heard' if result.damaged else ''})"
        )
    name, what, _ = words.upload_result_reason(code, ctl.table)
    return f"the commit found {name}: {what}"


def _flags_words(ctl: ControllerClient, after: dict[str, int]) -> str:
    if not after["Error Flags"]:
        return ""
    return f"Controller error flags: {words.describe_flags(after['Error Flags'], ctl.table)}. "


def _commit_failed(
    ctl: ControllerClient, after: dict[str, int], before: dict[str, int]
) -> UploadError:
    name, what, fix = words.upload_result_reason(after["Upload Result"], ctl.table)
    return UploadError(
        f"the controller refused the table at commit ({name}: {what}); "
        + _flags_words(ctl, after)
        + f"{fix}. "
        + _old_table_words(after, before)
    )


def _refused(
    ctl: ControllerClient,
    result: StreamResult,
    packets: int,
    after: dict[str, int],
    before: dict[str, int],
) -> UploadError:
    which = "the commit" if result.error_at == packets - 1 else f"WRITE {result.error_at + 1}"
    if words.upload_result_name(after["Upload Result"], ctl.table) == "NO_ROOM_WHILE_PLAYING":
        what, fix = words.UPLOAD_RESULTS["NO_ROOM_WHILE_PLAYING"]
        return UploadError(f"the controller refused {which} of {packets}: {what}: {fix}")
    return UploadError(
        f"the controller refused {which} of {packets} "
        f"({protocol.ErrorFlags(result.error).describe()}); "
        + _flags_words(ctl, after)
        + "this snakebot and the controller's firmware disagree about the upload window: "
        "flash the firmware built from this snakebot (`snakebot flash`). "
        + _old_table_words(after, before)
    )
