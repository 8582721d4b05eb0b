"""The campaigns of faults on the servo bus: corruption, drops, brown-outs, the servos' own
limits, and the checks every campaign shares."""

from __future__ import annotations

import random
import time
from collections.abc import Callable

from snakebot.facts.boards import CONTROL_TICK_MS
from snakebot.link.controller import Command, ControllerErrors, State, UploadResult
from snakebot.link.controller.limits import wait_settled
from snakebot.link.controller.monitor import Sample
from snakebot.link.controller.playback import RUNTIME_REFUSALS, refusal_reason
from tests.reliability.rig.campaigns.outcome import Outcome
from tests.reliability.rig.campaigns.rig import Rig
from tests.reliability.rig.campaigns.testbed import (
    FRAMES,
    IDS,
    LIMITS,
    PERIOD_MS,
    STEERING,
    CampaignFailed,
    gait_table,
)

PLAY_TRIES = 5


def start_steered(rig: Rig, out: Outcome) -> None:
    """Upload the table, steer it against the limits, play. As `snakebot play` does, PLAY
    waits while the controller checks the servos' limits (Limits State APPLYING: after
    the roster is set, and whenever an audit READ finds a limit changed, as a damaged
    packet can make it); one refused for a runtime reason (that, or the safe state a
    fault can cause before PLAY), or taken and then ended by the safe state before the
    State is read back (a read that waits out a lost reply gives a fault the time), is
    sent again after a CLEAR, as an operator does."""
    result = rig.upload(gait_table())
    if result != UploadResult.OK:
        raise CampaignFailed(f"the campaign's own table was refused: Upload Result {result}")
    rig.started_polling()
    rig.write({"Steering Offset": STEERING})
    for tries in range(1, PLAY_TRIES + 1):
        wait_settled(rig.ctl)
        rig.command(Command.PLAY)
        state = rig.ctl.read("State")["State"]
        if state == State.PLAYING:
            break
        name, _ = refusal_reason(rig.ctl)
        tripped = name == "NONE" and state == State.SAFE  # played, then went SAFE
        if not (name in RUNTIME_REFUSALS or tripped) or tries == PLAY_TRIES:
            raise CampaignFailed(
                f"the campaign's table did not play after {tries} tries: State "
                f"{State(state).name}, Refusal Reason {name} (protocol/controller.md says "
                "what it means); run the campaign again"
            )
        rig.command(Command.CLEAR)  # as the operator does; the next refusal shows anew
    out.counts["play_tries"] = tries
    rig.check_table("after commit")


def common_checks(rig: Rig, out: Outcome, last: Sample) -> None:
    """The invariants every campaign checks; fills the common counts."""
    tap, h, r = rig.tap, rig.health, last.registers
    ram = rig.ram_probe()
    out.counts.update(
        goal_packets=tap.goal_packets,
        goals=tap.goals,
        goals_outside_limits=tap.goals_outside,
        servo_goals_outside_limits=h.servo_goals_outside,
        servo_goals_accepted_outside=sum(len(s.goals_outside) for s in rig.servos),
        angle_limit_writes=sum(s.angle_limit_writes for s in rig.servos),
        reads_sent=tap.reads_sent,
        reads_answered=tap.reads_answered,
        reads_damaged=tap.reads_damaged,
        bus_reads=r["Bus Reads"],
        bus_timeouts=r["Bus Timeouts"],
        bus_errors=r["Bus Errors"],
        pc_packets=r["PC Packets"],
        pc_errors=r["PC Errors"],
        pings=h.pings,
        ping_failures=h.ping_failures,
        reboots=h.reboots,
        loop_stalls=h.stalls,
        safe_entries=h.safe_entries,
        recoveries=h.recoveries,
        uptime_ms=ram["uptime_ms"],
        max_bus_gap_ms=round(tap.max_gap_s * 1000, 1),
        table_checks=h.table_checks,
        corrupted_bytes=rig.bus.faults.corrupted_bytes,
        dropped_replies=rig.bus.faults.dropped_replies,
    )
    out.counts["error_flags_seen"] = h.flags_seen
    # READs whose reply did come, but after the firmware's reply window (a busy host)
    out.counts["late_replies"] = r["Bus Timeouts"] - (tap.reads_sent - tap.reads_answered)
    out.check(
        "limits", tap.goals_outside == 0, f"goals outside the limits: {tap.outside_examples[:5]}"
    )
    out.check("limits", tap.goal_packets > 0, "no goals were sent at all")
    out.check("alive", h.ping_failures == 0, f"{h.ping_failures} PINGs unanswered")
    out.check(
        "alive",
        h.reboots == 0,
        f"the firmware rebooted {h.reboots} times ({'; '.join(h.reboot_details[:3])})",
    )
    out.check("alive", h.stalls == 0, f"the control loop stalled in {h.stalls} samples")
    out.check(
        "alive", ram["bus_refused"] == 0 and ram["pc_tx_dropped"] == 0, f"buffers overflowed: {ram}"
    )
    watchdog_checks(rig, out)
    out.check("table", not h.table_failures, "; ".join(h.table_failures[:3]))
    out.check("table", h.table_checks > 0, "the table was never checked")
    accounted = r["Bus Reads"] + r["Bus Timeouts"]
    lost = tap.reads_sent - tap.reads_answered
    out.check(
        "counted",
        accounted == tap.reads_sent,
        f"{tap.reads_sent} READs sent, {accounted} counted as read or timed out",
    )
    out.check(
        "counted",
        r["Bus Reads"] <= tap.reads_answered,
        f"{r['Bus Reads']} Bus Reads but only {tap.reads_answered} intact replies",
    )
    out.check(
        "counted",
        r["Bus Timeouts"] >= lost,
        f"{lost} READs lost their reply, Bus Timeouts says {r['Bus Timeouts']}",
    )
    out.check(
        "counted",
        r["Bus Errors"] <= tap.reads_damaged,
        f"{r['Bus Errors']} Bus Errors, {tap.reads_damaged} damaged replies heard",
    )
    polled = rig.last_polled
    if polled is not None and all(j.timeout_count < 255 for j in polled.servos):
        # the registers, then the servo window a moment later: at most the READs of the
        # ticks in between apart (one READ a tick; the firmware's clock runs no faster
        # than the host's, however long a busy host makes that moment)
        per_servo = sum(j.timeout_count for j in polled.servos)
        then = polled.registers["Bus Timeouts"]
        between = 2 + int(rig.last_polled_s * 1000 / CONTROL_TICK_MS)
        out.check(
            "counted",
            then <= per_servo <= then + between,
            f"per-servo Timeout Counts sum to {per_servo}, Bus Timeouts was {then} "
            f"(at most {between} READs apart)",
        )


