"""`analyze` and `fit` against `imu-emu analyze --csv` and `imu-emu fit`."""

import numpy as np
import pytest

import imu_emu


def curves(path):
    """`analyze --csv`: {(kind, channel): (x, y, lo, hi) arrays}."""
    out = {}
    for line in path.read_text().splitlines()[1:]:
        kind, ch, *vals = line.split(",")
        out.setdefault((kind, ch), []).append([float(v) if v else np.nan for v in vals])
    return {k: np.array(v) for k, v in out.items()}


def test_analyze_is_cli_analyze(cli, tmp_path):
    cli("generate", "--scene", "static", "--imu", "stim300", "--rate", 200, "--duration", 120,
        "--seed", 3, "--format", "bin", "-o", "s.bin", cwd=tmp_path)
    cli("analyze", "s.bin", "--imu", "stim300", "--csv", "c.csv", cwd=tmp_path, check=False)
    want = curves(tmp_path / "c.csv")
    got = imu_emu.analyze(tmp_path / "s.bin", imu="stim300")
    assert got["samples"] == 24000 and got["dt"] == 1 / 200
    for ch in got["channels"]:
        name = ch["name"].replace(" ", "_")
        adev = want[("adev", name)]
        a = ch["adev"]
        np.testing.assert_array_equal(np.c_[a["tau"], a["adev"], a["lo"], a["hi"]], adev)
        psd = want[("psd", name)]
        np.testing.assert_array_equal(np.c_[ch["psd"]["freq"], ch["psd"]["density"]], psd[:, :2])
    # Records in memory give the same analysis as the file.
    sim = imu_emu.simulate("static", imu="stim300", rate=200.0, duration=120.0, seed=3)
    mem = imu_emu.analyze(sim)
    np.testing.assert_array_equal(mem["channels"][0]["adev"]["adev"],
                                  got["channels"][0]["adev"]["adev"])
    assert len(got["template"]) == 30
    assert {r["term"] for r in got["template"]} == {"Q", "N", "B", "K", "R"}


def test_fit_is_cli_fit(cli, tmp_path, monkeypatch):
    cli("generate", "--scene", "static", "--imu", "adis16488", "--rate", 200, "--duration", 300,
        "--seed", 2, "--format", "bin", "-o", "a.bin", cwd=tmp_path)
    want = cli("fit", "a.bin", cwd=tmp_path).stdout.decode()
    monkeypatch.chdir(tmp_path)  # the template names the recording as given
    got = imu_emu.fit("a.bin")
    assert got["toml"] == want
    # The fitted template simulates (a dict is a template).
    r = imu_emu.simulate("static", imu=got["template"], rate=200.0, duration=1.0)
    assert len(r.records) == 200


def test_a_knock_in_records_is_left_out_as_from_a_file(cli, tmp_path):
    """Records in memory go through the CLI's transient search: a knock on accel z (a 15 Hz
    ring of 100 step RMS, 0.5 s) is found and left out, and the analysis is the one
    `imu-emu analyze` gives of the same samples in a CSV and inside the clean record's band;
    kept, it lifts accel z's Allan deviation at τ = Δt out of that band."""
    # 300 s: the knock and its margins (2.5 s) stay under the 1 % past which transients are
    # kept as the noise's own tails.
    sim = imu_emu.simulate("static", imu="stim300", rate=200.0, duration=300.0, seed=3)
    clean = imu_emu.analyze(sim)["channels"][5]["adev"]
    rows = np.array(sim.records.rows[:, :7])
    az = rows[:, 6]
    step = np.std(np.diff(az))
    t = np.arange(100) / 200.0
    az[12000:12100] += 100 * step * np.exp(-t / 0.1) * np.sin(2 * np.pi * 15 * t)
    csv = tmp_path / "k.csv"
    with csv.open("w") as f:
        f.write("t,gx,gy,gz,ax,ay,az\n")
        for r in rows:
            f.write(",".join(repr(float(v)) for v in r) + "\n")
    cli("analyze", "k.csv", "--csv", "c.csv", cwd=tmp_path, check=False)
    want = curves(tmp_path / "c.csv")
    got = imu_emu.analyze(rows)
    tr = got["transients"]
    assert tr["handling"] == "left out" and tr["list"][0]["channel"] == "accel z"
    # The knock's 0.5 s with 1 s on each side: 2.5 s at 200 Hz, give or take the ring's tail
    # under the bar.
    assert 400 <= tr["left_out"] <= 500
    for ch in got["channels"]:
        a = ch["adev"]
        np.testing.assert_array_equal(np.c_[a["tau"], a["adev"], a["lo"], a["hi"]],
                                      want[("adev", ch["name"].replace(" ", "_"))])
    # Left out, accel z reads as the record without the knock, inside its 68 % band at τ up to
    # 0.64 s: there the gap (2.5 s) and the differences spanning it are at most 1.3 % of the
    # record's, which moves the estimate by about √0.013 ≈ 0.11 of its own scatter. (At longer
    # τ the differences dropped are a larger share and the estimate may leave a 1σ band.)
    az_out = got["channels"][5]["adev"]["adev"][:8]
    assert np.all((clean["lo"][:8] <= az_out) & (az_out <= clean["hi"][:8]))
    kept = imu_emu.analyze(rows, keep_transients=True)
    assert kept["transients"]["handling"] == "kept" and kept["transients"]["left_out"] == 0
    assert kept["channels"][5]["adev"]["adev"][0] > clean["hi"][0]


def test_a_segment_beyond_its_limit_raises():
    """Issue 38: `analyze(a, segment=2**40)` aborted the interpreter; now it raises, naming
    the limit, for records in memory and for a file alike."""
    sim = imu_emu.simulate("static", rate=100.0, duration=2.0)
    for segment in (2**40, 1000):
        with pytest.raises(imu_emu.ImuEmuError, match="expected a power of two from 8 to 1048576"):
            imu_emu.analyze(sim, segment=segment)


def test_records_the_cli_would_refuse_in_a_file_raise():
    """Issue 38: a NaN column gave NaN statistics and an ADEV of 0; a rate no gyro measures,
    or a sampling rate of 1e300 Hz, was analysed. Each raises naming the row and column, or
    the limit, as the CLI names the line and column of a file."""
    rows = imu_emu.simulate("static", rate=100.0, duration=2.0).records.rows.copy()
    bad = rows.copy()
    bad[12, 2] = np.nan
    with pytest.raises(imu_emu.ImuEmuError, match=r"row 12, column 2 \(gyro y\): NaN is not a finite"):
        imu_emu.analyze(bad)
    bad[12, 2] = np.inf
    with pytest.raises(imu_emu.ImuEmuError, match="row 12, column 2"):
        imu_emu.fit(bad)
    bad[12, 2] = 1e30
    with pytest.raises(imu_emu.ImuEmuError, match="gyro y is 1e30 rad/s, beyond the 1e4 rad/s"):
        imu_emu.analyze(bad)
    with pytest.raises(imu_emu.ImuEmuError, match=r"expected a sampling rate in \(0, 1e7\] Hz"):
        imu_emu.analyze(rows, rate=1e300)
