"""Uploading a gait table to the controller, checked end to end.

    report = upload_gait(ctl, read_gait("walk.gait"), on_progress=print)

1. Before anything is sent, the table must fit the controller's control table (Upload
   Length's and Joint Count's ranges).
2. One stream (:mod:`snakebot.link.controller.upload_stream`, several packets in flight on the
   full-duplex link) carries the checks, the chunk WRITEs, the commit and the
   verification READ. The checks go first: one READ of the head of the control table
   (who answers: a snakebot controller of our control-table version; what it holds now),
   Table Capacity (the largest table its board holds) and, when it has a roster, the
   roster (the table may name only servos in it unless ``allow_new_servos``). Their
   answers come back while the first chunks go out and are checked as they arrive; a
   check that fails stops the stream, and since the commit is held until every check
   has passed, the controller keeps its previous table. An answer that did not come
   back is asked again stop-and-wait.
3. Every packet is acknowledged. A shortfall, or a commit that found the staged bytes
   incomplete or damaged, sends the table again, up to ``retries`` times.
4. Success only once the controller's own figures agree: Upload Result OK, and the active
   table's size and CRC-32 (``Table Size``, ``Table CRC``) equal the file's, read right
   after the commit (the controller handles packets in order, so the READ sees what the
   commit made active).

Chunks are long (Upload Data, Window Page and window page Upload Data 2 in one WRITE); a
firmware without that page refuses the first (and those in flight behind it) with RANGE,
staging nothing, and the upload goes on with chunks of Upload Data's size.

On failure the Error Flags and Upload Result are read and given in words with the fix.
The controller replaces its table only after a commit has checked the whole new one, so
whatever happens on the wire, it keeps either its previous table or the complete new one.
"""

from __future__ import annotations

import functools
import time
import zlib
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

from snakebot.formats import protocol
from snakebot.formats.gaittable import GaitTable
from snakebot.formats.program import Program
from snakebot.formats.protocol import ErrorFlags, Packet
from snakebot.formats.upload_writes import chunk_limit, chunk_writes, commit_write
from snakebot.link.controller import messages as words
from snakebot.link.controller.client import IDENTITY_REGISTERS, ControllerClient, JointRecord
from snakebot.link.controller.errors import (
    ControllerLinkError,
    UploadError,
    UploadFailed,
    UploadRefused,
)
from snakebot.link.controller.settings import resolve_upload_retries, resolve_upload_window
from snakebot.link.controller.upload_stream import Ask, StreamResult, stream
from snakebot.link.transport.timing import BITS_PER_BYTE

HEAD_REGISTERS = (*IDENTITY_REGISTERS, "Joint Count", "Table Size", "Table CRC")
"""The stream's first READ: who answers, and the table and roster it has now."""

VERIFY_REGISTERS = (
    "Upload Result",
    "Error Flags",
    "Table Size",
    "Table CRC",
    "Table Joints",
    "Table Flags",
    "Table Frames",
    "Table Period",
)
"""Read right after the commit: its outcome and the active table (one READ)."""

CAPACITY = "Table Capacity"
"""The register (Program page) with the largest table this controller's board takes."""

NOT_COMMITTED = "nothing was committed, so the controller keeps its table"

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
    """Bytes of the upload's streams (checks, chunks, commit, verification) put on the
    link, every attempt counted."""
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
    """UploadRefused unless the controller can take ``table``: its control table (Upload
    Length's range, the largest board's) and, when given, the ``capacity`` it reports
    (Table Capacity on the Program page: this board's)."""
    largest = ctl.table.register("Upload Length").max or 0
    outcome = "nothing was sent" if capacity is None else NOT_COMMITTED
    if capacity is None or capacity > largest:
        capacity = largest
    if size > capacity:
        raise UploadRefused(
            f"the table is {size} bytes but the controller holds at most {capacity} "
            "(its Table Capacity): generate it with fewer frames (a lower rate or a "
            f"shorter duration); {outcome}"
        )
    max_joints = ctl.table.register("Joint Count").max or 0
    if table.joint_count > max_joints:
        raise UploadRefused(
            f"the table drives {table.joint_count} joints but the controller's roster "
            f"holds at most {max_joints}; {outcome}"
        )


