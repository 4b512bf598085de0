"""Public static IMU recordings to the CSV `imu-emu fit` reads (t,gx,gy,gz,ax,ay,az).

Used by scripts/fit_real.sh. None of these recordings is in this repository: clone the
repositories named below and give their paths. The tests read two MPU-6050 records as register
counts, made with `mpu6050-counts`, from the public data set sensor-fusion (docs/testing.md).

  adis16405 RDA OUT  SMAC-Group/imudata data/adis_16405_imuN.rda (CC BY-NC-SA 4.0): an R
                     matrix of 10^6 rows, gyro deg/s, accel g, 100 Hz (the package's own
                     description, R/data.R). Time is written as k/100 s.
  mpu6050 DIR OUT    sunsided/sensor-fusion data/set-2/<DIR> (EUPL-1.2): MATLAB v7.3 files
                     mpu6050_gyroscope.mat (gyroBuffer: t, x, y, z in deg/s) and
                     mpu6050_accelerometer.mat (accelBuffer: t, x, y, z in g), one host time
                     tag per sample.
  mpu6050-counts DIR OUT
                     the same record as the sensor's register counts, without the time tags
                     (gx,gy,gz in 1/131 deg/s, ax,ay,az in 1/4096 g: its ±250 deg/s and ±8 g
                     ranges); refused unless every value is a whole count.
  mtig RDA OUT       SMAC-Group/imudata data/cont.imu1.rda, in the repository's history (commit
                     d054287; removed later; CC BY-NC-SA 4.0): one column, the gyro x of an
                     Xsens MTi-G (EPFL TOPO), 500 000 samples, "possibly suffering from some
                     contaminated measurements (outliers)" (the package's README), at 100 Hz
                     (the README's rate for its MTi-G records); rad/s (its white noise, 1.9
                     deg/sqrt(h), is the MTi-G's order; in deg/s it would be 0.03 deg/sqrt(h)).
                     Written as t,gx with t = k/100 s.
  avar RDA OUT       SMAC-Group/avar data/<name>_av.rda (AGPL-3): per-axis maximal-overlap
                     Allan deviations at octave τ (2Δt … ) of a static recording, with its rate
                     and sample count, written as the Allan deviation table `fit` reads
                     (docs/fit.md). The package does not state units; each data set's are read
                     from its white-noise level against the figures published for it (the
                     LN-200's accelerometers are taken as m/s², which nothing confirms).

Needs: pip install rdata h5py numpy
"""

import sys

import numpy as np


def adis16405(rda, out):
    import rdata

    parsed = rdata.parser.parse_file(rda)
    value = np.asarray(list(rdata.conversion.convert(parsed).values())[0])
    if value.shape[1] != 6:
        sys.exit(f"{rda}: expected 6 columns, got {value.shape}")
    with open(out, "w") as f:
        f.write("t,gx,gy,gz,ax,ay,az\n")
        for k, row in enumerate(value):
            f.write("%.2f,%s\n" % ((k + 1) / 100.0, ",".join(repr(float(x)) for x in row)))


def mpu6050_buffers(folder):
    import h5py

    g = np.array(h5py.File(f"{folder}/mpu6050_gyroscope.mat", "r")["gyroBuffer"])
    a = np.array(h5py.File(f"{folder}/mpu6050_accelerometer.mat", "r")["accelBuffer"])
    if not np.array_equal(g[0], a[0]):
        sys.exit(f"{folder}: gyro and accelerometer time tags differ")
    return g, a


def mpu6050(folder, out):
    g, a = mpu6050_buffers(folder)
    with open(out, "w") as f:
        f.write("t,gx,gy,gz,ax,ay,az\n")
        for k in range(g.shape[1]):
            row = [g[0, k], g[1, k], g[2, k], g[3, k], a[1, k], a[2, k], a[3, k]]
            f.write(",".join(repr(float(x)) for x in row) + "\n")


