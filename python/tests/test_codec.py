"""`encode`/`decode` against the CLI's frames and `imu-emu decode`'s CSV."""

import numpy as np
import pytest

import imu_emu


def decode_csv(text):
    """`imu-emu decode`'s CSV as (columns, values with NaN for empty cells)."""
    lines = text.decode().splitlines()
    cols = lines[0].split(",")
    rows = [[float(x) if x else np.nan for x in line.split(",")] for line in lines[1:]]
    return cols, np.array(rows)


# Protocols whose frames carry rates (stim300), increments (kvh1750, ln200) or both with time
# tags (imar-ixcom), with their counters and checks.
# iMAR iXCOM has no nominal rate: its rates come from its time tags.
PROTOCOLS = [("stim300", "nominal"), ("kvh1750", "nominal"), ("ln200", "nominal"),
             ("imar-ixcom", None)]


@pytest.mark.parametrize("protocol,rate", PROTOCOLS)
def test_decode_is_cli_decode_and_encode_round_trips(cli, tmp_path, protocol, rate):
    cli("generate", "--scene", "circle", "--imu", "stim300", "--format", protocol, "--seed", 5,
        "--duration", 0.5, "-o", "f.bin", cwd=tmp_path)
    frames = (tmp_path / "f.bin").read_bytes()
    # The offline run's frames are simulate's output.
    sim = imu_emu.simulate("circle", imu="stim300", format=protocol, seed=5, duration=0.5)
    assert sim.output == frames
    flags = ["--rate", rate] if rate else []
    out = cli("decode", "--protocol", protocol, *flags, "f.bin", cwd=tmp_path).stdout
    cols, want = decode_csv(out)
    d = imu_emu.decode(frames, protocol, rate=rate)
    assert d["columns"] == cols
    assert d["stats"]["frames"] == len(want) and d["stats"]["check_failures"] == 0
    np.testing.assert_array_equal(d["values"], want)  # NaN == NaN here, exact elsewhere
    # The records simulate returns encode into the same frames.
    assert imu_emu.encode(sim, protocol) == frames


def test_decode_refuses_noise_with_the_cli_message(cli, tmp_path):
    noise = bytes(range(256)) * 4
    (tmp_path / "noise.bin").write_bytes(noise)
    p = cli("decode", "--protocol", "kvh1750", "noise.bin", cwd=tmp_path, check=False)
    assert p.returncode != 0
    with pytest.raises(imu_emu.ImuEmuError) as e:
        imu_emu.decode(noise, "kvh1750")
    assert str(e.value) in p.stderr.decode()


def test_encode_refuses_wrong_shapes_and_protocols():
    with pytest.raises(imu_emu.ImuEmuError, match="13"):
        imu_emu.encode(np.zeros((3, 7)), "kvh1750")
    with pytest.raises(imu_emu.ImuEmuError):
        imu_emu.encode(np.zeros((3, 13)), "no-such-protocol")


def test_encode_refuses_values_a_frame_cannot_carry():
    """Issue 38: NaN and 1e300 were encoded into frames that decode as values with no flag.
    A NaN or ±inf raises, naming the row and column; a value beyond a field's range is
    clipped with the protocol's status bits where it has them (STIM300: the gyro status
    word, as the CLI's frames), and raises where it has none (NovAtel's integer fields)."""
    rows = imu_emu.simulate("static", imu="stim300", rate=200.0, duration=0.2).records.rows
    for v in (np.nan, np.inf):
        bad = rows.copy()
        bad[5, 1] = v
        with pytest.raises(imu_emu.ImuEmuError, match=r"row 5, column 1 \(`gyro_x`\)"):
            imu_emu.encode(bad, "stim300")
    big = rows.copy()
    big[5, 1] = 1e300
    d = imu_emu.decode(imu_emu.encode(big, "stim300"), "stim300")
    gyro_status = d["values"][:, d["columns"].index("gyro_status")]
    assert gyro_status[5] != 0 and np.all(np.delete(gyro_status, 5) == 0)
    assert d["stats"]["status_flagged"] == 1
    with pytest.raises(imu_emu.ImuEmuError, match="row 5: a value beyond the range of a `novatel-rawimusx` field"):
        imu_emu.encode(big, "novatel-rawimusx")