def check_servos(
    table: GaitTable | Program, roster: list[JointRecord], allow_new: bool
) -> list[int]:
    """The table's servo IDs that the controller's roster does not list; UploadRefused if
    there are any and ``allow_new`` is False. An empty roster knows no servos: anything
    goes (the commit makes the table's servos the roster)."""
    known = [j.id for j in roster]
    unknown = [i for i in table.joint_ids if i not in known] if known else []
    if unknown and not allow_new:
        raise UploadRefused(
            f"the table drives servo {_ids(unknown)}, which the controller does not have: "
            f"its roster (from its active table, or set by hand) is servo {_ids(known)}. "
            "Generate the gait for this robot's description, or, if the servos really are "
            "on this robot now, let the table replace the roster (new servos allowed); "
            f"{NOT_COMMITTED}"
        ).about("new_servos")
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


def span_ask(
    ctl: ControllerClient,
    start: int,
    length: int,
    take: Callable[[bytes], Sequence[Ask]],
    *,
    after: Callable[[], bool] | None = None,
) -> Ask:
    """A READ of ``length`` bytes from ``start``; ``take`` gets them when an answer without
    error bits arrives. ``after``: the READ follows the WRITE of its window page, and the
    bytes count only if that WRITE says True (it was acknowledged without error). What
    does not count is asked again stop-and-wait (:meth:`_Checks.finish`)."""

    def on_reply(reply: Packet) -> Sequence[Ask]:
        if reply.code or (after is not None and not after()):
            return ()
        return take(reply.params)

    return Ask(protocol.read(ctl.id, start, length), length, on_reply, follows=after is not None)


def read_ask(
    ctl: ControllerClient,
    names: Sequence[str],
    take: Callable[[dict[str, int]], Sequence[Ask]],
    *,
    after: Callable[[], bool] | None = None,
) -> Ask:
    """:func:`span_ask` of the registers ``names`` (of one window page, or of none), which
    ``take`` gets by name."""
    regs = ctl.registers(names)
    start = min(r.address for r in regs)

    def values(data: bytes) -> Sequence[Ask]:
        return take({r.name: r.decode(data[r.address - start : r.end - start]) for r in regs})

    return span_ask(ctl, start, max(r.end for r in regs) - start, values, after=after)


def page_asks(ctl: ControllerClient, page: int, read: Callable[..., Ask]) -> list[Ask]:
    """The WRITE of Window Page = ``page``, then ``read(after=...)``: a READ of the page
    that counts only if the WRITE was acknowledged without error."""
    selector = ctl.table.register("Window Page")
    shown: list[bool] = []

    def on_reply(reply: Packet) -> Sequence[Ask]:
        shown.append(reply.code == 0)
        return ()

    write = protocol.write(ctl.id, selector.address, selector.encode(page))
    return [Ask(write, 0, on_reply), read(after=lambda: shown == [True])]


class _Checks:
    """What must hold before the commit (module docstring, step 2), asked at the head of
    a stream and checked as the answers arrive; :meth:`finish` asks stop-and-wait for
    what did not come back."""

    def __init__(
        self, ctl: ControllerClient, table: GaitTable | Program, size: int, allow_new: bool
    ) -> None:
        self.ctl, self.table, self.size, self.allow_new = ctl, table, size, allow_new
        self.before: dict[str, int] | None = None
        self.capacity: int | None = None
        self.roster: list[JointRecord] | None = None
        self.new_servos: list[int] = []
        self._records: dict[int, JointRecord] = {}

    @property
    def done(self) -> bool:
        return self.before is not None and self.capacity is not None and self.roster is not None

    def asks(self) -> list[Ask]:
        """The packets still to send: the head READ, Table Capacity (its page, then the
        field), and the roster once the head has said how long it is."""
        asks = []
        if self.before is None:
            asks.append(read_ask(self.ctl, HEAD_REGISTERS, self._head))
        if self.capacity is None:
            page = self.ctl.table.page_number(CAPACITY)
            assert page is not None  # a field of the Program page
            asks += page_asks(
                self.ctl, page, functools.partial(read_ask, self.ctl, (CAPACITY,), self._capacity)
            )
        if self.before is not None and self.roster is None:
            asks += self._roster_asks(self.before["Joint Count"])
        return asks

    def finish(self) -> None:
        """Ask stop-and-wait for what the stream did not bring back (link errors and the
        checks' own errors raise as they would from a plain exchange)."""
        if self.before is None:
            self._head(self.ctl.read(*HEAD_REGISTERS))
        if self.capacity is None:
            self._capacity(self.ctl.read(CAPACITY))
        if self.roster is None:
            assert self.before is not None
            self._take_roster(self.ctl.roster(self.before["Joint Count"]))

    def _head(self, values: dict[str, int]) -> Sequence[Ask]:
        self.ctl.check_identity(values)
        self.before = values
        self.roster = None
        if values["Joint Count"] == 0:
            self._take_roster([])
            return ()
        return self._roster_asks(values["Joint Count"])

    def _capacity(self, values: dict[str, int]) -> Sequence[Ask]:
        check_fits(self.ctl, self.table, self.size, values[CAPACITY])
        self.capacity = values[CAPACITY]
        return ()

    def _roster_asks(self, count: int) -> list[Ask]:
        """Per window page of the roster: its WRITE, then a READ of the records shown."""
        table = self.ctl.table
        per_page, size = table.servo_records, table.servo_record_size
        self._records = {}
        asks = []
        for first in range(0, count, per_page):
            page, _ = table.servo_page(first)
            length = min(per_page, count - first) * size
            take = functools.partial(self._records_from, first, count)
            read = functools.partial(span_ask, self.ctl, table.servo_window_address, length, take)
            asks += page_asks(self.ctl, page, read)
        return asks

    def _records_from(self, first: int, count: int, data: bytes) -> Sequence[Ask]:
        """Records ``first``.. of the roster, read from a window page; with the last of
        the ``count`` records the roster is complete and checked."""
        for slot, record in enumerate(self.ctl.table.decode_servo_window(data)):
            self._records[first + slot] = JointRecord.from_record(first + slot, record)
        if len(self._records) == count:
            self._take_roster([self._records[j] for j in range(count)])
        return ()

    def _take_roster(self, roster: list[JointRecord]) -> None:
        self.new_servos = check_servos(self.table, roster, self.allow_new)
        self.roster = roster