def mpu6050_counts(folder, out):
    g, a = mpu6050_buffers(folder)
    counts = np.vstack([g[1:4] * 131.0, a[1:4] * 4096.0])
    whole = np.round(counts)
    if np.max(np.abs(counts - whole)) > 1e-6:
        sys.exit(f"{folder}: values that are not whole register counts")
    with open(out, "w") as f:
        f.write("gx,gy,gz,ax,ay,az\n")
        for k in range(counts.shape[1]):
            f.write(",".join(str(int(x)) for x in whole[:, k]) + "\n")


# Units of the avar data sets (gyro, accel), in the table's column units, and the factor from
# the data set's values to them: LN-200 gyro ARW 0.041 deg/√h at 1.28 s in rad/s; iMAR 0.090;
# KVH 1750 gyro 0.0031 deg/√h in deg/s, accel minimum 33–43 µg in g; NavChip σ(1 s) 13 deg/h in
# rad/s, VRW 0.03 m/s/√h in m/s²; ADIS16405 (SMAC-Group/imudata's runs) deg/s and g.
AVAR_UNITS = {
    "ln200_av": (("rad_s", 1.0), ("m_s2", 1.0)),
    "imar_av": (("rad_s", 1.0), None),
    "kvh1750_av": (("deg_s", 1.0), ("mg", 1e3)),
    "navchip_av": (("rad_s", 1.0), ("m_s2", 1.0)),
    "adis_av": (("deg_s", 1.0), ("mg", 1e3)),
}


def mtig(rda, out):
    import warnings

    import rdata

    warnings.filterwarnings("ignore", message="Missing constructor")
    value = np.asarray(list(rdata.conversion.convert(rdata.parser.parse_file(rda)).values())[0])
    if value.ndim != 2 or value.shape[1] != 1:
        sys.exit(f"{rda}: expected 1 column, got {value.shape}")
    with open(out, "w") as f:
        f.write("t,gx\n")
        for k, x in enumerate(value[:, 0]):
            f.write("%.2f,%r\n" % ((k + 1) / 100.0, float(x)))


def avar(rda, out):
    import warnings

    import rdata

    # The R classes `avar` and `imu_avar` have no converter; they are plain lists underneath.
    warnings.filterwarnings("ignore", message="Missing constructor")
    converted = rdata.conversion.convert(rdata.parser.parse_file(rda))
    name = list(converted.keys())[0]
    if name not in AVAR_UNITS:
        sys.exit(f"{rda}: data set `{name}` has no known units (known: {', '.join(AVAR_UNITS)})")
    v = converted[name]
    freq, n = float(np.asarray(v["freq"])[0]), int(np.asarray(v["n"])[0])
    columns, taus = [], set()
    for key, x in v["avar"].items():
        sensor = {"Gyro.": 0, "Accel.": 1}[key.split()[0]]
        unit = AVAR_UNITS[name][sensor]
        if unit is None:
            sys.exit(f"{rda}: `{key}` has no known unit")
        levels = [float(t) for t in np.asarray(x["levels"])]
        adev = [float(a) * unit[1] for a in np.asarray(x["adev"])]
        col = "ga"[sensor] + key.split()[1].lower() + "_" + unit[0]
        columns.append((col, dict(zip(levels, adev))))
        taus.update(levels)
    with open(out, "w") as f:
        f.write(f"# {np.asarray(v['sensor'])[0]}: SMAC-Group/avar data set `{name}` (AGPL-3),\n")
        f.write("# per-axis maximal-overlap Allan deviation; converted by scripts/fit_real_convert.py.\n")
        f.write(f"# rate = {freq:g} Hz\n# record_length = {n / freq:.10g} s\n")
        f.write("tau_s," + ",".join(c for c, _ in columns) + "\n")
        for t in sorted(taus):
            cells = [repr(d[t]) if t in d else "" for _, d in columns]
            f.write(repr(t) + "," + ",".join(cells) + "\n")


if __name__ == "__main__":
    modes = {
        "adis16405": adis16405,
        "mpu6050": mpu6050,
        "mpu6050-counts": mpu6050_counts,
        "mtig": mtig,
        "avar": avar,
    }
    if len(sys.argv) != 4 or sys.argv[1] not in modes:
        sys.exit(__doc__)
    modes[sys.argv[1]](sys.argv[2], sys.argv[3])
