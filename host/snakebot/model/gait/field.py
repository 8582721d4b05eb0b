"""Gaits that follow a control vector field or a combination such as ``2*g1-h3``.

X = sum_i a_i g_i + sum_k b_k h_k is followed in K blocks, each realising eps X
(``eps * K = tau``, the flow parameter of X):

* the direct part: constant inputs u = a for time eps (exact: the flow of sum a_i g_i);
* each bracket term, one whole period of periodic inputs whose net motion is, to
  leading order, eps b_k h_k (docs/models.md):
  - second order [g_i, g_j] (the trident's h1..h3, the 3-link snake's h1): a loop
    u_i = -A w sin(w t), u_j = +-A w cos(w t), moving +-pi A^2 [g_i, g_j];
  - third order [g_i, [g_i, g_j]] (the 3-link snake's h2 = [g1, h1], h3 = [g2, h1]):
    u_i = A w cos(w t), u_j = 2 B w cos(2 w t), moving -(pi A^2 B / 2) [g_i, [g_i, g_j]]
    (from the Chen-Fliess series; the area term vanishes over a period).

The leading-order error of a block is relative O(A) (second order), O(A^2) (third
order) or O(eps) (direct part), so shrinking the blocks (more, smaller loops) meets a
requested ``tolerance``; it is measured on the first block, not assumed. Each segment is
then timed as fast as the servos allow (a driftless system follows the same path at any
speed), with loop periods a whole number of frames so the table samples them exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cached_property
from typing import Any

import numpy as np

from snakebot.formats.gaittable import max_frames
from snakebot.model.gait.common import (
    PREDICT_OPTIONS,
    Gait,
    GaitError,
    frame_budget,
    motion,
    path,
    period_ms_for,
    predict_table,
    singularity_warnings,
)
from snakebot.model.gait.limits import check_motion, check_ticks
from snakebot.model.gait.values import parse_field_expression
from snakebot.model.kinematics import (
    BRACKETS,
    FIELD_NAMES,
    Inputs,
    Trajectory,
    default_form,
    field_model,
    field_velocity,
    fields,
    integrate_fields,
)
from snakebot.model.robots import Robot

#: Share of the servo's maximum speed a gait is timed to (rounding to ticks adds some).
SPEED_MARGIN = 0.8
#: A loop is sampled by at least this many frames.
MIN_FRAMES_PER_PERIOD = 16
#: Tolerance used when neither an amplitude nor a tolerance is given.
DEFAULT_TOLERANCE = 0.05
DENSE = 4  # integration samples per frame for the limit checks
#: Flow parameter a gait with brackets follows for when neither a duration nor periods
#: are given (fewer blocks if the table cannot hold them; the summary gives the value used).
AUTO_FLOW = 1.0


@dataclass(frozen=True)
class Segment:
    """Inputs over a normalised time ``length`` (omega = 1 for loops)."""

    term: str  # "direct" or the bracket's name
    inputs: Inputs
    length: float
    loop: bool


def bracket_order(model: str, name: str) -> int:
    """2 for [g_i, g_j], 3 for [g_i, [g_i, g_j]]."""
    a, b = BRACKETS[model][name]
    return 3 if b.startswith("h") else 2


def _index(name: str) -> int:
    return int(name[1:]) - 1


def plan_block(
    model: str, combo: dict[str, float], eps: float, form: str | None, inputs: int
) -> list[Segment]:
    """The segments of one block realising eps * X (normalised time)."""
    zero = (0.0,) * inputs
    segments: list[Segment] = []
    direct = [combo.get(f"g{i + 1}", 0.0) for i in range(inputs)]
    if any(direct):
        segments.append(Segment("direct", Inputs(tuple(direct), form=form, omega=1.0), eps, False))
    for name, coef in combo.items():
        if not name.startswith("h"):
            continue
        a, b = BRACKETS[model][name]
        sign = math.copysign(1.0, coef)
        if bracket_order(model, name) == 2:
            amp = math.sqrt(eps * abs(coef) / math.pi)
            i, j = _index(a), _index(b)
            sa, ca = list(zero), list(zero)
            sa[i] = -amp
            ca[j] = sign * amp
            inp = Inputs(zero, tuple(sa), tuple(ca), 1.0, form)
        else:
            # [g_i, [g_i, g_j]]: u_i = A cos t, u_j = 2 B cos 2t moves -(pi A^2 B / 2) of it.
            inner_a, inner_b = BRACKETS[model][b]
            i = _index(a)
            j = _index(inner_b if inner_a == a else inner_a)
            # h = [g_i, [g_i, g_j]] if the inner bracket is [g_i, g_j], else minus that.
            orient = 1.0 if inner_a == a else -1.0
            amp = (2.0 * eps * abs(coef) / math.pi) ** (1.0 / 3.0)
            ca, c2 = list(zero), list(zero)
            ca[i] = amp
            c2[j] = -2.0 * sign * orient * amp
            inp = Inputs(zero, b=tuple(ca), b2=tuple(c2), omega=1.0, form=form)
        segments.append(Segment(name, inp, 2.0 * math.pi, True))
    return segments


def _run(robot: Robot, segments: list[Segment], q0: np.ndarray) -> np.ndarray:
    """Final state after the segments, at normalised speed."""
    q = q0
    for seg in segments:
        q = integrate_fields(
            robot, seg.inputs, seg.length, q0=q, samples=2, options=PREDICT_OPTIONS
        ).q[-1]
    return q


@dataclass(frozen=True)
class _Target:
    """What a field gait follows: the combination X of ``robot``'s fields (``combo``,
    written ``text``) in the field ``model`` and ``form``, from the joint angles ``start``."""

    robot: Robot
    model: str
    form: str
    combo: dict[str, float]
    text: str
    start: tuple[float, ...]

    @property
    def field_form(self) -> str | None:
        """The form the fields are computed in: the trident's, none for a snake."""
        return self.form if self.robot.kind == "trident" else None

    @property
    def brackets(self) -> list[str]:
        return [n for n in self.combo if n.startswith("h")]

    @property
    def q0(self) -> np.ndarray:
        return np.r_[0.0, 0.0, 0.0, np.asarray(self.start, dtype=float)]

    @cached_property
    def x0(self) -> np.ndarray:
        """X(q0), the combination's velocity at the start; GaitError if q0 is singular."""
        at_start = fields(self.robot, self.q0, self.field_form)
        if at_start.singular:
            raise GaitError(
                f"the start configuration {np.round(self.start, 4).tolist()} is singular "
                f"for {self.robot.name}: choose another start"
            ).about("start")
        return sum(coef * at_start[name] for name, coef in self.combo.items())

    def block(self, eps: float) -> list[Segment]:
        """The segments of one block realising eps X (normalised time)."""
        inputs = 2 if self.model == "snake3" else 3
        return plan_block(self.model, self.combo, eps, self.field_form, inputs)

    def block_error(self, eps: float, q0: np.ndarray) -> float:
        """The relative error of one block of eps X from ``q0``."""
        return self.relative_error(eps, q0, _run(self.robot, self.block(eps), q0) - q0)

    def relative_error(self, eps: float, q0: np.ndarray, moved: np.ndarray) -> float:
        """|moved - eps X(q0)| / |eps X(q0)|: how far a block from q0 missed its target."""
        f = fields(self.robot, q0, self.field_form)
        target = eps * sum(coef * f[name] for name, coef in self.combo.items())
        return float(np.linalg.norm(moved - target) / np.linalg.norm(target))


