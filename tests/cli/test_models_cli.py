"""`snakebot model ...` from the command line."""

import json
import math

import numpy as np
import pytest
import sympy as sp
from click.testing import CliRunner

from snakebot.cli import main


def run(*args):
    return CliRunner().invoke(main, list(args), catch_exceptions=False)


def test_fields_json_at_the_thesis_q0():
    result = run("model", "fields", "snake3", "--at", "0,0,0,pi/3,-60deg", "--json")
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    assert data["robot"] == "snake3" and data["singular"] is False
    assert list(data["fields"]) == ["g1", "g2", "h1", "h2", "h3"]
    np.testing.assert_allclose(
        data["fields"]["h3"], [8 * math.sqrt(3) / 27, -4 / 9, 2 / 9, 0, 0], atol=1e-9
    )
    assert data["growth"] == [2, 3, 5]
    assert data["q"][4] == -math.pi / 3


def test_fields_text_and_singular_point():
    result = run("model", "fields", "trident", "--at", "0,0,0,0,0,0")
    assert result.exit_code == 0
    assert "growth vector: (3, 6)" in result.output and "det G* = 2.59807621" in result.output
    singular = json.loads(
        run("model", "fields", "snake3", "--at", "0,0,0,0.2,0.2", "--json").output
    )
    assert singular["singular"] is True and singular["fields"] is None


def test_wrong_arguments_are_clear():
    result = run("model", "fields", "snake3", "--at", "0,0,0,1")
    assert result.exit_code == 2 and "give 5 values, got 4" in result.output
    result = run("model", "fields", "snake5", "--at", "0,0,0,0,0,0,0", "--depth", "9")
    assert (
        result.exit_code == 2 and "error:" in result.output and "between 1 and 8" in result.output
    )
    result = run("model", "fields", "trident", "--at", "0,0,0,0,0,0", "--depth", "3")
    assert result.exit_code == 2 and "--depth applies to snakes and the car" in result.output
    result = run("model", "fields", "snake3", "--at", "0,0,0,1,x")
    assert result.exit_code == 2 and "cannot read 'x'" in result.output


def test_symbolic_trident_expressions_evaluate_to_the_corrected_h2():
    data = json.loads(
        run("model", "fields", "trident", "--at", "0,0,0,0,0,0", "--symbolic", "--json").output
    )
    names = sp.symbols("x y theta phi1 phi2 phi3")
    subs = {**{s: 0 for s in names}, sp.Symbol("r"): 1, sp.Symbol("l"): 1}
    h2 = [float(sp.sympify(e).subs(subs)) for e in data["fields"]["h2"]]
    np.testing.assert_allclose(h2, [0, -1, 0, -1, 2, -1], atol=1e-12)


def test_malformed_robot_file_names_key_and_line(tmp_path):
    bad = tmp_path / "bad.toml"
    joint = "[[joints]]\nservo_id = {}\nzero_tick = 512\nsign = 1\nmin_deg = -9\nmax_deg = 9\n"
    bad.write_text(
        'name = "b"\nkind = "snake"\n[geometry]\nlinks = 3\nhalf_link = "long"\n'
        + joint.format(1)
        + joint.format(2)
    )
    result = run("model", "info", str(bad))
    assert result.exit_code == 2
    assert f"error: {bad}, line 5: key 'geometry.half_link'" in result.output


def test_info_json():
    data = json.loads(run("model", "info", "snake5", "--json").output)
    assert [j["servo_id"] for j in data["joints"]] == [10, 11, 15, 16]
    friction = data["friction"]
    assert (friction["lateral"], friction["rolling"], friction["axle_nm"]) == (0.8, 0.01, 3e-4)
    # each wheel carries a link and its wheel: (0.08 + 0.01) kg under standard gravity
    assert friction["wheel_loads_n"] == pytest.approx([0.09 * 9.80665] * 5)


def test_growth_near_the_singular_line_and_the_folded_singularity():
    near = run("model", "fields", "snake3", "--at", "0,0,0,0.3,0.294")
    assert near.exit_code == 0, near.output
    assert "growth vector: (2, 3, 5)" in near.output and "condition number" in near.output
    data = json.loads(run("model", "fields", "snake3", "--at", "0,0,0,0.3,0.294", "--json").output)
    assert data["growth"] == [2, 3, 5] and data["condition"] > 1e6
    folded = run("model", "fields", "snake3", "--at", "0,0,0,pi,0.3")
    assert folded.exit_code == 0 and "singular: yes" in folded.output
    assert "phi1 = +-pi" in folded.output and "here phi1 = phi2" not in folded.output


def test_five_link_fields_text_and_json():
    at = "0,0,0,0.3,-0.2,0.4,0.1"
    text = run("model", "fields", "snake5", "--at", at)
    assert text.exit_code == 0, text.output
    assert "[g1,[g1,g2]]" in text.output and "growth vector: (2, 3, 5)" in text.output
    data = json.loads(run("model", "fields", "snake5", "--at", at, "--depth", "4", "--json").output)
    assert data["growth"] == [2, 3, 5, 6] and data["depth"] == 4 and not data["singular"]
    assert len(data["fields"]) == 8 and data["condition"] > 1
    straight = json.loads(
        run("model", "fields", "snake5", "--at", "0,0,0,0,0,0,0", "--json").output
    )
    assert straight["singular"] and straight["singular_where"] == "phi1 = phi2"


def test_car_fields_and_growth():
    result = run("model", "fields", "car", "--at", "0,0,pi/6,0.3")
    assert result.exit_code == 0, result.output
    assert "R = [S,D]" in result.output and "T = [[S,D],D]" in result.output
    assert "growth vector: (2, 3, 4)" in result.output
    data = json.loads(run("model", "fields", "car", "--at", "0,0,0,0", "--json").output)
    np.testing.assert_allclose(data["fields"]["T"], [0, 1, 0, 0], atol=1e-15)
    assert data["aliases"] == {"R": "[S,D]", "T": "[[S,D],D]"}


def test_the_car_has_fields_but_no_gaits(tmp_path):
    for args in (
        ("gait", "serpenoid", "car", "-A", "0.3", "-w", "1", "-d", "1", "--cycles", "1"),
        ("gait", "field", "car", "--field", "S", "--duration", "0.1"),
    ):
        result = run(*args, "-o", tmp_path / "car.gait")
        assert result.exit_code == 2 and "snakebot model fields car" in result.output
        assert not (tmp_path / "car.gait").exists()


def test_joint_driven_singularity_of_the_trident_is_named():
    at = "0,0,0,45deg,60deg,-60deg"  # the three axles meet in one point
    text = run("model", "fields", "trident", "--at", at)
    assert "growth vector: (3, 6)" in text.output
    assert "warning: driven by its joints" in text.output and "singular" in text.output
    data = json.loads(run("model", "fields", "trident", "--at", at, "--json").output)
    assert data["joint_driven"]["near_singular"] and data["joint_driven"]["rcond"] < 1e-12
    clear = json.loads(run("model", "fields", "trident", "--at", "0,0,0,0,0,0", "--json").output)
    assert not clear["joint_driven"]["near_singular"]
    assert "warning" not in run("model", "fields", "trident", "--at", "0,0,0,0,0,0").output


def test_symbolic_car_is_the_thesis_s():
    data = json.loads(run("model", "fields", "car", "--symbolic", "--json").output)
    assert data["fields"]["R"] == ["0", "0", "1/(L*cos(Phi)**2)", "0"]
    assert data["fields"]["T"][:2] == ["-sin(theta)/(L*cos(Phi)**2)", "cos(theta)/(L*cos(Phi)**2)"]
