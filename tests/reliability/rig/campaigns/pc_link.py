"""The campaigns on the PC link: noise between the host's packets, and uploads cut short."""

from __future__ import annotations

import random
import time
from collections import Counter

from snakebot.formats import protocol
from snakebot.formats.protocol import (
    Packet,
    PacketParser,
    ProtocolError,
    Rejected,
)
from snakebot.formats.upload_writes import chunk_writes, commit_write
from snakebot.link.controller import Command, ControllerErrors, State, UploadResult
from tests.reliability.rig.campaigns.bus_faults import start_steered
from tests.reliability.rig.campaigns.outcome import Outcome
from tests.reliability.rig.campaigns.rig import Rig
from tests.reliability.rig.campaigns.testbed import CONTROLLER_ID, CTL, MAX_LEN_FIELD, big_table


class PcLinkModel:
    """The controller's PC link as the firmware parses it, for predicting what noise does:
    the shared resynchronisation rule (:class:`snakebot.formats.protocol.PacketParser`), and after
    each byte the firmware's extra step (``dxl_parser_skip_to_hidden``): while a candidate
    is incomplete, the first later ``FF FF`` that starts a complete packet with a good
    checksum among the bytes held back wins, and what lay before it is one rejection."""

    def __init__(self) -> None:
        self.parser = PacketParser()
        self.held = b""  # the parser's pending bytes (the last ``pending`` bytes fed)

    def reset(self) -> None:
        self.parser.reset()
        self.held = b""

    def _feed(self, data: bytes) -> list[Packet | Rejected]:
        events = self.parser.feed(data)
        pending = self.parser.pending
        self.held = (self.held + data)[len(self.held) + len(data) - pending :] if pending else b""
        return events

    def _hidden(self) -> int | None:
        held = self.held
        for i in range(1, len(held) - 3):
            if held[i] != 0xFF or held[i + 1] != 0xFF or held[i + 2] == 0xFF:
                continue
            end = i + held[i + 3] + 4
            if 2 <= held[i + 3] <= MAX_LEN_FIELD and end <= len(held):
                if protocol.checksum(held[i + 2 : end - 1]) == held[end - 1]:
                    return i
        return None

    def feed(self, data: bytes) -> list[Packet | Rejected]:
        events: list[Packet | Rejected] = []
        for byte in data:
            events += self._feed(bytes([byte]))
            while self.parser.pending and (i := self._hidden()) is not None:
                events.append(Rejected("hidden", self.held[:i]))
                rest = self.held[i:]
                self.reset()
                events += self._feed(rest)
        return events


BURSTS = 40
DISTURBED_AT_MOST = BURSTS // 4
"""Bursts the host may disturb (see :func:`pc_noise`) before the campaign gives up on
the run as a measurement: rerun on an idle machine."""
RESET_WAIT_S = 2.0
"""How long a burst waits for the firmware to drop a partial packet (100 ms of the
firmware's time, however late the host gets to run it)."""


def _noise(rng: random.Random) -> bytes:
    size = rng.randint(1, 24)
    if rng.random() < 0.5:
        return bytes(rng.getrandbits(8) for _ in range(size))
    # FF-rich: fake headers and length bytes
    return bytes(
        rng.choice((0xFF, 0xFF, 0x00, CONTROLLER_ID, 0x02, 0x04, 0xF0)) for _ in range(size)
    )


def _gap_resets(rig: Rig) -> int:
    return rig.ram_probe()["pc_gap_resets"]


def _wait_gap_reset(rig: Rig, target: int) -> None:
    """Until the firmware has dropped ``target`` partial packets since it started."""
    end = time.monotonic() + RESET_WAIT_S
    while _gap_resets(rig) < target and time.monotonic() < end:
        time.sleep(0.02)


