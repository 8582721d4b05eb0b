"""`snakebot robot export`: the files it writes, and its refusals (issue #33)."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from snakebot.cli import main

mujoco = pytest.importorskip("mujoco")


def run(*args):
    return CliRunner().invoke(main, ["robot", "export", *args])


def test_export_writes_both_files_that_mujoco_loads(tmp_path):
    urdf, mjcf = tmp_path / "s.urdf", tmp_path / "s.xml"
    result = run("snake5", "--urdf", str(urdf), "--mjcf", str(mjcf), "--json")
    assert result.exit_code == 0, result.output
    assert json.loads(result.output) == {"robot": "snake5", "urdf": str(urdf), "mjcf": str(mjcf)}
    for path in (urdf, mjcf):
        assert mujoco.MjModel.from_xml_path(str(path)).nu >= 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.urdf", "s.xml"]  # no temp left


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (("snake5",), "--urdf FILE"),
        (("snake5", "--urdf", "x.txt"), ".urdf"),
        (("snake5", "--urdf", "missing/x.urdf"), "not a directory"),
        (("car", "--urdf", "car.urdf"), "[physics]"),
    ],
)
def test_export_refuses_bad_input_in_one_line(args, words, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = run(*args)
    assert result.exit_code == 2
    assert words in result.output and "Traceback" not in result.output
    assert list(tmp_path.iterdir()) == []
