"""The gait library's flash store under power cuts (on the host, against the flash register
model)."""

from __future__ import annotations

import random
import tempfile
from collections import Counter
from pathlib import Path

from tests.reliability.rig.campaigns.outcome import Outcome
from tests.reliability.rig.campaigns.testbed import support

LIBRARY_CUT = "library-power-cut"
LIBRARY_CUT_DESCRIPTION = (
    "the CM-530's gait-library store (firmware/app/store_lib.c, on the host against the "
    "flash register model) takes seeded stores and deletes, most cut by a power failure at "
    "a random flash operation (torn erase or program), each followed by a fresh start"
)


def library_power_cut(seed: int, operations: int = 40) -> Outcome:
    """The library campaign: after every operation, cut or not, a fresh start must find
    every other slot as it was and the slot written as it was or as it was to become
    ("library"), and an uncut operation must have done what it said ("done")."""
    lf = support("library_flash")  # the test support's build of the store and flash model

    out = Outcome(LIBRARY_CUT, seed, LIBRARY_CUT_DESCRIPTION)
    rng = random.Random(seed)
    counts = Counter[str]()
    with tempfile.TemporaryDirectory(prefix="snakebot.library-campaign-") as tmp:
        hal = lf.build(Path(tmp))
        mem = lf.ERASED_LONG_AGO
        expected = lf.contents(hal, mem)
        for i in range(operations):
            slot = rng.randrange(lf.SLOTS)
            if rng.random() < 0.25:
                op, new = lf.delete(hal, slot), lf.EMPTY
            else:
                name = f"gait {i}".encode()
                new = (lf.TABLE, name, lf.blob(rng.randint(1, 400), seed * 1000 + i))
                op = lf.put(hal, slot, *new)
            _, _, steps = lf.run(hal, mem, op)  # how many flash operations it takes
            cut = rng.randrange(steps) if steps and rng.random() < 0.75 else None
            status, mem, _ = lf.run(hal, mem, op, cut_at=cut, seed=rng.randrange(1 << 16))
            found = lf.contents(hal, mem)
            counts["operations"] += 1
            counts["cuts"] += cut is not None
            counts["slots_checked"] += lf.SLOTS
            for s in range(lf.SLOTS):
                allowed = (expected[s], new) if s == slot else (expected[s],)
                if found[s] not in allowed:
                    counts["corrupted_slots"] += 1
                    out.check(
                        "library", False, f"operation {i} cut at {cut}: slot {s} is {found[s]!r}"
                    )
            if cut is None:
                out.check(
                    "done", status == lf.OK and found[slot] == new, f"operation {i}: {status}"
                )
            else:
                counts["new_after_cut" if found[slot] == new else "old_after_cut"] += 1
            expected = found
    out.counts = {"corrupted_slots": 0, **counts}
    out.check("library", True)
    out.check("done", True)
    return out