@dataclass(frozen=True)
class _Blocks:
    """``count`` blocks of eps X each; ``err``: the first block's relative error."""

    eps: float
    count: int
    err: float


def _joint_speeds(robot: Robot, traj: Trajectory, inputs: Inputs) -> np.ndarray:
    """Joint velocities along a segment's trajectory (its own clock, from 0)."""
    u = inputs.at(traj.t)
    return np.array(
        [field_velocity(robot, q, ui, inputs.form)[3:] for q, ui in zip(traj.q, u, strict=True)]
    )


def _timed(
    robot: Robot, seg: Segment, q0: np.ndarray, dt: float, omega: float | None
) -> tuple[Segment, int]:
    """The segment sped up to the servos' limit: (real-time segment, frames it spans)."""
    probe = integrate_fields(
        robot, seg.inputs, seg.length, q0=q0, samples=257, options=PREDICT_OPTIONS
    )
    peak = float(np.abs(_joint_speeds(robot, probe, seg.inputs)).max())
    fastest = SPEED_MARGIN * robot.max_speed_rad_s / peak if peak > 0 else 1.0
    if seg.loop:
        speed = omega if omega is not None else fastest
        frames = max(MIN_FRAMES_PER_PERIOD, math.ceil(seg.length / (speed * dt) - 1e-9))
        if omega is not None:
            frames = max(1, round(seg.length / (omega * dt)))
    else:
        frames = max(1, math.ceil(seg.length / (fastest * dt) - 1e-9))
    speed = seg.length / (frames * dt)  # normalised time per second
    k = seg.inputs
    scaled = Inputs(
        tuple(speed * v for v in k.c),
        tuple(speed * v for v in k.a),
        tuple(speed * v for v in k.b),
        speed * k.omega,
        k.form,
        tuple(speed * v for v in k.a2),
        tuple(speed * v for v in k.b2),
    )
    return replace(seg, inputs=scaled, length=frames * dt), frames