def pc_noise(rig: Rig, out: Outcome) -> None:
    """Noise bursts on the PC link while the table plays; each is followed at once by a
    PING, or first by a pause (the firmware drops a partial packet after 100 ms).

    Each burst is judged on its own: the counters before and after it against what the
    parser rule predicts. The firmware counts the partial packets it drops after its
    100 ms gap (``pc_gap_resets``, read from RAM), so a burst whose bytes the host let
    sit for 100 ms (a busy machine stalled the emulator or the client mid-burst) shows as
    one drop more than the burst asks for; such a burst says nothing about the parser
    and is counted as disturbed, not judged. Where a burst asks for a drop, it waits until
    the firmware has made it, however late."""
    start_steered(rig, out)
    rng = random.Random(f"{out.seed}/pc-noise")
    ctl = rig.ctl
    link = ctl.link
    model = PcLinkModel()
    counters = ctl.read("PC Packets", "PC Errors")
    resets = _gap_resets(rig)
    wrong: list[str] = []
    predicted_wrong = disturbed = 0
    noise_bytes = answered = errors_expected = 0
    for burst in range(BURSTS):
        model.reset()  # a burst starts on a clean parser: the one before ended on one
        expected: Counter[str] = Counter()
        drops = 0
        noise = _noise(rng)
        noise_bytes += len(noise)
        link.port.write(noise)
        expected.update(type(e).__name__ for e in model.feed(noise))
        if rng.random() < 0.4:  # a pause past the firmware's gap
            if model.parser.pending:
                drops += 1
                _wait_gap_reset(rig, resets + drops)
            model.reset()
        ping = protocol.ping(CONTROLLER_ID)
        events = model.feed(ping)
        expected.update(type(e).__name__ for e in events)
        will_answer = any(isinstance(e, Packet) and e.encode() == ping for e in events)
        try:
            link.transact(ping, CONTROLLER_ID, 0, retries=0)
            did_answer = True
        except ProtocolError:
            did_answer = False
        if not did_answer and model.parser.pending:
            drops += 1  # the PING sits in a candidate the gap drops
            _wait_gap_reset(rig, resets + drops)
        rig.check_alive()  # its PING is one more packet, parsed from a clean state
        after = ctl.read("PC Packets", "PC Errors")
        now_resets = _gap_resets(rig)
        expected["Packet"] += 2  # check_alive's PING and this READ
        got_errors = (after["PC Errors"] - counters["PC Errors"]) & 0xFFFF
        got_packets = (after["PC Packets"] - counters["PC Packets"]) & 0xFFFF
        got_drops = (now_resets - resets) & 0xFFFF
        counters, resets = after, now_resets
        answered += did_answer
        if got_drops != drops or (will_answer and not did_answer):
            disturbed += 1  # the host let bytes sit past the gap, or a reply came late
            continue
        errors_expected += expected["Rejected"]
        predicted_wrong += did_answer != will_answer
        if (got_errors, got_packets) != (expected["Rejected"], expected["Packet"]):
            wrong.append(
                f"burst {burst} ({noise.hex()}): PC Errors +{got_errors} for "
                f"{expected['Rejected']}, PC Packets +{got_packets} for {expected['Packet']}"
            )
    out.counts.update(
        noise_bursts=BURSTS,
        noise_bytes=noise_bytes,
        bursts_disturbed_by_the_host=disturbed,
        pings_through_noise=answered,
        pc_errors_expected=errors_expected,
        bursts_counted_otherwise=len(wrong),
    )
    out.check(
        "counted",
        disturbed <= DISTURBED_AT_MOST,
        f"the host disturbed {disturbed} of {BURSTS} bursts (bytes left past the firmware's "
        "100 ms gap, or replies late): not a measurement, rerun on an idle machine",
    )
    out.check("counted", not wrong, "; ".join(wrong[:3]))
    out.check(
        "counted",
        predicted_wrong == 0,
        f"{predicted_wrong} PINGs answered otherwise than the parser rule predicts",
    )
    out.check("counted", answered > 0, "no PING got through the noise")
    rig.watch(0.3, rig.operator())


def upload_cut(rig: Rig, out: Outcome) -> None:
    """While table A plays, an upload of table B is cut after every chunk (and in the
    middle of every chunk's packet) and committed anyway; then B is uploaded whole."""
    start_steered(rig, out)
    ctl = rig.ctl
    b = big_table()
    chunks = chunk_writes(b, controller=CTL)
    out.counts["table_b_chunks"] = len(chunks)
    refused = incomplete_flag = still_playing = 0
    for cut in range(len(chunks)):
        for mid in (False, True):
            for address, data in chunks[:cut]:
                ctl.write_block(address, data)
            if mid:
                address, data = chunks[cut]
                packet = protocol.write(CONTROLLER_ID, address, data)
                ctl.link.port.write(packet[: len(packet) // 2])  # the cable is pulled
                time.sleep(0.15)
            ctl.write_block(*commit_write(b, CTL))
            regs = ctl.read("Upload Result", "Error Flags", "State")
            refused += regs["Upload Result"] == UploadResult.INCOMPLETE
            incomplete_flag += bool(regs["Error Flags"] & ControllerErrors.UPLOAD_LENGTH)
            still_playing += regs["State"] == State.PLAYING
            rig.check_alive()
            rig.check_table(f"after a cut at chunk {cut}{' (mid-packet)' if mid else ''}")
    cuts = 2 * len(chunks)
    out.counts.update(
        cuts=cuts,
        commits_refused_incomplete=refused,
        upload_length_flag_set=incomplete_flag,
        kept_playing=still_playing,
    )
    out.check("table", refused == cuts, f"{cuts - refused} cut uploads were not INCOMPLETE")
    out.check("counted", incomplete_flag == cuts, "UPLOAD_LENGTH was not raised for every cut")
    out.check("table", still_playing == cuts, "a refused commit stopped the playing table")
    # the whole table B now lands, and plays
    result = rig.upload(b)
    out.check("table", result == UploadResult.OK, f"the whole table B was refused: {result}")
    rig.check_table("after the whole upload")
    rig.command(Command.PLAY)
    rig.watch(0.5, rig.operator())
