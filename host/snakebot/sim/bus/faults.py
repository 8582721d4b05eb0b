"""Seeded, reproducible fault injection for the emulated bus.

Every kind of fault draws from its own random stream derived from one seed, so a run
is repeated exactly by giving the same seed, and switching one fault on does not
change what the others do.

==================  =====================================================================
fault               what happens on the emulated wire
==================  =====================================================================
``corrupt``         each byte on the wire has this probability of one flipped bit; every
                    receiver (servos, and the host through its echo) hears the same damage
``drop``            each status packet has this probability of never being sent
``delay_s``         extra seconds before every status packet (after Return Delay Time)
``jitter_s``        plus a uniformly random extra delay from 0 to ``jitter_s``
``noise_rate``      bursts of random bytes per second of bus time (a Poisson process),
                    each 1 to ``noise_len`` bytes long, heard by everyone
``brownouts``       a servo loses power at ``start_s`` for ``duration_s``: it hears
                    nothing, answers nothing, stops, and comes back with its RAM reset
                    (EEPROM kept), as after a supply dip
==================  =====================================================================
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, field

from snakebot.errors import quoted
from snakebot.sim.errors import SimOptionError

MAX_BROWNOUT_S = 1e6
"""The latest start and the longest duration of a brownout (11 days of bus time)."""


@dataclass(frozen=True)
class Brownout:
    """Servo ``servo_id`` is unpowered from ``start_s`` for ``duration_s`` (bus time)."""

    servo_id: int
    start_s: float
    duration_s: float

    @classmethod
    def parse(cls, text: str) -> Brownout:
        """``ID@START+DURATION`` in seconds, e.g. ``3@0.5+0.2``."""
        try:
            ident, when = text.split("@", 1)
            start, duration = when.split("+", 1)
            result = cls(int(ident), float(start), float(duration))
        except ValueError:
            raise SimOptionError(
                f"brownout {quoted(text)} is not ID@START+DURATION: write e.g. 3@0.5+0.2 for "
                "servo 3 losing power at 0.5 s for 0.2 s"
            ) from None
        start_ok = 0 <= result.start_s <= MAX_BROWNOUT_S  # NaN fails both
        if not (start_ok and 0 < result.duration_s <= MAX_BROWNOUT_S):
            raise SimOptionError(
                f"brownout {quoted(text)}: the start must be 0 to {MAX_BROWNOUT_S:g} s and the "
                f"duration more than 0 and at most {MAX_BROWNOUT_S:g} s"
            )
        if not 0 <= result.servo_id <= 253:
            raise SimOptionError(f"brownout {quoted(text)}: the servo ID must be 0..253")
        return result


@dataclass(frozen=True)
class FaultConfig:
    """What can go wrong on the wire; all off by default."""

    seed: int = 0
    corrupt: float = 0.0
    drop: float = 0.0
    delay_s: float = 0.0
    jitter_s: float = 0.0
    noise_rate: float = 0.0
    noise_len: int = 4
    brownouts: tuple[Brownout, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        for name in ("corrupt", "drop"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise SimOptionError(f"{name} is a probability from 0 to 1, got {quoted(value)}")
        for name in ("delay_s", "jitter_s", "noise_rate"):
            value = getattr(self, name)
            if not (value >= 0.0 and math.isfinite(value)):
                raise SimOptionError(f"{name} must be a finite number >= 0, got {quoted(value)}")
        if not 1 <= self.noise_len <= 255:
            raise SimOptionError(f"noise_len must be 1..255 bytes, got {quoted(self.noise_len)}")

    @property
    def any(self) -> bool:
        """Whether any fault is switched on."""
        return bool(
            self.corrupt
            or self.drop
            or self.delay_s
            or self.jitter_s
            or self.noise_rate
            or self.brownouts
        )


_NEVER = 1 << 62  # "no corruption ahead" for a zero rate


class FaultInjector:
    """Draws the faults of one bus from its :class:`FaultConfig`, reproducibly."""

    def __init__(self, config: FaultConfig) -> None:
        self.config = config
        seed = config.seed
        self._corrupt_rng = random.Random(f"{seed}/corrupt")
        self._drop_rng = random.Random(f"{seed}/drop")
        self._delay_rng = random.Random(f"{seed}/delay")
        self._noise_rng = random.Random(f"{seed}/noise")
        self._collision_rng = random.Random(f"{seed}/collision")
        # Bytes left before the next corrupted one (a geometric gap: one draw per fault,
        # not one per byte, so a clean run costs nothing).
        self._until_corrupt = self._gap()
        self.corrupted_bytes = 0
        self.dropped_replies = 0
        self.noise_bursts = 0

    def _gap(self) -> int:
        p = self.config.corrupt
        if p <= 0.0:
            return _NEVER
        if p >= 1.0:
            return 0
        u = self._corrupt_rng.random()
        return int(math.log1p(-u) / math.log1p(-p))

    def corrupt(self, data: bytearray) -> None:
        """Flip one random bit in each byte of ``data`` (in place) that the rate hits."""
        n = len(data)
        i = self._until_corrupt
        if i >= n:
            self._until_corrupt = i - n
            return
        while i < n:
            data[i] ^= 1 << self._corrupt_rng.randrange(8)
            self.corrupted_bytes += 1
            i += 1 + self._gap()
        self._until_corrupt = i - n

    def drop_reply(self) -> bool:
        """Whether the next status packet is lost."""
        if self.config.drop <= 0.0:
            return False
        dropped = self._drop_rng.random() < self.config.drop
        self.dropped_replies += dropped
        return dropped

    def reply_delay(self) -> float:
        """Extra seconds before the next status packet."""
        extra = self.config.delay_s
        if self.config.jitter_s:
            extra += self._delay_rng.uniform(0.0, self.config.jitter_s)
        return extra

    def next_noise(self, after: float) -> tuple[float, bytes] | None:
        """The next noise burst after bus time ``after``: (start time, bytes), or None."""
        rate = self.config.noise_rate
        if rate <= 0.0:
            return None
        rng = self._noise_rng
        start = after + rng.expovariate(rate)
        length = rng.randint(1, self.config.noise_len)
        self.noise_bursts += 1
        return start, bytes(rng.getrandbits(8) for _ in range(length))

    def collision_byte(self) -> int:
        """What a receiver makes of two drivers fighting over one byte slot."""
        return self._collision_rng.getrandbits(8)
