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
#: Tolerance used when neither --amplitude nor --tolerance is given.
DEFAULT_TOLERANCE = 0.05
DENSE = 4  # integration samples per frame for the limit checks
#: Flow parameter a gait with brackets follows for when no --duration or --periods is
#: given (fewer blocks if the table cannot hold them; the summary gives the value used).
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


def block_error(
    robot: Robot, model: str, combo: dict[str, float], eps: float, form: str | None, q0: np.ndarray
) -> tuple[float, np.ndarray]:
    """Relative error of one block against eps X(q0), and the block's motion."""
    inputs = 2 if model == "snake3" else 3
    moved = _run(robot, plan_block(model, combo, eps, form, inputs), q0) - q0
    return _relative_error(robot, combo, eps, form, q0, moved), moved


def _relative_error(
    robot: Robot,
    combo: dict[str, float],
    eps: float,
    form: str | None,
    q0: np.ndarray,
    moved: np.ndarray,
) -> float:
    """|moved - eps X(q0)| / |eps X(q0)|: how far a block from q0 missed its target."""
    f = fields(robot, q0, form)
    target = eps * sum(coef * f[name] for name, coef in combo.items())
    return float(np.linalg.norm(moved - target) / np.linalg.norm(target))


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
    model = field_model(robot)
    form = form or default_form(robot)
    c_form = None if robot.kind != "trident" else form
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
    brackets = [n for n in combo if n.startswith("h")]
    if duration is not None and periods is not None:
        raise GaitError("give one of --duration T or --periods K, not both")
    auto = duration is None and periods is None  # the longest the accuracy allows
    if auto and not brackets:
        raise GaitError(f"{text} has no bracket term: give --duration T to follow it for")
    if auto and amplitude is not None:
        raise GaitError("with --amplitude, give --duration T or --periods K too")
    if duration is not None and not (duration > 0 and math.isfinite(duration)):
        raise GaitError(f"--duration must be positive, not {duration}")
    if periods is not None and (periods < 1 or not brackets):
        raise GaitError(
            "--periods K needs K >= 1 and a bracket term (h...) in --field: "
            "a direct field is followed for --duration T"
        )
    if amplitude is not None and not amplitude > 0:
        raise GaitError(f"--amplitude must be positive, not {amplitude}")
    if tolerance is not None and not 0 < tolerance < 1:
        raise GaitError(f"--tolerance is a relative error between 0 and 1, not {tolerance}")
    if omega is not None and not omega > 0:
        raise GaitError(f"--omega must be positive, not {omega}")
    if amplitude is not None and tolerance is not None:
        raise GaitError(
            "give --amplitude or --tolerance, not both: the tolerance picks the amplitude"
        )
    period_ms = period_ms_for(rate_hz)
    dt = period_ms / 1000.0
    if start is None:
        start = (math.pi / 3, -math.pi / 3) if model == "snake3" else (0.0,) * robot.n_joints
    if len(start) != robot.n_joints:
        raise GaitError(f"--start needs {robot.n_joints} joint angles for {robot.name}")
    q0 = np.r_[0.0, 0.0, 0.0, np.asarray(start, dtype=float)]
    at_start = fields(robot, q0, c_form)
    if at_start.singular:
        raise GaitError(
            f"the start configuration {np.round(start, 4).tolist()} is singular "
            f"for {robot.name}: choose another --start"
        )
    x0 = sum(coef * at_start[name] for name, coef in combo.items())

    # Block size eps and count K.
    order = max((bracket_order(model, b) for b in brackets), default=1)
    inputs = 2 if model == "snake3" else 3
    if not brackets:
        eps, count, err = float(duration), 1, 0.0
    else:

        def eps_of(a: float) -> float:
            return math.pi * a * a if order == 2 else math.pi * a**3 / 2.0

        if amplitude is not None:
            eps0 = eps_of(amplitude)
            count = periods if periods is not None else max(1, round(duration / eps0))
            eps = eps0 if periods is not None else duration / count
            err = block_error(robot, model, combo, eps, c_form, q0)[0]
        else:
            tol = tolerance or DEFAULT_TOLERANCE
            exponent = 2.0 if order == 2 else 3.0  # relative error ~ eps^(1/exponent)
            # Fewest frames a block can take: each loop is sampled by a minimum of frames.
            block_frames = MIN_FRAMES_PER_PERIOD * len(brackets) + (len(combo) > len(brackets))
            most_blocks = max(1, (max_frames(robot.n_joints) - 1) // block_frames)
            eps = eps_of(0.3) if duration is None else duration
            count = periods or 1
            for _ in range(16):
                err = block_error(robot, model, combo, eps, c_form, q0)[0]
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
            if err > tol:
                # the error scales as eps^(1/exponent): the duration that would meet tol
                fits = count * eps * 0.8 * (tol / err) ** exponent
                raise GaitError(
                    f"cannot follow {text} to within {tol:g} for --duration {duration:g}: "
                    f"{count} blocks of loops (the most a gait table of {robot.n_joints} "
                    f"joints holds) still err by {err:.3g}: shorten --duration to about "
                    f"{fits:.3g}, loosen --tolerance to {err:.2g}, or leave --duration out "
                    "to get the longest motion that meets the tolerance"
                )

    block = plan_block(model, combo, eps, c_form, inputs)
    timed: list[Segment] = []
    total_frames = 0
    for seg in block:
        s, frames = _timed(robot, seg, q0, dt, omega)
        timed.append(s)
        total_frames += frames
    if auto:
        # As many blocks as reach AUTO_FLOW, or as the table holds.
        fit = max(1, (max_frames(robot.n_joints) - 1) // total_frames)
        count = max(1, min(fit, math.ceil(AUTO_FLOW / eps - 1e-9)))
    frame_budget(
        robot,
        count * total_frames + 1,
        "loosen --tolerance, raise --amplitude, or shorten --duration/--periods",
    )

    # The whole gait, segment after segment, sampled DENSE times per frame.
    t_all, q_all, dphi_all = [np.zeros(1)], [q0[None, :]], [np.zeros((1, robot.n_joints))]
    t, q = 0.0, q0
    block_errors = []
    for _ in range(count):
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
        block_errors.append(_relative_error(robot, combo, eps, c_form, q_block, q - q_block))
    times, states, dphi = np.concatenate(t_all), np.vstack(q_all), np.vstack(dphi_all)
    check_motion(robot, times, states[:, 3:], dphi)

    phi_frames = states[::DENSE, 3:]
    loop = bool(np.allclose(phi_frames[-1], phi_frames[0], atol=1e-9))
    if loop:
        phi_frames = phi_frames[:-1]
    ticks = robot.angles_to_ticks(phi_frames)
    check_ticks(robot, ticks, dt, loop)
    traj = Trajectory(times, states)
    table_traj, note = predict_table(robot, ticks, dt, loop)

    moved = states[-1] - q0
    tau = count * eps
    predicted_q = tau * x0
    parameters = {
        "field": text,
        "coefficients": combo,
        "form": form,
        "start_rad": [float(v) for v in start],
        "blocks": count,
        "block_eps": eps,
        "flow_parameter": tau,
        "block_relative_error": err,
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
    extra = {
        "state_names": list(robot.state_names),
        "final_q": states[-1].tolist(),
        "moved_q": moved.tolist(),
        ("second_order" if brackets else "first_order"): {
            "dx": float(predicted_q[0]),
            "dy": float(predicted_q[1]),
            "dtheta": float(predicted_q[2]),
            "q": predicted_q.tolist(),
            "formula": (
                f"{tau:.6g} * ({text}) at the start configuration"
                + (
                    "; each loop moves pi A^2 [g_i, g_j] (second order) or "
                    "-pi A^2 B / 2 [g_i, [g_i, g_j]] (third order)"
                    if brackets
                    else ""
                )
            ),
        },
    }
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
        extra,
        # the field-driven path has no wheel problem to condition; the table is played
        # through the joints, as the robot will
        singularity_warnings({"table as written": table_traj}),
    )


def _amplitude(seg: Segment) -> float:
    k = seg.inputs
    values = [abs(v) for v in (*k.a, *k.b, *k.b2)]
    return float(max(values)) if values else 0.0
