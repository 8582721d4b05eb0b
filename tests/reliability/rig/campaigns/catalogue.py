"""Every campaign by name, and running one."""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from snakebot.link.controller.errors import ControllerError
from snakebot.link.controller.monitor import Sample
from snakebot.sim.bus.faults import FaultConfig
from tests.reliability.rig.campaigns.bus_faults import (
    after_brownout,
    after_clean,
    after_corrupt,
    after_drop,
    after_servo_limits,
    brownout,
    clean,
    common_checks,
    play_under,
    servo_limits,
)
from tests.reliability.rig.campaigns.library import LIBRARY_CUT, library_power_cut
from tests.reliability.rig.campaigns.outcome import Outcome
from tests.reliability.rig.campaigns.pc_link import pc_noise, upload_cut
from tests.reliability.rig.campaigns.rig import Rig
from tests.reliability.rig.campaigns.targets import DEFAULT_BOARD, TARGETS
from tests.reliability.rig.campaigns.testbed import CampaignFailed


@dataclass(frozen=True)
class Campaign:
    name: str
    description: str
    faults: Callable[[int], FaultConfig]
    body: Callable[[Rig, Outcome], None]
    after: Callable[[Rig, Outcome, Sample], None] | None = None


def _corrupt(p: float) -> Callable[[int], FaultConfig]:
    return lambda seed: FaultConfig(seed=seed, corrupt=p)


CAMPAIGNS: dict[str, Campaign] = {
    c.name: c
    for c in (
        Campaign(
            "clean",
            "no faults: the healthy baseline (no reply lost, no error counted)",
            lambda s: FaultConfig(seed=s),
            clean,
            after_clean,
        ),
        Campaign(
            "corrupt-0.1pct",
            "each byte on the servo bus has one bit flipped w.p. 0.1 %",
            _corrupt(0.001),
            play_under(4.0),
            after_corrupt,
        ),
        Campaign(
            "corrupt-1pct",
            "each byte on the servo bus has one bit flipped w.p. 1 %",
            _corrupt(0.01),
            play_under(4.0),
            after_corrupt,
        ),
        Campaign(
            "corrupt-5pct",
            "each byte on the servo bus has one bit flipped w.p. 5 %",
            _corrupt(0.05),
            play_under(4.0),
            after_corrupt,
        ),
        Campaign(
            "servo-limits-1pct",
            "the robot's limits set in the servos first, then as corrupt-1pct: no servo "
            "may accept a goal outside them",
            _corrupt(0.01),
            servo_limits(4.0),
            after_servo_limits,
        ),
        Campaign(
            "servo-limits-5pct",
            "the robot's limits set in the servos first, then as corrupt-5pct: no servo "
            "may accept a goal outside them",
            _corrupt(0.05),
            servo_limits(4.0),
            after_servo_limits,
        ),
        Campaign(
            "drop-10pct",
            "each servo status packet is lost w.p. 10 %",
            lambda s: FaultConfig(seed=s, drop=0.10),
            play_under(4.0),
            after_drop,
        ),
        Campaign(
            "brownout-short",
            "servo 2 loses power for 60 ms (fewer misses than "
            "Bus Loss Limit) and comes back with its RAM reset",
            lambda s: FaultConfig(seed=s),
            brownout(0.06),
            after_brownout(False),
        ),
        Campaign(
            "brownout-long",
            "servo 2 loses power for 600 ms and comes back with its RAM "
            "reset; the operator CLEARs and PLAYs again",
            lambda s: FaultConfig(seed=s),
            brownout(0.6),
            after_brownout(True),
        ),
        Campaign(
            "pc-noise",
            "40 bursts of noise on the PC link (random and FF-rich, 1-24 "
            "bytes), each followed by a PING at once or after a pause",
            lambda s: FaultConfig(seed=s),
            pc_noise,
        ),
        Campaign(
            "upload-cut",
            "an upload of a 10-chunk table cut after every chunk and in "
            "the middle of every chunk's packet, committed anyway, while another plays",
            lambda s: FaultConfig(seed=s),
            upload_cut,
        ),
    )
}


def run(
    name: str, seed: int = 1, seconds: float | None = None, board: str = DEFAULT_BOARD
) -> Outcome:
    """Run one campaign on ``board`` (the library's runs on the host, whatever the board);
    its Outcome says what was counted and which checks held. ``seconds``: how long the
    campaigns that play a table play (default: their own)."""
    if name == LIBRARY_CUT:
        t0 = time.monotonic()
        out = library_power_cut(seed)
        out.seconds = time.monotonic() - t0
        return out
    try:
        campaign = CAMPAIGNS[name]
    except KeyError:
        raise CampaignFailed(
            f"no campaign {name!r}: choose one of {', '.join(CAMPAIGNS)}"
        ) from None
    if board not in TARGETS:
        raise CampaignFailed(f"no board {board!r}: choose one of {', '.join(TARGETS)}")
    image = TARGETS[board].image
    if not image.is_file():
        raise CampaignFailed(f"{image} not found: build the firmware with `make firmware`")
    out = Outcome(name, seed, campaign.description, board)
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="snakebot.sim-campaign-") as tmp:
        with Rig(board, campaign.faults(seed), Path(tmp), seconds) as rig:
            try:
                campaign.body(rig, out)
                last = rig.freeze()
            except ControllerError as exc:
                out.check("alive", False, f"the campaign lost the controller: {exc}")
                out.seconds = time.monotonic() - t0
                return out
            rig.check_table("at the end")
            common_checks(rig, out, last)
            if campaign.after is not None:
                campaign.after(rig, out, last)
    out.seconds = time.monotonic() - t0
    return out
