"""`snakebot robot new`: a commented robot file that the loader and `model info` accept,
for every built-in robot and snake length, written only where asked (issue #29)."""

from __future__ import annotations

import json
import re

import pytest
from click.testing import CliRunner

from snakebot.cli import main
from snakebot.model.robots import BUILTIN_ROBOTS, load_robot
from snakebot.model.robots.schema import TABLES

KEY_LINE = re.compile(r"^(?:# )?([a-z_]+) = ")
HEADER = re.compile(r"^(?:# )?\[\[?([a-z]+)\]\]?$")


def run(*args):
    return CliRunner().invoke(main, list(args))


def info(path):
    result = run("model", "info", str(path), "--json")
    assert result.exit_code == 0, result.output
    return json.loads(result.output)


@pytest.mark.parametrize("like", BUILTIN_ROBOTS)
def test_each_built_in_robot_round_trips_through_the_loader_and_model_info(tmp_path, like):
    path = tmp_path / "my.toml"
    result = run("robot", "new", str(path), "--like", like)
    assert result.exit_code == 0, result.output
    built_in, written = load_robot(like), load_robot(path)
    assert written.name == "my"
    for field in ("kind", "joints", "l", "r", "alphas", "links", "friction", "physics"):
        assert getattr(written, field) == getattr(built_in, field), field
    assert info(path)["joints"] == info(like)["joints"]


@pytest.mark.parametrize("like", BUILTIN_ROBOTS)
def test_every_key_is_under_the_comment_that_explains_it(tmp_path, like):
    path = tmp_path / f"{like}.toml"
    assert run("robot", "new", str(path), "--like", like).exit_code == 0
    lines = path.read_text().splitlines()
    table, seen = "", set()
    for n, line in enumerate(lines):
        if header := HEADER.match(line):
            table = header.group(1)
        m = KEY_LINE.match(line)
        if m is None:
            continue
        seen.add((table, m.group(1)))
        above = []  # the comment block right above, without its "# " or "#   "
        for previous in reversed(lines[:n]):
            if not previous.startswith("#") or KEY_LINE.match(previous):
                break
            above.insert(0, previous.lstrip("# "))
        meaning = TABLES[table].keys[m.group(1)].meaning
        assert " ".join(above).endswith(meaning), f"{like}: {m.group(1)} is not explained"
    # the other kinds' geometry apart, every key a robot file may have is shown
    every = {(name, key) for name, t in TABLES.items() for key in t.keys}
    geometry = {k for k in every if k[0] == "geometry"}
    assert every - geometry <= seen
    assert {key for _, key in seen & geometry} == set(info(path)["geometry"])


@pytest.mark.parametrize("like", ["snake5", "snake3"])
@pytest.mark.parametrize("links", range(3, 9))
def test_a_snake_of_any_length_is_accepted(tmp_path, like, links):
    path = tmp_path / "s.toml"
    result = run("robot", "new", str(path), "--like", like, "--links", str(links))
    assert result.exit_code == 0, result.output
    described = info(path)
    assert described["geometry"]["links"] == links
    ids = [j["servo_id"] for j in described["joints"]]
    assert len(ids) == links - 1 == len(set(ids))
    kept = [j.servo_id for j in load_robot(like).joints][: links - 1]
    assert ids[: len(kept)] == kept  # the built-in's IDs first, then new ones


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (("--links", "1"), "--links: a snake has 2 to 16 links, not 1"),
        (("--links", "17"), "not 17"),
        (("--links", "x"), "'x' is not a valid integer"),
        (("--like", "trident", "--links", "4"), "--links: a trident has a fixed number"),
        (("--like", "eel"), "'eel' is not one of"),
    ],
)
def test_bad_input_exits_2_and_writes_nothing(tmp_path, args, words):
    path = tmp_path / "bad.toml"
    result = run("robot", "new", str(path), *args)
    assert result.exit_code == 2
    assert words in result.stderr
    assert list(tmp_path.iterdir()) == []


def test_an_existing_file_is_kept_unless_forced(tmp_path):
    path = tmp_path / "my.toml"
    path.write_text("# my own notes\n")
    result = run("robot", "new", str(path))
    assert result.exit_code == 2
    assert "--force" in result.stderr and "exists already" in result.stderr
    assert path.read_text() == "# my own notes\n"
    result = run("robot", "new", str(path), "--force", "--json")
    assert result.exit_code == 0, result.output
    assert json.loads(result.output) == {"robot": str(path), "like": "snake5", "joints": 4}
    assert load_robot(path).kind == "snake"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["my.toml"]  # no temporary left
