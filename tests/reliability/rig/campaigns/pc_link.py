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


def pc_noise(rig: Rig, out: Outcome) -> None:
    """Noise bursts on the PC link while the table plays; each is followed at once by a
    PING, or first by a pause (the firmware drops a partial packet after 100 ms)."""
    start_steered(rig, out)
    rng = random.Random(f"{out.seed}/pc-noise")
    ctl = rig.ctl
    link = ctl.link
    base = ctl.read("PC Packets", "PC Errors")
    model = PcLinkModel()
    expected = Counter()
    predicted_wrong = 0
    bursts = noise_bytes = answered = 0
    for _ in range(40):
        size = rng.randint(1, 24)
        if rng.random() < 0.5:
            noise = bytes(rng.getrandbits(8) for _ in range(size))
        else:  # FF-rich: fake headers and length bytes
            noise = bytes(
                rng.choice((0xFF, 0xFF, 0x00, CONTROLLER_ID, 0x02, 0x04, 0xF0)) for _ in range(size)
            )
        bursts += 1
        noise_bytes += len(noise)
        link.port.write(noise)
        expected.update(type(e).__name__ for e in model.feed(noise))
        if rng.random() < 0.4:
            time.sleep(0.15)  # past PCLINK_GAP_MS: the firmware drops what it holds
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
        answered += did_answer
        predicted_wrong += did_answer != will_answer
        if not did_answer:
            model.reset()  # the client waited past the firmware's 100 ms gap
        rig.check_alive()  # its PING is one more packet, parsed from a clean state
        expected["Packet"] += 1
    time.sleep(0.15)  # nothing left pending
    after = ctl.read("PC Packets", "PC Errors")
    expected["Packet"] += 1  # this READ itself
    got_packets = (after["PC Packets"] - base["PC Packets"]) & 0xFFFF
    got_errors = (after["PC Errors"] - base["PC Errors"]) & 0xFFFF
    out.counts.update(
        noise_bursts=bursts,
        noise_bytes=noise_bytes,
        pings_through_noise=answered,
        pc_errors_expected=expected["Rejected"],
        pc_errors_counted=got_errors,
        pc_packets_expected=expected["Packet"],
        pc_packets_counted=got_packets,
    )
    out.check(
        "counted",
        got_errors == expected["Rejected"],
        f"PC Errors grew by {got_errors}, the noise must cause {expected['Rejected']}",
    )
    out.check(
        "counted",
        got_packets == expected["Packet"],
        f"PC Packets grew by {got_packets}, expected {expected['Packet']}",
    )
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
