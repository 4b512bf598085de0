"""`analyze` and `fit` against `imu-emu analyze --csv` and `imu-emu fit`."""

import numpy as np

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