def field_gait(
    robot: Robot,
    expression: str | dict[str, float],
    *,
    duration: float | None = None,
    periods: int | None = None,
    amplitude: float | None = None,
    omega: float | None = None,
    tolerance: float | None = None,
    start: tuple[float, ...] | None = None,
    form: str | None = None,
    rate_hz: float = 50.0,
) -> Gait:
    """A gait following the field combination ``expression`` (see the module doc)."""
    target = _target(robot, expression, form or default_form(robot), start)
    _check_request(target, duration, periods, amplitude, omega, tolerance)
    period_ms = period_ms_for(rate_hz)
    dt = period_ms / 1000.0
    _check_start(target)
    blocks = _blocks(target, duration, periods, amplitude, tolerance)
    block = target.block(blocks.eps)
    timed = [_timed(robot, seg, target.q0, dt, omega) for seg in block]
    block_frames = sum(frames for _, frames in timed)
    if duration is None and periods is None:
        blocks = replace(blocks, count=_auto_count(robot, blocks.eps, block_frames))
    frame_budget(
        robot,
        blocks.count * block_frames + 1,
        "loosen the tolerance, raise the amplitude, or shorten the duration or the periods",
        "tolerance",
        "amplitude",
        "duration",
        "periods",
    )
    segments = [seg for seg, _ in timed]
    traj, dphi, block_errors = _follow(target, segments, blocks, dt)
    check_motion(robot, traj.t, traj.q[:, 3:], dphi)
    parameters = _parameters(target, blocks, block_errors, period_ms, segments, block)
    return _gait(target, blocks, period_ms, traj, parameters)


def _target(
    robot: Robot, expression: str | dict[str, float], form: str, start: tuple[float, ...] | None
) -> _Target:
    """The combination ``expression`` of ``robot``'s fields, parsed and named, from
    ``start`` (by default the thesis's pi/3, -pi/3 for the 3-link snake, else zeros)."""
    model = field_model(robot)
    combo = (
        parse_field_expression(expression, FIELD_NAMES[model])
        if isinstance(expression, str)
        else dict(expression)
    )
    text = (
        expression
        if isinstance(expression, str)
        else " + ".join(f"{v:g}*{k}" for k, v in combo.items())
    )
    if start is None:
        start = (math.pi / 3, -math.pi / 3) if model == "snake3" else (0.0,) * robot.n_joints
    return _Target(robot, model, form, combo, text, start)


def _check_request(
    target: _Target,
    duration: float | None,
    periods: int | None,
    amplitude: float | None,
    omega: float | None,
    tolerance: float | None,
) -> None:
    """GaitError for a request that does not say how far to follow ``target``, or how."""
    brackets = target.brackets
    if duration is not None and periods is not None:
        raise GaitError("give a duration or a number of periods, not both").about(
            "duration", "periods"
        )
    auto = duration is None and periods is None  # the longest the accuracy allows
    if auto and not brackets:
        raise GaitError(
            f"{target.text} has no bracket term: give the duration to follow it for"
        ).about("duration")
    if auto and amplitude is not None:
        raise GaitError("a loop amplitude needs a duration or a number of periods too").about(
            "amplitude", "duration", "periods"
        )
    if duration is not None and not (duration > 0 and math.isfinite(duration)):
        raise GaitError(f"the duration must be positive, not {duration}").about("duration")
    if periods is not None and (periods < 1 or not brackets):
        raise GaitError(
            "a number of periods needs 1 or more and a bracket term (h...) in the field: "
            "a direct field is followed for a duration"
        ).about("periods", "expression")
    if amplitude is not None and not amplitude > 0:
        raise GaitError(f"the loop amplitude must be positive, not {amplitude}").about("amplitude")
    if tolerance is not None and not 0 < tolerance < 1:
        raise GaitError(
            f"the tolerance is a relative error between 0 and 1, not {tolerance}"
        ).about("tolerance")
    if omega is not None and not omega > 0:
        raise GaitError(f"the loop frequency must be positive, not {omega}").about("omega")
    if amplitude is not None and tolerance is not None:
        raise GaitError(
            "give a loop amplitude or a tolerance, not both: the tolerance picks the amplitude"
        ).about("amplitude", "tolerance")