def watchdog_checks(rig: Rig, out: Outcome) -> None:
    """Where the machine models the independent watchdog (the emulated CM-530; QEMU does
    not), it was fed and never reset the chip; the longest time between two feeds and
    the timeout are counted."""
    dog = rig.target.watchdog()
    if dog is None:
        return
    out.counts.update(
        watchdog_feeds=dog.feeds,
        watchdog_resets=len(dog.resets),
        watchdog_largest_gap_ms=round(dog.largest_gap_s * 1000, 1),
        watchdog_timeout_ms=round(dog.timeout_s * 1000, 1),
    )
    out.check("alive", dog.feeds > 0, "the firmware never started or fed the watchdog")
    out.check(
        "alive",
        not dog.resets,
        f"the watchdog reset the chip (at {', '.join(f'{t:.3f}' for t in dog.resets[:5])} s "
        f"of its time; since then the longest time between feeds was "
        f"{dog.largest_gap_s * 1000:.1f} ms of {dog.timeout_s * 1000:.0f} ms)",
    )


def play_under(seconds: float, recover: bool = True) -> Callable[[Rig, Outcome], None]:
    """A campaign body: play for ``seconds`` with the fault on, an operator recovering
    from SAFE."""

    def body(rig: Rig, out: Outcome) -> None:
        start_steered(rig, out)
        rig.watch(rig.play_s or seconds, rig.operator() if recover else None)

    return body


def servo_limits(seconds: float) -> Callable[[Rig, Outcome], None]:
    """A campaign body: the robot's limits set on the controller first (the servos' angle
    limits start at the factory 0..1023), then play as the other campaigns do."""
    play = play_under(seconds)

    def body(rig: Rig, out: Outcome) -> None:
        state = rig.set_robot_limits(dict(zip(IDS, LIMITS, strict=True)))
        out.check("servo-limits", state == "VERIFIED", f"Limits State {state} after setting")
        with rig.lock:
            held = [s.angle_limits() for s in rig.servos]
        out.check(
            "servo-limits",
            held == list(LIMITS),
            f"the servos' angle limits are {held}, the robot's {list(LIMITS)}",
        )
        play(rig, out)

    return body


def after_servo_limits(rig: Rig, out: Outcome, last: Sample) -> None:
    """No servo took a goal outside the robot's limits, however the bus damaged packets."""
    after_corrupt(rig, out, last)
    outside = {s.id: s.goals_outside[:5] for s in rig.servos if s.goals_outside}
    out.check("servo-limits", not outside, f"servos accepted goals outside the limits: {outside}")


def clean(rig: Rig, out: Outcome) -> None:
    play_under(3.0)(rig, out)


LATE_AT_MOST = 0.01
"""The share of READs a healthy run may see unanswered: the emulated servos answer in the
host's time, and a host that holds them up past the firmware's 30 ms reply window makes
a reply too late to count (a Bus Timeout, rightly). A firmware that lost replies itself
would lose far more than this."""


