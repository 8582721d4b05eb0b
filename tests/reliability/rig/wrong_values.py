"""How often does the client return a wrong value as right, with bytes damaged on the wire?

    python -m tests.reliability.rig.wrong_values    # 1 % corruption, seeds 1-3, 10^4 each
    python -m tests.reliability.rig.wrong_values --seeds 7 --transactions 40000 --json
    python -m tests.reliability.rig.wrong_values --baseline    # without the client's defences
    python -m tests.reliability.rig.wrong_values --confirmed   # every READ as read_confirmed

A ``DxlClient`` talks to one emulated AX-12A through ``sim://`` (the bus runs as fast as
the host allows, so a seed fixes every damaged byte). Each transaction is a READ of a
random span of registers (two in three) or a WRITE of LED or CW Compliance Margin (one
in three; neither moves the servo, so what it holds stays put). Every value a READ
returns is compared with the emulated servo's own registers at that moment: a
difference is a wrong value returned as right. Failures (timeout, corrupt, servo error)
are counted by kind; a ServoError with the CHECKSUM bit is the servo saying it received
a damaged instruction.

``--baseline`` measures the client as it was before these defences: no resend on the
CHECKSUM and INSTRUCTION bits, no range check of the values read. ``--confirmed`` reads
with ``read_confirmed`` (two equal replies), as the tools do for values they base
decisions on.
"""

from __future__ import annotations

import argparse
import json
import random
from collections import Counter
from dataclasses import asdict, dataclass, field

from snakebot.formats.protocol import CorruptPacket, DxlTimeout, ErrorFlags, ServoError
from snakebot.formats.protocol.control_table import ControlTable
from snakebot.link.transport import DxlClient
from snakebot.link.transport import client as client_module

SERVO_ID = 1
MODEL = "AX-12A"
WRITABLE = ("LED", "CW Compliance Margin")


@dataclass
class Tally:
    """What happened in one run."""

    seed: int
    corrupt: float
    transactions: int = 0
    reads: int = 0
    wrong_values: int = 0
    failures: Counter[str] = field(default_factory=Counter)
    examples: list[str] = field(default_factory=list)

    def per_10k(self) -> float:
        return 1e4 * self.wrong_values / max(1, self.transactions)


def run(
    seed: int, transactions: int, corrupt: float, baseline: bool = False, confirmed: bool = False
) -> Tally:
    """``transactions`` transactions at ``corrupt`` with faults seeded by ``seed``."""
    table = ControlTable.for_model(MODEL)
    url = f"sim://?ids={SERVO_ID}&model={MODEL}&corrupt={corrupt}&seed={seed}&return_delay=0"
    saved = client_module.RESEND_FLAGS
    if baseline:
        client_module.RESEND_FLAGS = ErrorFlags(0)
    tally = Tally(seed, corrupt)
    rng = random.Random(seed)
    entries = list(table)
    try:
        with DxlClient(url, echo=False, check_ranges=not baseline) as client:
            servo = client.port.bus.servos[0]
            read = client.read_confirmed if confirmed else client.read
            for _ in range(transactions):
                tally.transactions += 1
                try:
                    if rng.random() < 2 / 3:
                        first = rng.randrange(len(entries))
                        last = min(len(entries) - 1, first + rng.randrange(3))
                        start = entries[first].address
                        length = entries[last].address + entries[last].size - start
                        got = read(SERVO_ID, start, length)
                        tally.reads += 1
                        truth = servo.regs.read(start, length)
                        if got != truth:
                            tally.wrong_values += 1
                            if len(tally.examples) < 5:
                                tally.examples.append(
                                    f"{length} bytes at {start}: got {got.hex()}, "
                                    f"servo holds {truth.hex() if truth else None}"
                                )
                    else:
                        entry = table.by_name(rng.choice(WRITABLE))
                        value = rng.randrange(entry.min or 0, (entry.max or 1) + 1)
                        client.write(SERVO_ID, entry.address, value.to_bytes(entry.size, "little"))
                except ServoError as exc:
                    tally.failures[f"ServoError({exc.flags.describe()})"] += 1
                except (DxlTimeout, CorruptPacket) as exc:
                    tally.failures[type(exc).__name__] += 1
    finally:
        client_module.RESEND_FLAGS = saved
    return tally


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m tests.reliability.rig.wrong_values", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--transactions", type=int, default=10_000)
    parser.add_argument("--corrupt", type=float, default=0.01)
    parser.add_argument("--baseline", action="store_true")
    parser.add_argument("--confirmed", action="store_true")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    for seed in args.seeds:
        tally = run(seed, args.transactions, args.corrupt, args.baseline, args.confirmed)
        if args.json:
            print(json.dumps({**asdict(tally), "per_10k": tally.per_10k()}))
            continue
        failures = ", ".join(f"{k} {v}" for k, v in sorted(tally.failures.items())) or "none"
        print(
            f"seed {seed}: {tally.transactions} transactions ({tally.reads} READs answered), "
            f"{tally.wrong_values} wrong values ({tally.per_10k():.2f} per 10^4); "
            f"failures: {failures}"
        )
        for example in tally.examples:
            print(f"    {example}")


if __name__ == "__main__":
    main()
