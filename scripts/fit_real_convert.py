"""Public static IMU recordings to the CSV `imu-emu fit` reads (t,gx,gy,gz,ax,ay,az).

Used by scripts/fit_real.sh. The ADIS16405 data are not in this repository (their licence
does not allow it): clone the repositories named below and give their paths. Two MPU-6050
records are, as register counts (tests/data/sensor-fusion/, made with `mpu6050-counts`).

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
                     ranges); refused unless every value is a whole count. tests/data/sensor-fusion/ holds two such files.

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


if __name__ == "__main__":
    modes = {"adis16405": adis16405, "mpu6050": mpu6050, "mpu6050-counts": mpu6050_counts}
    if len(sys.argv) != 4 or sys.argv[1] not in modes:
        sys.exit(__doc__)
    modes[sys.argv[1]](sys.argv[2], sys.argv[3])
