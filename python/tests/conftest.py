"""Shared fixtures: the `imu-emu` binary the values are checked against, and a scratch dir.

The binary is `$IMU_EMU_BIN`, else the one `cargo build --release` left in the repo's
target/release (`.ci/run` builds it before the Python tests)."""

import os
import pathlib
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


def _binary() -> pathlib.Path:
    env = os.environ.get("IMU_EMU_BIN")
    return pathlib.Path(env) if env else REPO / "target" / "release" / "imu-emu"


@pytest.fixture(scope="session")
def cli():
    """Runs `imu-emu ARGS` in a directory; returns the completed process (stdout bytes)."""
    exe = _binary()
    if not exe.is_file():
        pytest.fail(f"{exe}: no imu-emu binary (cargo build --release, or set IMU_EMU_BIN)")

    def run(*args, cwd=None, check=True):
        p = subprocess.run([str(exe), *map(str, args)], cwd=cwd, capture_output=True)
        if check and p.returncode != 0:
            raise AssertionError(f"imu-emu {' '.join(map(str, args))}: {p.stderr.decode()}")
        return p

    return run