def _check_start(target: _Target) -> None:
    """GaitError if the start is not one angle per joint, or is singular."""
    robot = target.robot
    if len(target.start) != robot.n_joints:
        raise GaitError(f"the start needs {robot.n_joints} joint angles for {robot.name}").about(
            "start"
        )
    target.x0  # noqa: B018 - computed now: it refuses a singular start before any work


def _blocks(
    target: _Target,
    duration: float | None,
    periods: int | None,
    amplitude: float | None,
    tolerance: float | None,
) -> _Blocks:
    """The block size eps and count K: the direct field in one block, loops of a given
    ``amplitude``, or loops shrunk until a block errs by at most ``tolerance``."""
    if not target.brackets:
        assert duration is not None  # _check_request: a direct field needs a duration
        return _Blocks(float(duration), 1, 0.0)
    order = max(bracket_order(target.model, b) for b in target.brackets)
    if amplitude is not None:
        eps = _loop_eps(order, amplitude)
        if periods is None:
            assert duration is not None  # _check_request: an amplitude needs one of them
            count = max(1, round(duration / eps))
            eps = duration / count
        else:
            count = periods
        return _Blocks(eps, count, target.block_error(eps, target.q0))
    tol = tolerance or DEFAULT_TOLERANCE
    blocks = _shrink(target, duration, periods, tol, order)
    if blocks.err > tol:
        # the error scales as eps^(1/exponent): the duration that would meet tol
        exponent = 2.0 if order == 2 else 3.0
        fits = blocks.count * blocks.eps * 0.8 * (tol / blocks.err) ** exponent
        raise GaitError(
            f"cannot follow {target.text} to within {tol:g} for a duration of {duration:g}: "
            f"{blocks.count} blocks of loops (the most a gait table of "
            f"{target.robot.n_joints} joints holds) still err by {blocks.err:.3g}: shorten "
            f"the duration to about {fits:.3g}, loosen the tolerance to {blocks.err:.2g}, "
            "or leave the duration out to get the longest motion that meets the tolerance"
        ).about("duration", "tolerance")
    return blocks


def _loop_eps(order: int, amplitude: float) -> float:
    """The block size eps a loop of ``amplitude`` realises for a bracket of ``order``."""
    return math.pi * amplitude**2 if order == 2 else math.pi * amplitude**3 / 2.0