def after_clean(rig: Rig, out: Outcome, last: Sample) -> None:
    """Nothing is damaged in a healthy run, and no reply lost beyond what a busy host can
    make late (each one a Bus Timeout: the common checks account for every READ)."""
    r, tap = last.registers, rig.tap
    late = tap.reads_sent - tap.reads_answered
    out.counts["replies_late_by_the_host"] = late
    out.check(
        "counted",
        r["Bus Errors"] == 0 and r["PC Errors"] == 0,
        f"a healthy run counted {r['Bus Errors']} bus errors, {r['PC Errors']} PC errors",
    )
    out.check(
        "counted",
        late <= max(1, int(LATE_AT_MOST * tap.reads_sent)),
        f"a healthy run lost {late} of {tap.reads_sent} replies",
    )
    out.check("alive", rig.health.safe_entries == 0, "a healthy run went SAFE")


def after_corrupt(rig: Rig, out: Outcome, last: Sample) -> None:
    lost = rig.tap.reads_sent - rig.tap.reads_answered
    out.counts["reads_lost"] = lost
    if rig.bus.faults.corrupted_bytes > 50:
        out.check(
            "counted",
            last.registers["Bus Timeouts"] > 0,
            "bytes were corrupted but no READ ever timed out",
        )


def after_drop(rig: Rig, out: Outcome, last: Sample) -> None:
    dropped = rig.bus.faults.dropped_replies
    out.check(
        "counted",
        last.registers["Bus Timeouts"] >= dropped,
        f"{dropped} replies dropped, Bus Timeouts {last.registers['Bus Timeouts']}",
    )
    out.check("counted", dropped > 0, "the campaign dropped nothing")


def brownout(duration_s: float) -> Callable[[Rig, Outcome], None]:
    def body(rig: Rig, out: Outcome) -> None:
        start_steered(rig, out)
        rig.watch(0.5, rig.operator())
        rng = random.Random(f"{out.seed}/brownout")
        start = 0.1 + rng.uniform(0.0, 0.2)
        victim = rig.bus.servo(2)
        with rig.lock:
            t0 = rig.bus.now + start
            rig.bus.at(t0, victim.power_off)
            rig.bus.at(t0 + duration_s, victim.power_on)
            before = rig.tap.unanswered[2]
        out.counts["brownout_ms"] = round(duration_s * 1000)
        # on the bus's clock, which the brown-out runs on: the operator waits for the
        # servo to be back; the watch lasts until well after
        recover_wait = start + duration_s + 0.2
        operator = rig.operator(recover_wait, rig.bus_now)
        rig.watch(start + duration_s + 1.5, operator, rig.bus_now)
        with rig.lock:
            out.counts["servo2_reads_unanswered"] = rig.tap.unanswered[2] - before
            unanswered_total = rig.tap.unanswered[2]
        s = rig.look()
        counted = next(j.timeout_count for j in s.servos if j.id == 2)
        out.counts["servo2_timeout_count"] = counted
        out.check(
            "counted",
            counted >= min(unanswered_total, 255),
            f"servo 2 missed {unanswered_total} READs, its Timeout Count says {counted}",
        )
        sweep = _sweep(rig, len(FRAMES) * PERIOD_MS / 1000 + 0.1)
        out.counts["servo2_sweep_after_ticks"] = round(sweep)
        out.check(
            "recovered", sweep > 50, f"servo 2 swept only {sweep:.0f} ticks after it came back"
        )

    return body


def _sweep(rig: Rig, seconds: float) -> float:
    """How far servo 2 moves (ticks, largest less smallest position) over ``seconds`` of
    the bus's clock, looked at every 50 ms: over a whole cycle of the gait, its range."""
    over = rig.lasting(seconds, rig.bus_now)
    seen: list[float] = []
    while True:
        with rig.lock:
            seen.append(rig.bus.positions([2])[0])
        if over():
            return max(seen) - min(seen)
        time.sleep(0.05)


def after_brownout(long: bool) -> Callable[[Rig, Outcome, Sample], None]:
    def check(rig: Rig, out: Outcome, last: Sample) -> None:
        unanswered = out.counts["servo2_reads_unanswered"]
        out.check("counted", unanswered > 0, "no READ of servo 2 went unanswered")
        if long:
            out.check(
                "counted",
                rig.health.flags_seen & ControllerErrors.BUS_LOSS,
                "the brown-out never raised BUS_LOSS",
            )
            out.check("counted", rig.health.safe_entries >= 1, "the controller never went SAFE")
            out.check("counted", rig.tap.torque_off >= 1, "no torque-off was sent on SAFE")
        else:
            out.check("alive", rig.health.safe_entries == 0, "a short brown-out tripped SAFE")

    return check
