"""Every output option refuses, while parsing and before any work, what it must not write
(issue #28): a device, a FIFO, a directory, a symbolic link (another user's planted one
included), two options naming one file, a plot name whose format is not the file's."""

from __future__ import annotations

import os
import stat
import time
from pathlib import Path

import pytest
from click.testing import CliRunner
from other_user import as_other_user, needs_root

from snakebot.cli import main
from snakebot.cli.troubleshooting import ERROR_LINE

SERPENOID = ["gait", "serpenoid", "snake3", "-A", "20deg", "-w", "90deg", "-d", "90deg"]
SERPENOID += ["--cycles", "1"]
PRECIOUS = b"the victim's data\n"
BIG_SEARCH = ["gait", "search", "snake3", "--param", "A=10deg:50deg:1000", "--param"]
BIG_SEARCH += ["delta=30deg:150deg:1000"]


def _run(args: list[str]):
    start = time.monotonic()
    result = CliRunner().invoke(main, args)
    return result, time.monotonic() - start


def _refused(result, *words: str) -> None:
    assert result.exit_code == 2, result.output
    line = result.stderr.strip()
    assert "\n" not in line and ERROR_LINE.match(line), line
    for word in words:
        assert word in line, line


@pytest.fixture
def victim(tmp_path: Path) -> Path:
    path = tmp_path / "victim.txt"
    path.write_bytes(PRECIOUS)
    return path


def _outputs(tmp_path: Path, name: str) -> list[list[str]]:
    """Command lines with ``name`` as one output each: every command's output options
    that need no controller."""
    out = str(tmp_path / name)
    return [
        [*SERPENOID, "-o", out],
        [*SERPENOID, "-o", str(tmp_path / "ok.gait"), "--plot", out],
        [*BIG_SEARCH, "--best", out],
        [*BIG_SEARCH, "-o", out],
        [*BIG_SEARCH, "--plot", out],
        ["plan", "snake3", "--to", "1,0,0", "-o", str(tmp_path / "p.gait"), "--plot", out],
        ["monitor", "--port", "loop://", "--csv", out],
        ["monitor", "--port", "loop://", "--mcap", out],
        ["program", "build", "spec.toml", "-o", out],
        ["sim", "goto", "snake3", "--to", "1,0,0", "--plot", out],
    ]


def test_a_symlink_at_any_output_is_refused_before_the_work(tmp_path, victim):
    for args in _outputs(tmp_path, "out.png"):
        (tmp_path / "out.png").unlink(missing_ok=True)
        (tmp_path / "out.png").symlink_to(victim)
        result, took = _run(args)
        _refused(result, "symbolic link", "name the file itself")
        assert took < 10, (args, took)  # the million-point search never started
        assert victim.read_bytes() == PRECIOUS


@pytest.mark.parametrize("kind", ["fifo", "device", "directory"])
def test_a_fifo_device_or_directory_at_any_output_is_refused(tmp_path, kind):
    for args in _outputs(tmp_path, "out.png"):
        if kind == "fifo":
            target = tmp_path / "out.png"
            if not target.exists():
                os.mkfifo(target)
        elif kind == "directory":
            (tmp_path / "out.png").mkdir(exist_ok=True)
        else:
            args = [("/dev/null" if a == str(tmp_path / "out.png") else a) for a in args]
        result, took = _run(args)
        _refused(result)
        assert "device, a pipe" in result.stderr or "directory" in result.stderr
        assert took < 10
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)


def test_search_best_on_a_device_is_refused_at_once():
    # As root this replaced /dev/null by a regular file after the whole search.
    result, took = _run([*BIG_SEARCH, "--best", "/dev/null"])
    _refused(result, "'/dev/null' is a device")
    assert took < 10
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)


def test_two_outputs_naming_one_file_are_refused(tmp_path):
    same = str(tmp_path / "x.csv")
    result, _ = _run(["monitor", "--port", "loop://", "--csv", same, "--mcap", same])
    _refused(result, "also given to '--csv'", "give each its own file")
    other = str(tmp_path / "." / "x.csv")
    result, _ = _run([*BIG_SEARCH, "-o", same, "--best", other])
    _refused(result, "also given to")
    result, _ = _run(
        [*BIG_SEARCH, "-o", str(tmp_path / "r.csv"), "--plot", str(tmp_path / "r.best.gait")]
    )
    _refused(result)
    assert not list(tmp_path.iterdir())


def test_a_plot_name_without_its_format_is_refused_not_renamed(tmp_path):
    result, _ = _run(
        ["plan", "snake3", "--to", "1,0,0", "-o", str(tmp_path / "p.gait"), "--plot", "noext"]
    )
    _refused(result, "'noext' has the extension '(none)'", ".png")
    result, _ = _run([*BIG_SEARCH, "--plot", str(tmp_path / "heat.xyz")])
    _refused(result, "use one of", ".png", ".svg")
    assert not list(tmp_path.iterdir())


def test_a_plot_is_written_under_the_name_given(tmp_path):
    gait, plot = tmp_path / "p.gait", tmp_path / "p.svg"
    result, _ = _run(
        ["plan", "snake3", "--to", "1,0,0", "-o", str(gait), "--plot", str(plot), "--json"]
    )
    assert result.exit_code == 0, result.output
    assert plot.read_bytes().lstrip().startswith(b"<?xml")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.gait", "p.gait.json", "p.svg"]


@needs_root
def test_a_symlink_planted_by_another_user_is_never_written_through(shared_tmp):
    victim = shared_tmp / "victim.txt"
    victim.write_bytes(PRECIOUS)
    victim.chmod(0o600)
    names = ("walk.gait", "walk.gait.json", "rec.csv", "rec.mcap", "plot.png", "plan.gait")
    names += ("best.gait",)
    as_other_user("; ".join(f"ln -s {victim} {shared_tmp / n}" for n in names))
    cases = [
        [*SERPENOID, "-o", str(shared_tmp / "walk.gait")],
        [*SERPENOID, "-o", str(shared_tmp / "mine.gait"), "--plot", str(shared_tmp / "plot.png")],
        ["monitor", "--port", "loop://", "--csv", str(shared_tmp / "rec.csv")],
        ["monitor", "--port", "loop://", "--mcap", str(shared_tmp / "rec.mcap")],
        ["plan", "snake3", "--to", "1,0,0", "-o", str(shared_tmp / "plan.gait")],
        [*BIG_SEARCH, "--best", str(shared_tmp / "best.gait")],
    ]
    for args in cases:
        result, _ = _run(args)
        _refused(result, "symbolic link")
    assert victim.read_bytes() == PRECIOUS
    assert all(os.readlink(shared_tmp / n) == str(victim) for n in names)  # left as planted
    # The sidecar of a gait: refused too, and neither file of the pair is written.
    (shared_tmp / "walk.gait").unlink()
    result, _ = _run([*SERPENOID, "-o", str(shared_tmp / "walk.gait")])
    _refused(result, "walk.gait.json", "symbolic link")
    assert not (shared_tmp / "walk.gait").exists()
    assert victim.read_bytes() == PRECIOUS
