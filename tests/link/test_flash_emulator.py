"""The emulated ROBOTIS bootloader's state machine (what `snakebot flash` is tested
against must itself behave as documented)."""

from __future__ import annotations

import os
import time

import pytest
import serial

from snakebot.sim.bootloader import APP_BASE, Bootloader, BootloaderFaults, BootloaderPty


def booted(**kwargs) -> Bootloader:
    boot = Bootloader(**kwargs)
    boot.reset(0.0)
    return boot


def test_ignores_everything_until_hash_then_prompts():
    boot = booted()
    assert boot.feed(b"L\nGO\nhello", 0.0) == b""
    out = boot.feed(b"#", 0.1)
    assert b"ROBOTIS CM-530 boot loader" in out and out.endswith(b"[CM-530]> ")
    assert boot.feed(b"###", 0.2) == b""  # the host's leftover '#'
    assert boot.commands == []


def test_load_receives_until_silence_and_reports_the_sum():
    boot = booted(silence_s=0.5)
    boot.feed(b"#", 0.0)
    assert b"Ready.." in boot.feed(b"\nL\n", 0.0)
    image = bytes(range(256)) * 3 + b"\x10"
    boot.feed(image[:300], 1.0)
    assert boot.poll(1.4) == b""  # a pause shorter than the silence is not the end
    boot.feed(image[300:], 1.4)
    assert boot.poll(1.8) == b""
    out = boot.poll(1.9)
    assert f"Size: {len(image)}".encode() in out
    assert f"Checksum: {sum(image) & 0xFF:02X}".encode() in out
    assert boot.image == image


def test_bytes_waiting_unread_are_not_a_silence():
    """An emulator held up (a busy host) reads bytes that waited in the terminal after
    more than the silence: the line carried them without a pause, so they go on with
    the image. Only a silence it sees with nothing waiting ends the image."""
    boot = booted(silence_s=0.5)
    boot.feed(b"#\nL\n", 0.0)
    image = bytes(range(256)) * 2
    boot.feed(image[:100], 1.0)
    assert boot.poll(1.8, line_busy=True) == b""  # bytes wait: not silent
    boot.feed(image[100:], 1.9)  # read late, after the silence's length
    assert boot.poll(2.3) == b""
    assert f"Size: {len(image)}".encode() in boot.poll(2.5)
    assert boot.image == image


def test_a_silence_the_emulator_did_not_watch_does_not_end_the_image():
    """The served bootloader's thread woke 0.4 s late (the whole process held up by a
    busy host, the flasher in it too): that time is not silence on the line, so the image
    ends only after a whole silence watched afterwards (it ended early, and the flash
    reported a checksum mismatch)."""
    boot = booted(silence_s=0.5)
    boot.feed(b"#\nL\n", 0.0)
    image = bytes(range(256)) * 2
    boot.feed(image[:100], 1.0)
    boot.held(0.4)
    assert boot.poll(1.6) == b""  # 0.6 s after the last byte, 0.2 s of it watched
    boot.feed(image[100:], 1.7)
    assert f"Size: {len(image)}".encode() in boot.poll(2.3)
    assert boot.image == image


def test_an_emulator_held_up_mid_image_still_receives_all_of_it(tmp_path):
    """The served bootloader, kept from running for longer than its silence while the
    flasher's bytes wait in the terminal (what a busy host does to it), stores the
    whole image (it ended it early and reported a checksum mismatch)."""
    boot = Bootloader(silence_s=0.1)
    server = BootloaderPty(boot, pace=False)
    image = bytes(range(256)) * 4
    with server, serial.Serial(server.device, 57600, timeout=0.5) as port:
        server.press_reset()
        heard, deadline = b"", time.monotonic() + 5
        while b"[CM-530]> " not in heard and time.monotonic() < deadline:
            port.write(b"#")
            heard += port.read(200)
        port.write(b"\nL\n")
        assert b"Ready" in port.read_until(b"Ready", 200)
        port.write(image[:300])
        time.sleep(0.05)
        with server._lock:  # the emulator's thread held up, as if descheduled
            port.write(image[300:])
            time.sleep(0.4)
        deadline = time.monotonic() + 5
        while boot.state == "receive" and time.monotonic() < deadline:
            time.sleep(0.05)
    assert boot.image == image