def _shrink(
    target: _Target, duration: float | None, periods: int | None, tol: float, order: int
) -> _Blocks:
    """Smaller blocks until one errs by at most ``tol``: smaller loops without a
    ``duration``, more of them within one (up to what the table holds)."""
    exponent = 2.0 if order == 2 else 3.0  # relative error ~ eps^(1/exponent)
    # Fewest frames a block can take: each loop is sampled by a minimum of frames.
    n_brackets = len(target.brackets)
    block_frames = MIN_FRAMES_PER_PERIOD * n_brackets + (len(target.combo) > n_brackets)
    most_blocks = max(1, (max_frames(target.robot.n_joints) - 1) // block_frames)
    eps = _loop_eps(order, 0.3) if duration is None else duration
    count = periods or 1
    for _ in range(16):
        err = target.block_error(eps, target.q0)
        if err <= tol:
            break
        shrink = min(0.5, 0.8 * (tol / err) ** exponent)
        if duration is None:
            eps *= shrink
        elif count >= most_blocks:
            break
        else:
            count = min(most_blocks, max(count + 1, math.ceil(count / shrink)))
            eps = duration / count
    return _Blocks(eps, count, err)


def _auto_count(robot: Robot, eps: float, block_frames: int) -> int:
    """As many blocks as reach AUTO_FLOW, or as the table holds."""
    fit = max(1, (max_frames(robot.n_joints) - 1) // block_frames)
    return max(1, min(fit, math.ceil(AUTO_FLOW / eps - 1e-9)))


def _follow(
    target: _Target, timed: list[Segment], blocks: _Blocks, dt: float
) -> tuple[Trajectory, np.ndarray, list[float]]:
    """The whole gait, segment after segment, sampled DENSE times per frame: its
    trajectory, joint velocities, and each block's relative error."""
    robot, q = target.robot, target.q0
    t_all, q_all, dphi_all = [np.zeros(1)], [q[None, :]], [np.zeros((1, robot.n_joints))]
    t = 0.0
    block_errors = []
    for _ in range(blocks.count):
        q_block = q
        for seg in timed:
            steps = round(seg.length / dt)
            # Each segment's inputs run on its own clock from 0, as block_error simulated
            # them: a loop must start at phase 0 wherever it falls in the gait.
            traj = integrate_fields(
                robot,
                seg.inputs,
                seg.length,
                q0=q,
                samples=DENSE * steps + 1,
                options=PREDICT_OPTIONS,
            )
            speeds = _joint_speeds(robot, traj, seg.inputs)
            t_all.append(t + traj.t[1:])
            q_all.append(traj.q[1:])
            dphi_all.append(speeds[1:])
            dphi_all[0] = speeds[:1] if len(t_all) == 2 else dphi_all[0]
            t, q = t + seg.length, traj.q[-1]
        block_errors.append(target.relative_error(blocks.eps, q_block, q - q_block))
    return Trajectory(np.concatenate(t_all), np.vstack(q_all)), np.vstack(dphi_all), block_errors


def _parameters(
    target: _Target,
    blocks: _Blocks,
    block_errors: list[float],
    period_ms: int,
    timed: list[Segment],
    block: list[Segment],
) -> dict[str, Any]:
    """The gait's parameters as its metadata records them."""
    dt = period_ms / 1000.0
    return {
        "field": target.text,
        "coefficients": target.combo,
        "form": target.form,
        "start_rad": [float(v) for v in target.start],
        "blocks": blocks.count,
        "block_eps": blocks.eps,
        "flow_parameter": blocks.count * blocks.eps,
        "block_relative_error": blocks.err,
        "block_errors_max": max(block_errors),
        "rate_hz": 1000.0 / period_ms,
        "segments": [
            {
                "term": s.term,
                "frames": round(s.length / dt),
                "omega_rad_s": s.inputs.omega if s.loop else None,
                "amplitude": _amplitude(seg) if seg.loop else None,
            }
            for s, seg in zip(timed, block, strict=True)
        ],
    }


def _gait(
    target: _Target, blocks: _Blocks, period_ms: int, traj: Trajectory, parameters: dict[str, Any]
) -> Gait:
    """The gait table of the followed motion ``traj``, checked, with its predictions."""
    robot, dt = target.robot, period_ms / 1000.0
    phi_frames = traj.q[::DENSE, 3:]
    loop = bool(np.allclose(phi_frames[-1], phi_frames[0], atol=1e-9))
    if loop:
        phi_frames = phi_frames[:-1]
    ticks = robot.angles_to_ticks(phi_frames)
    check_ticks(robot, ticks, dt, loop)
    table_traj, note = predict_table(robot, ticks, dt, loop)
    moved = traj.q[-1] - traj.q[0]
    predicted = {"dx": float(moved[0]), "dy": float(moved[1]), "dtheta": float(moved[2])}
    return Gait(
        robot,
        "field",
        parameters,
        period_ms,
        loop,
        ticks,
        predicted,
        {**motion(table_traj), **note},
        path(traj),
        path(table_traj),
        _extra(target, traj, blocks.count * blocks.eps),
        # the field-driven path has no wheel problem to condition; the table is played
        # through the joints, as the robot will
        singularity_warnings({"table as written": table_traj}),
    )


def _extra(target: _Target, traj: Trajectory, tau: float) -> dict[str, Any]:
    """The gait's final and moved state beside the motion tau X(q0) predicts."""
    brackets = bool(target.brackets)
    predicted_q = tau * target.x0
    formula = f"{tau:.6g} * ({target.text}) at the start configuration"
    if brackets:
        formula += (
            "; each loop moves pi A^2 [g_i, g_j] (second order) or "
            "-pi A^2 B / 2 [g_i, [g_i, g_j]] (third order)"
        )
    return {
        "state_names": list(target.robot.state_names),
        "final_q": traj.q[-1].tolist(),
        "moved_q": (traj.q[-1] - traj.q[0]).tolist(),
        ("second_order" if brackets else "first_order"): {
            "dx": float(predicted_q[0]),
            "dy": float(predicted_q[1]),
            "dtheta": float(predicted_q[2]),
            "q": predicted_q.tolist(),
            "formula": formula,
        },
    }


def _amplitude(seg: Segment) -> float:
    k = seg.inputs
    values = [abs(v) for v in (*k.a, *k.b, *k.b2)]
    return float(max(values)) if values else 0.0
