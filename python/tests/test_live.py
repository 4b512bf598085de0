"""The live emulator from Python: a paced run to a UDP socket on loopback, stopped on exit,
sends the offline run's bytes."""

import socket
import time

import pytest

import imu_emu


def test_emulator_udp_sends_the_offline_bytes():
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(0.2)
    port = rx.getsockname()[1]
    args = dict(imu="stim300", format="stim300", seed=11, rate=125.0)
    got = bytearray()
    with imu_emu.Emulator("circle", sinks=[f"udp:127.0.0.1:{port}"], speed=4.0, **args) as emu:
        assert "udp:127.0.0.1" in emu.description
        deadline = time.monotonic() + 10
        while len(got) < 200 * 64 and time.monotonic() < deadline:
            try:
                got += rx.recv(65536)
            except socket.timeout:
                pass
        assert emu.status()["started"]
    assert emu.report["stopped"]
    frames = emu.report["frames"]
    assert frames >= 200
    offline = imu_emu.simulate("circle", duration=frames / 125.0, **args).output
    assert len(got) > 0 and offline.startswith(bytes(got))


def test_emulator_runs_to_its_end_and_refuses_bad_sinks(tmp_path):
    with pytest.raises(imu_emu.ImuEmuError, match="sink"):
        imu_emu.Emulator("static", sinks=["carrier-pigeon:nowhere"])
    out = tmp_path / "f.kvh"
    emu = imu_emu.Emulator("static", imu="ln200", format="kvh1750", sinks=[f"file:{out}"],
                           duration=0.2, speed=10.0, seed=4)
    emu.start()
    r = emu.wait(timeout=10)
    assert r is not None and not r["stopped"] and r["frames"] == 200
    offline = imu_emu.simulate("static", imu="ln200", format="kvh1750", duration=0.2, seed=4)
    assert out.read_bytes() == offline.output


def test_emulator_pty_sends_the_offline_bytes(tmp_path):
    import os
    import tty

    link = tmp_path / "imu"
    args = dict(imu="ln200", format="kvh1750", seed=2, rate=1000.0)
    got = bytearray()
    with imu_emu.Emulator("circle", sinks=[f"pty:{link}"], speed=2.0, **args) as emu:
        deadline = time.monotonic() + 10
        while not link.exists() and time.monotonic() < deadline:
            time.sleep(0.01)
        fd = os.open(link, os.O_RDONLY | os.O_NOCTTY | os.O_NONBLOCK)
        tty.setraw(fd)  # bytes as sent: no line discipline
        try:
            while len(got) < 4000 and time.monotonic() < deadline:
                try:
                    got += os.read(fd, 65536)
                except BlockingIOError:
                    time.sleep(0.005)
        finally:
            os.close(fd)
    assert emu.report["stopped"]
    offline = imu_emu.simulate("circle", duration=emu.report["frames"] / 1000.0, **args).output
    # The reader joined after the first frames: what it got is a run of the offline bytes.
    assert len(got) >= 4000 and bytes(got) in offline
