"""`simulate` against `imu-emu generate`: the same arguments and seed give the same bytes."""

import pathlib
import tomllib

import numpy as np
import pytest

import imu_emu

from conftest import REPO

ARGS = dict(imu="stim300", seed=7, rate=200.0, duration=2.0)


def cli_flags(a):
    return ["--imu", a["imu"], "--seed", a["seed"], "--rate", a["rate"], "--duration", a["duration"]]


def test_scene_records_truth_errors_byte_for_byte(cli, tmp_path):
    cli("generate", "--scene", "circle", *cli_flags(ARGS), "--format", "bin", "-o", "imu.bin",
        "--truth", "truth.bin", "--truth-errors", "errors.bin", cwd=tmp_path)
    r = imu_emu.simulate("circle", format="bin", **ARGS)
    main = (tmp_path / "imu.bin").read_bytes()
    assert len(r.records) == 400
    # The binary record is 13 little-endian f64: the array's own bytes.
    assert r.records.rows.astype("<f8").tobytes() == main
    assert r.output == main
    assert r.truth.rows.astype("<f8").tobytes() == (tmp_path / "truth.bin").read_bytes()
    assert r.error_rows.astype("<f8").tobytes() == (tmp_path / "errors.bin").read_bytes()
    # The errors explain the records: truth + every stage's injection = record (to round-off).
    injected = sum(e["gyro"] for e in r.errors.values())
    np.testing.assert_allclose(r.truth.gyro + injected, r.records.gyro, rtol=0, atol=1e-15)
    # The named views are views, not copies.
    assert np.shares_memory(r.records.gyro, r.records.rows)


def test_csv_output_is_generate_csv(cli, tmp_path):
    out = cli("generate", "--scene", "survey", *cli_flags(ARGS)).stdout
    r = imu_emu.simulate("survey", **ARGS)
    assert r.output == out
    rows = np.array([[float(x) for x in line.split(",")] for line in out.decode().splitlines()[1:]])
    assert np.array_equal(rows, r.records.rows)


def test_frames_are_generate_frames(cli, tmp_path):
    cli("generate", "--scene", "coning", "--imu", "ln200", "--format", "kvh1750", "--seed", 3,
        "--duration", 1, "-o", "f.kvh", cwd=tmp_path)
    r = imu_emu.simulate("coning", imu="ln200", format="kvh1750", seed=3, duration=1.0)
    assert r.output == (tmp_path / "f.kvh").read_bytes()
    assert r.rate == 1000.0


def trajectory_arrays(path):
    text = [line for line in path.read_text().splitlines() if not line.startswith("#")]
    header = text[0].split(",")
    assert header == ["t", "lat", "lon", "h", "vn", "ve", "vd", "roll", "pitch", "yaw"]
    a = np.array([[float(x) for x in line.split(",")] for line in text[1:]])
    return dict(t=a[:, 0], lat=a[:, 1], lon=a[:, 2], h=a[:, 3], v_ned=a[:, 4:7], rpy=a[:, 7:10])


def test_trajectory_arrays_are_the_trajectory_file(cli, tmp_path):
    cli("trajectory", "--scene", "survey", "--rate", 100, "--duration", 20, "-o", "flight.csv",
        cwd=tmp_path)
    cli("generate", "--trajectory", "flight.csv", *cli_flags(ARGS), "--format", "bin",
        "-o", "imu.bin", cwd=tmp_path)
    main = (tmp_path / "imu.bin").read_bytes()
    arrays = trajectory_arrays(tmp_path / "flight.csv")
    from_arrays = imu_emu.simulate(trajectory=arrays, **ARGS)
    from_file = imu_emu.simulate(trajectory=tmp_path / "flight.csv", **ARGS)
    assert from_arrays.records.rows.tobytes() == main
    assert from_file.records.rows.tobytes() == main


def test_template_dict_is_the_template_file():
    text = (REPO / "templates" / "stim300.toml").read_text()
    as_dict = tomllib.loads(text)
    a = imu_emu.simulate("circle", imu=as_dict, seed=7, rate=200.0, duration=2.0)
    b = imu_emu.simulate("circle", imu="stim300", seed=7, rate=200.0, duration=2.0)
    assert np.array_equal(a.records.rows, b.records.rows)
    # And a changed figure changes the records (the dict is used, not the name).
    as_dict["gyro"]["bias_instability"] = "0.3 deg/h" if "bias_instability" in as_dict["gyro"] else 0
    c = imu_emu.simulate("circle", imu=as_dict, seed=7, rate=200.0, duration=2.0)
    assert not np.array_equal(a.records.rows, c.records.rows)


def test_scene_file(cli, tmp_path):
    scene = REPO / "examples" / "survey.toml"
    cli("generate", scene, "--duration", 1, "--format", "bin", "-o", "s.bin",
        cwd=tmp_path)
    r = imu_emu.simulate(scene_file=scene, duration=1.0, format="bin")
    assert r.output == (tmp_path / "s.bin").read_bytes()


def test_errors_carry_the_library_message(cli):
    bad = cli("generate", "--scene", "circle", "--imu", "no-such-imu", check=False)
    assert bad.returncode != 0
    with pytest.raises(imu_emu.ImuEmuError) as e:
        imu_emu.simulate("circle", imu="no-such-imu")
    assert str(e.value) in bad.stderr.decode()
    with pytest.raises(imu_emu.ImuEmuError, match="scene"):
        imu_emu.simulate("no-such-scene")


def test_trajectory_array_errors_name_row_and_array():
    t = np.array([0.0, 1.0, 1.0, 2.0])
    z = np.zeros(4)
    arrays = dict(t=t, lat=z + 41, lon=z, h=z, v_ned=np.zeros((4, 3)), rpy=np.zeros((4, 3)))
    with pytest.raises(imu_emu.ImuEmuError, match=r"row 2, `t`: 1 does not increase"):
        imu_emu.simulate(trajectory=arrays)
    arrays["t"] = np.arange(4.0)
    arrays["lat"] = np.array([41.0, 41.0, np.nan, 41.0])
    with pytest.raises(imu_emu.ImuEmuError, match=r"row 2, `lat`"):
        imu_emu.simulate(trajectory=arrays)
    with pytest.raises(imu_emu.ImuEmuError, match=r"`rpy` has shape \(4,\)"):
        imu_emu.simulate(trajectory=dict(arrays, rpy=z))


def test_pose_is_cli_trajectory(cli, tmp_path):
    cli("trajectory", "--scene", "circle", "--rate", 200, "--duration", 2, "-o", "c.csv",
        cwd=tmp_path)
    want = trajectory_arrays(tmp_path / "c.csv")
    got = imu_emu.simulate("circle", rate=200.0, duration=2.0, pose=True).pose
    for k in want:
        np.testing.assert_array_equal(got[k], want[k])


def test_a_call_beyond_what_memory_holds_raises():
    """Issue 38: rate=1e5, duration=1e4 (10^9 records) aborted the interpreter (exit 134);
    now it raises before allocating, naming the limit, and the interpreter goes on."""
    with pytest.raises(imu_emu.ImuEmuError, match=r"1000000000 records, more than the 33554432 \(2\^25\)"):
        imu_emu.simulate("static", rate=1e5, duration=1e4)
    assert len(imu_emu.simulate("static", rate=100.0, duration=1.0).records) == 100