class _Chunks:
    """The chunk WRITEs and the commit of one table as asks, reporting progress as
    their acknowledgements come back; the commit waits for ``ready``. ``long`` tells
    whether the chunks pass through Window Page (the first one asks for the page)."""

    def __init__(
        self,
        ctl: ControllerClient,
        data: bytes,
        commit: bytes,
        long_chunks: bool,
        on_progress: ProgressCallback | None,
        ready: Callable[[], bool],
    ) -> None:
        writes = chunk_writes(data, None, ctl.table, long_chunks=long_chunks)
        self.size = chunk_limit(ctl.table, long_chunks=long_chunks)
        self.long = long_chunks and len(data) > chunk_limit(ctl.table)
        total = len(data)
        n = len(writes)
        acked_bytes = [min(total, k * self.size) for k in range(n + 1)]

        def progress(confirmed: int) -> Callable[[Packet], Sequence[Ask]]:
            def on_reply(reply: Packet) -> Sequence[Ask]:
                if on_progress is not None and not reply.code:
                    on_progress(acked_bytes[confirmed], total)
                return ()

            return on_reply

        # Acknowledgements come in packet order, so the first n - 1 can only be for
        # chunks; the next one may be the commit's if a chunk was lost, so it proves one
        # chunk less; the commit's proves everything.
        self.chunks = [
            Ask(protocol.write(ctl.id, a, p), on_reply=progress(min(k + 1, n - 1)))
            for k, (a, p) in enumerate(writes)
        ]
        self.commit = Ask(commit, on_reply=progress(n), ready=ready)


