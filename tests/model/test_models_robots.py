"""Robot descriptions: the built-ins follow the contract, ticks round-trip, and a
malformed user file is refused with the key and the line named."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from snakebot.model.robots import TICKS_PER_RAD, RobotError, load_robot, parse_robot

GOOD = """\
name = "mine"
kind = "snake"
[geometry]
links = 3
half_link = 0.05
[[joints]]
servo_id = 4
zero_tick = 500
sign = -1
min_deg = -60
max_deg = 45
[[joints]]
servo_id = 5
zero_tick = 512
sign = 1
min_deg = -90
max_deg = 90
"""


def test_builtins_follow_the_contract():
    snake5 = load_robot("snake5")
    assert snake5.kind == "snake" and snake5.links == 5 and len(snake5.joints) == 4
    assert set(snake5.servo_ids) <= {10, 11, 15, 16, 17}
    assert snake5.servo_model == "AX-12A"
    assert snake5.max_speed_rad_s == pytest.approx(59 * 2 * math.pi / 60)
    assert snake5.l == pytest.approx(0.07)
    snake3 = load_robot("snake3")
    assert (snake3.kind, snake3.links, snake3.l) == ("snake", 3, 1.0)
    assert (snake3.friction.lateral, snake3.friction.rolling) == (0.8, 0.01)
    trident = load_robot("trident")
    assert (trident.kind, trident.r, trident.l) == ("trident", 1.0, 1.0)
    assert trident.alphas == pytest.approx((-2 * math.pi / 3, 0.0, 2 * math.pi / 3))
    for robot in (snake3, snake5, trident):
        for lo, hi in robot.tick_limits:
            assert 0 <= lo < 512 < hi <= 1023


def test_tick_conversion_follows_the_contract():
    robot = parse_robot(GOOD)
    phi = np.array([0.3, -0.2])
    expected = [round(500 - 0.3 * 1023 / math.radians(300)), round(512 - 0.2 * TICKS_PER_RAD)]
    assert robot.angles_to_ticks(phi).tolist() == expected
    low, high = (round(500 + math.radians(a) * TICKS_PER_RAD) for a in (-45, 60))
    assert robot.joints[0].tick_range == (low, high)  # sign -1: max_deg gives the low tick


@given(st.lists(st.integers(0, 1023), min_size=2, max_size=2))
def test_ticks_round_trip(ticks):
    robot = parse_robot(GOOD)
    back = robot.angles_to_ticks(robot.ticks_to_angles(np.array(ticks)))
    assert back.tolist() == ticks


def test_user_file_loads_from_a_path(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text(GOOD)
    robot = load_robot(path)
    assert robot.name == "mine" and robot.joints[0].sign == -1 and robot.source == str(path)


@pytest.mark.parametrize(
    ("old", "new", "key", "line"),
    [
        ("sign = -1", "sign = 2", "joints[0].sign", 9),
        ("servo_id = 5", "servo_id = 4", "joints[1].servo_id", 13),
        ("half_link = 0.05", "half_link = -1", "geometry.half_link", 5),
        ("links = 3", "links = 4", "joints", 6),
        ("max_deg = 45", "max_deg = 175", "joints[0].max_deg", 11),
        ('kind = "snake"', 'kind = "worm"', "kind", 2),
        ("zero_tick = 500", 'zero_tick = "mid"', "joints[0].zero_tick", 8),
    ],
)
def test_schema_errors_name_key_and_line(old, new, key, line):
    with pytest.raises(RobotError) as err:
        parse_robot(GOOD.replace(old, new), source="mine.toml")
    message = str(err.value)
    assert f"mine.toml, line {line}:" in message
    assert f"'{key}'" in message


def test_missing_key_is_named():
    with pytest.raises(RobotError, match=r"line 12: key 'joints\[1\].zero_tick' is missing"):
        parse_robot(GOOD.replace("zero_tick = 512\n", ""), source="x")


def test_syntax_error_names_the_line():
    with pytest.raises(RobotError, match=r"line 5"):
        parse_robot(GOOD.replace("half_link = 0.05", "half_link = = 0.05"), source="x")


def test_unknown_robot_says_what_to_give():
    with pytest.raises(RobotError, match="snake3, trident, snake5"):
        load_robot("no-such-robot")