def test_sum_excluding_the_last_byte():
    boot = booted(silence_s=0.1, sum_excludes_last=True)
    boot.feed(b"#\nL\n", 0.0)
    boot.feed(b"\x01\x02\x03\xff", 0.0)
    assert b"Checksum: 06" in boot.poll(0.2)


def test_image_bigger_than_the_application_area_is_refused():
    boot = booted(silence_s=0.1, capacity=100)
    boot.feed(b"#\nL\n", 0.0)
    boot.feed(bytes(102), 0.0)
    out = boot.poll(0.2)
    assert b"Error: 102 bytes is more than the 100 byte application area" in out
    assert boot.images == []


def test_corrupt_fault_flips_one_stored_bit():
    boot = booted(silence_s=0.1, faults=BootloaderFaults(corrupt=True))
    boot.feed(b"#\nL\n", 0.0)
    boot.feed(bytes(10), 0.0)
    boot.poll(0.2)
    assert boot.image == bytes(5) + b"\x01" + bytes(4)


def test_faults_mute_and_no_ready():
    mute = booted(faults=BootloaderFaults(mute=True))
    assert mute.feed(b"#" * 50, 0.0) == b""
    silent = booted(faults=BootloaderFaults(no_ready=True))
    silent.feed(b"#", 0.0)
    assert b"Ready" not in silent.feed(b"\nL\n", 0.0)
    assert silent.state == "prompt"


def test_commands_go_g_app_sys_help_and_unknown():
    boot = booted()
    boot.feed(b"#", 0.0)
    assert b"L        load" in boot.feed(b"help\r", 0.0)
    assert b"Unknown command: FROB" in boot.feed(b"FROB\r", 0.0)
    assert b"G needs a hex address" in boot.feed(b"G zz\r", 0.0)
    assert b"boot loader after reset" in boot.feed(b"sys\r", 0.0)
    assert b"Go 0x08004000" in boot.feed(b"G 8004000\r", 0.0)
    assert boot.state == "app" and boot.started == [0x08004000]
    # SYS: a reset lands at the prompt without '#'.
    assert b"[CM-530]> " in boot.reset(1.0)
    assert b"application after reset" in boot.feed(b"APP\r", 1.0)
    assert b"Go 0x08003000" in boot.feed(b"GO\r", 1.0)
    assert boot.started == [0x08004000, APP_BASE]
    assert boot.reset(2.0) == b"" and boot.state == "wait_hash"


def test_typed_characters_are_echoed_and_backspace_works():
    boot = booted()
    boot.feed(b"#", 0.0)
    assert boot.feed(b"GX", 0.0) == b"GX"
    assert boot.feed(b"\x08", 0.0) == b"\x08 \x08"
    assert b"Go 0x" in boot.feed(b"O\r", 0.0)


def test_hash_window_closes_into_the_application():
    boot = Bootloader(hash_window_s=0.5)
    boot.reset(10.0)
    assert boot.next_deadline() == 10.5
    boot.poll(10.6)
    assert boot.state == "app"
    assert boot.feed(b"#", 10.7) == b""


def test_pty_server_press_reset_and_link(tmp_path):
    link = tmp_path / "ttyCM530"
    server = BootloaderPty(Bootloader(), reset_after_s=60, pace=False, link=link)
    with server:
        assert os.path.realpath(link) == server.device
        with serial.Serial(str(link), 57600, timeout=0.2) as port:
            port.write(b"#")
            assert port.read(100) == b""  # still "running the application"
            server.press_reset()
            deadline = time.monotonic() + 5
            heard = b""
            while b"[CM-530]> " not in heard and time.monotonic() < deadline:
                port.write(b"#")
                heard += port.read(200)
            assert b"boot loader" in heard
    assert not link.exists()
    assert not server.running


def test_link_over_a_regular_file_is_refused(tmp_path):
    from snakebot.sim.errors import SimError

    path = tmp_path / "file"
    path.write_text("keep me")
    with pytest.raises(SimError, match="exists and is not a link"):
        BootloaderPty(Bootloader(), link=path).start()
    assert path.read_text() == "keep me"