def upload_gait(
    ctl: ControllerClient,
    table: GaitTable | Program,
    *,
    retries: int | None = None,
    window: int | None = None,
    allow_new_servos: bool = False,
    on_progress: ProgressCallback | None = None,
    on_retry: RetryCallback | None = None,
    long_chunks: bool = True,
) -> UploadReport:
    """Upload ``table`` to the controller and make it the active table (see the module);
    a Program is committed as PROGRAM and takes the table's place. ``long_chunks=False``
    sends chunks of Upload Data's size from the start, as to a firmware without the page
    (a reference for benchmarks)."""
    start = time.monotonic()  # the whole command: checks, transfer, verification
    retries = resolve_upload_retries(retries)
    window = resolve_upload_window(window)
    data = table.encode()
    crc = zlib.crc32(data)
    check_fits(ctl, table, len(data))
    checks = _Checks(ctl, table, len(data), allow_new_servos)
    what = "PROGRAM" if isinstance(table, Program) else "TABLE"
    commit = protocol.write(ctl.id, *commit_write(data, ctl.table, what=what))

    attempts = 1 + retries
    attempt = 1
    why = ""
    after: dict[str, int] | None = None
    sent_bytes = 0
    while attempt <= attempts:
        if attempt > 1 and on_retry is not None:
            on_retry(attempt, attempts, why)
        plan = _Chunks(ctl, data, commit, long_chunks, on_progress, lambda: checks.done)
        verified: dict[str, int] = {}

        def keep(values: dict[str, int], into: dict[str, int] = verified) -> Sequence[Ask]:
            into.update(values)
            return ()

        asked = checks.asks()
        asks = [*asked, *plan.chunks, plan.commit, read_ask(ctl, VERIFY_REGISTERS, keep)]
        result = stream(ctl.link, ctl.id, asks, window)
        sent_bytes += result.sent_bytes
        if not checks.done:
            try:
                checks.finish()
            except ControllerLinkError as exc:
                if checks.before is None:
                    raise  # it never answered: the link's own words say what to check
                raise UploadFailed(f"{exc}. {_old_table_words(None, checks.before)}") from None
        if result.error_ask in asked:
            continue  # a check answered with error bits, asked again above: not an attempt
        if plan.long and result.error_ask is plan.chunks[0] and result.error & ErrorFlags.RANGE:
            long_chunks = False  # a firmware without the page: not a failed attempt
            continue
        if result.held:  # the commit waited for answers that never came: nothing committed
            why = _shortfall(ctl, result, 0)
            attempt += 1
            continue
        try:
            after = verified or ctl.read(*VERIFY_REGISTERS)
            elapsed = time.monotonic() - start
        except ControllerLinkError:
            after = None
            why = (
                f"{result.acked} of {result.sent} packets were acknowledged, then the "
                "controller stopped answering"
            )
            attempt += 1
            continue
        assert checks.before is not None and checks.roster is not None
        result_name = words.upload_result_name(after["Upload Result"], ctl.table)
        active = after["Table Size"] == len(data) and after["Table CRC"] == crc
        if active and result_name == "OK" and not result.error:
            return UploadReport(
                bytes=len(data),
                crc=crc,
                chunks=len(plan.chunks),
                packets=len(plan.chunks) + 1,
                seconds=elapsed,
                attempts=attempt,
                baudrate=ctl.baudrate,
                joints=after["Table Joints"],
                frames=after["Table Frames"],
                period_ms=after["Table Period"],
                loop=bool(after["Table Flags"] & 1),
                roster_before=[j.id for j in checks.roster],
                new_servos=checks.new_servos,
                playback_stopped=words.state_name(checks.before["State"], ctl.table)
                in ("PLAYING", "SERPENOID"),
                previous_crc=checks.before["Table CRC"] if checks.before["Table Size"] else None,
                sent_bytes=sent_bytes,
                chunk_bytes=plan.size,
            )
        if result.error:
            raise _refused(ctl, result, plan, after, checks.before)
        if result.complete and result_name not in words.RETRYABLE_RESULTS:
            raise _commit_failed(ctl, after, checks.before)
        why = _shortfall(ctl, result, after["Upload Result"])
        attempt += 1
    before = checks.before or {"Table Size": 0, "Table CRC": 0}
    raise UploadFailed(
        f"upload failed after {attempts} attempt{'s' if attempts != 1 else ''}: {why}. "
        + (_flags_words(ctl, after) if after else "")
        + "Check the USB cable and that nothing else uses the port, then upload again "
        "(SNAKEBOT_UPLOAD_RETRIES sets the attempts). " + _old_table_words(after, before)
    )


def _shortfall(ctl: ControllerClient, result: StreamResult, code: int) -> str:
    if result.held:
        return "the answers to the checks did not all come back, so nothing was committed"
    if not result.complete:
        lost = result.total - result.acked
        return (
            f"{lost} of {result.total} packets got no acknowledgement (lost or damaged on "
            f"the wire{f'; {result.damaged} damaged replies heard' if result.damaged else ''})"
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
    refused = UploadFailed if words.is_runtime_result(name) else UploadRefused
    return refused(
        f"the controller refused the table at commit ({name}: {what}); "
        + _flags_words(ctl, after)
        + f"{fix}. "
        + _old_table_words(after, before)
    )


def _refused(
    ctl: ControllerClient,
    result: StreamResult,
    plan: _Chunks,
    after: dict[str, int],
    before: dict[str, int],
) -> UploadError:
    n = len(plan.chunks)
    which = (
        f"chunk WRITE {plan.chunks.index(result.error_ask) + 1} of {n}"
        if result.error_ask in plan.chunks
        else "the commit"
    )
    if words.upload_result_name(after["Upload Result"], ctl.table) == "NO_ROOM_WHILE_PLAYING":
        what, fix = words.UPLOAD_RESULTS["NO_ROOM_WHILE_PLAYING"]
        return UploadFailed(f"the controller refused {which}: {what}: {fix}")
    return UploadFailed(
        f"the controller refused {which} "
        f"({protocol.ErrorFlags(result.error).describe()}); "
        + _flags_words(ctl, after)
        + "this snakebot and the controller's firmware disagree about the upload window: "
        "flash the firmware built from this snakebot (`snakebot flash`). "
        + _old_table_words(after, before)
    )
