"""`snakebot gait search --world mujoco`: each run is the gait played on the emulated bus
with the physics world (the same motion `sim predict --world mujoco` reports), with the
motors' energy, over a range of floor friction."""

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

from snakebot.cli import main
from snakebot.model.gait import serpenoid
from snakebot.model.robots import load_robot
from snakebot.workflows.predict import predict_gait
from snakebot.workflows.search import Settings, evaluate
from snakebot.workflows.search.results import read_results

pytest.importorskip("mujoco")

POINT = {"amplitude": math.radians(30), "omega": math.radians(360), "delta": math.radians(60)}


def test_a_physics_run_is_the_gait_played_in_the_physics_world():
    row = evaluate(Settings("snake5", "mujoco", 2, 50), {**POINT, "offset": 0.0, "mu": 0.5})
    assert row["status"] == "ok", row["reason"]
    robot = load_robot("snake5")
    table = serpenoid(robot, *POINT.values(), cycles=2, rate_hz=50).gait_table()
    played = predict_gait(table, robot, world="mujoco", mu=0.5).emulated
    d = played.displacement()
    assert (row["dx"], row["dy"], row["dtheta"]) == pytest.approx((d["dx"], d["dy"], d["dtheta"]))
    work = float(np.sum(played.energy))
    electrical = float(np.sum(played.electrical))
    assert row["work_j"] == pytest.approx(work) and work > 0
    # the electrical energy adds the windings' loss to the work: more than the work
    assert row["electrical_j"] == pytest.approx(electrical) and electrical > work
    # efficiency: distance per joule drawn from the supply, not per joule of work
    assert row["efficiency"] == pytest.approx(math.hypot(d["dx"], d["dy"]) / electrical)
    assert row["slip_per_cycle"] == pytest.approx(float(np.sum(played.slip_distance())) / 2)


def test_an_efficiency_search_over_friction_keeps_each_floor_and_the_worst(tmp_path):
    out = tmp_path / "runs.csv"
    result = CliRunner().invoke(
        main,
        [
            "gait",
            "search",
            "snake5",
            "--world",
            "mujoco",
            "--objective",
            "efficiency",
            "--param",
            "A=20deg:30deg:2",
            "--param",
            "delta=60deg",
            "--param",
            "omega=360deg",
            "--robust",
            "friction.lateral=0.05:0.8:2",
            "--cycles",
            "1",
            "--workers",
            "2",
            "-o",
            out,
            "--json",
        ],
        catch_exceptions=False,
    )
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    rows = read_results(out)
    assert len(rows) == 4 and all(r["status"] == "ok" for r in rows)
    assert all(r["electrical_j"] > r["work_j"] > 0 for r in rows)
    # a slippery floor takes the snake less far for its energy than a grippy one
    for a in {r["amplitude"] for r in rows}:
        floor = {r["mu"]: r for r in rows if r["amplitude"] == a}
        assert floor[0.05]["efficiency"] < floor[0.8]["efficiency"]
    best = summary["best"]
    mine = [r for r in rows if r["amplitude"] == pytest.approx(best["parameters"]["amplitude"])]
    assert best["efficiency"] == pytest.approx(min(r["efficiency"] for r in mine))


def test_a_heavier_robot_costs_more_energy_for_the_same_gait():
    settings = Settings("snake5", "mujoco", 2, 50)
    runs = [evaluate(settings, {**POINT, "offset": 0.0, "mass": m}) for m in (0.5, 1.0, 3.0)]
    assert all(r["status"] == "ok" for r in runs)
    energy = [r["electrical_j"] for r in runs]
    assert energy[0] < energy[1] < energy[2]
    # a factor of 1 is the robot as described
    plain = evaluate(settings, {**POINT, "offset": 0.0})
    assert runs[1]["electrical_j"] == pytest.approx(plain["electrical_j"])
