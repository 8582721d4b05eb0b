"""Program errors, and what each of the controller's refusal codes (40..59) means."""

from __future__ import annotations

from snakebot.core import lib
from snakebot.errors import InputError

# prog_validate()'s refusals (Upload Result PROGRAM_*, controller.json): what went wrong,
# and what to do (snakebot.link.controller.messages shows them for an upload too).
RESULTS: dict[str, tuple[str, str]] = {
    "TRUNCATED": (
        "the program is truncated",
        "rebuild it with `snakebot program build`",
    ),
    "BAD_MAGIC": (
        "not a program (no SNKP magic)",
        "pass a file from `snakebot program build`",
    ),
    "BAD_VERSION": (
        "unknown program version",
        "rebuild it with this snakebot",
    ),
    "BAD_JOINT_COUNT": (
        "a program drives 1..18 joints",
        "fix the robot description",
    ),
    "BAD_SEGMENT_COUNT": (
        "a program has 1..64 segments",
        "split the spec into programs",
    ),
    "BAD_PERIOD": (
        "the step period must be 1..1000 ms",
        "fix `period_ms` in the spec",
    ),
    "TOO_BIG": (
        "the program does not fit the controller's table buffer",
        "use fewer segments, periodic blocks or table frames",
    ),
    "TRAILING_BYTES": (
        "bytes after the program's end",
        "rebuild it",
    ),
    "CRC_MISMATCH": (
        "the program's CRC-32 does not match",
        "the file is damaged, rebuild it",
    ),
    "BAD_JOINT": (
        "a joint record is invalid (ID above 253 or repeated, limits out of order, "
        "zero tick outside them)",
        "fix the robot description",
    ),
    "FRAME_OUT_OF_LIMITS": (
        "a table frame lies outside its joint's limits",
        "rebuild the table",
    ),
    "BAD_SEGMENT": (
        "a segment is malformed (unknown kind, zero duration, frames beyond the table, "
        "more than 65535 steps, no such periodic block)",
        "fix the segment",
    ),
    "OUT_OF_RANGE": (
        "a segment's goals leave a joint's limits (amplitude plus offset plus where "
        "the previous segment ended)",
        "use a smaller amplitude, offset or rate",
    ),
    "TOO_FAST": (
        "a segment moves a joint faster than the servo can (A * omega, or rate + "
        "omega * amplitudes, above its no-load speed)",
        "slow it down",
    ),
}
MESSAGES: dict[int, str] = {
    getattr(lib, f"CTL_UPLOAD_RESULT_PROGRAM_{name}"): f"{what}: {fix}"
    for name, (what, fix) in RESULTS.items()
}


class ProgramError(InputError):
    """A program that cannot be built, read or accepted; ``code`` is the controller's
    refusal code (40..59) when the controller would refuse it for the same reason."""

    def __init__(self, message: str, code: int | None = None) -> None:
        super().__init__(message)
        self.code = code


def refusal(code: int, segment: int | None = None) -> ProgramError:
    """The ProgramError for a prog_validate() code, naming the segment when there is one."""
    where = f"segment {segment + 1}: " if segment is not None else ""
    text = MESSAGES.get(code, f"refused with code {code}")
    return ProgramError(f"{where}{text}", code)
