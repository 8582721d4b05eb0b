"""The one way to write an output file (``snakebot.userfiles``): atomic, never through a
symbolic link, never onto a device, FIFO or directory, keeping the file's mode."""

from __future__ import annotations

import os
import stat
import threading

import pytest

from snakebot.userfiles import (
    OutputExists,
    OutputRefused,
    atomic_output,
    check_output,
    new_file_mode,
    open_recording,
    same_file,
    write_atomic,
)

OLD = b"old content\n"


def _mode(path) -> int:
    return stat.S_IMODE(os.lstat(path).st_mode)


@pytest.mark.parametrize("mode", [0o644, 0o640, 0o600, 0o664])
def test_an_existing_files_mode_is_kept(tmp_path, mode):
    path = tmp_path / "robot.toml"
    path.write_bytes(OLD)
    path.chmod(mode)
    write_atomic(path, "new\n")
    assert path.read_text() == "new\n"
    assert _mode(path) == mode


def test_a_new_file_gets_the_umask_mode_not_0600(tmp_path):
    old = os.umask(0o027)
    try:
        write_atomic(tmp_path / "new.gait", b"x")
        assert _mode(tmp_path / "new.gait") == 0o640 == new_file_mode()
    finally:
        os.umask(old)


def test_a_failure_half_way_leaves_the_old_file_and_no_temporary(tmp_path):
    path = tmp_path / "out.csv"
    path.write_bytes(OLD)
    with pytest.raises(RuntimeError), atomic_output(path) as f:
        f.write(b"half")
        raise RuntimeError("killed")
    assert path.read_bytes() == OLD
    assert os.listdir(tmp_path) == ["out.csv"]


def test_a_symlink_at_the_final_path_is_refused_and_its_target_untouched(tmp_path):
    victim = tmp_path / "victim"
    victim.write_bytes(OLD)
    link = tmp_path / "out.gait"
    link.symlink_to(victim)
    for write in (lambda: write_atomic(link, b"x"), lambda: open_recording(link)):
        with pytest.raises(OutputRefused, match=r"is a symbolic link .*name the file itself"):
            write()
    assert victim.read_bytes() == OLD and link.is_symlink()


def test_a_dangling_symlink_is_refused_too(tmp_path):
    link = tmp_path / "out.gait"
    link.symlink_to(tmp_path / "nowhere")
    with pytest.raises(OutputRefused, match="symbolic link"):
        write_atomic(link, b"x")
    assert not (tmp_path / "nowhere").exists()


@pytest.mark.parametrize(
    ("make", "words"),
    [
        (lambda p: os.mkfifo(p), "a device, a pipe or a socket"),
        (lambda p: p.mkdir(), "is a directory"),
    ],
)
def test_a_fifo_or_directory_is_refused(tmp_path, make, words):
    path = tmp_path / "out"
    make(path)
    with pytest.raises(OutputRefused, match=words):
        check_output(path)
    with pytest.raises(OutputRefused, match=words):
        write_atomic(path, b"x")


def test_a_device_is_refused_and_stays_a_device():
    with pytest.raises(OutputRefused, match="device"):
        write_atomic("/dev/null", b"x")
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)


def test_a_missing_directory_is_refused_with_the_fix(tmp_path):
    with pytest.raises(OutputRefused, match=r"not a directory: make it first \(mkdir -p"):
        check_output(tmp_path / "no" / "out.gait")


def test_a_recording_onto_a_fifo_with_no_reader_does_not_block(tmp_path):
    fifo = tmp_path / "rec.csv"
    os.mkfifo(fifo)
    done = threading.Event()

    def attempt() -> None:
        with pytest.raises(OutputRefused):
            open_recording(fifo)
        done.set()

    worker = threading.Thread(target=attempt, daemon=True)
    worker.start()
    worker.join(10)
    assert done.is_set(), "open_recording blocked on a FIFO"


def test_a_recording_empties_a_regular_file_and_keeps_its_mode(tmp_path):
    path = tmp_path / "rec.csv"
    path.write_bytes(OLD)
    path.chmod(0o640)
    with open_recording(path, text=True) as f:
        f.write("t\n")
    assert path.read_text() == "t\n" and _mode(path) == 0o640


def test_two_names_of_one_file_are_the_same_output(tmp_path):
    (tmp_path / "a").write_bytes(b"")
    os.link(tmp_path / "a", tmp_path / "b")
    assert same_file(tmp_path / "a", tmp_path / "sub" / ".." / "a")
    assert same_file(tmp_path / "a", tmp_path / "b")
    assert not same_file(tmp_path / "a", tmp_path / "c")


def test_a_new_file_only_output_keeps_an_existing_file(tmp_path):
    path = tmp_path / "robot.toml"
    path.write_bytes(OLD)
    with pytest.raises(OutputExists, match="exists already"):
        write_atomic(path, "new", replace=False)
    assert path.read_bytes() == OLD
    # the file appears between the first check and the end: still kept, in one step
    late = tmp_path / "late.toml"
    with pytest.raises(OutputExists), atomic_output(late, replace=False) as f:
        late.write_bytes(OLD)
        f.write(b"new")
    assert late.read_bytes() == OLD
    assert write_atomic(tmp_path / "fresh.toml", "new", replace=False).read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fresh.toml", "late.toml", "robot.toml"]
