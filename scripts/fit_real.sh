#!/usr/bin/env bash
# Fits templates to public static recordings of real IMUs and checks the closure of each
# (docs/fit.md, "Real recordings"): `imu-emu fit REC -o UNIT.toml --report REPORT.md --plot
# PICTURE.png` simulates a record of the same length from the fitted template and lists its
# Allan deviation per octave and PSD per band against the recording's bands. Prints one line
# per recording and channel: octaves and PSD bands inside.
#
#   scripts/fit_real.sh IMUDATA SENSOR_FUSION OUT [AVAR]
#
# IMUDATA: a clone of https://github.com/SMAC-Group/imudata (ADIS16405, six 10^6-sample runs
# at 100 Hz, and from its history (commit d054287) an Xsens MTi-G's gyro x, 500 000 samples at
# 100 Hz with outliers; CC BY-NC-SA 4.0). SENSOR_FUSION: a clone of https://github.com/sunsided/sensor-fusion
# (MPU-6050, set-2; EUPL-1.2). Either may be `-` to skip it. The ADIS16448 and BMI160 Allan
# deviation tables of gaowenliang/imu_utils (MIT) are read from the public data set imu_utils in
# $IMU_EMU_TEST_DATA (default ../shared/data beside the clone; docs/testing.md). AVAR, optional:
# a clone of https://github.com/SMAC-Group/avar (AGPL-3), whose per-axis Allan deviation tables
# of an LN-200, an iMAR FSAS-class unit, a KVH 1750, a NavChip and an ADIS16405 are fitted as
# tables. OUT receives the converted CSVs, templates, reports and pictures. Needs python3 with
# rdata, h5py, numpy (installed into OUT/venv on first use) and imu-emu built (cargo build
# --release).
set -euo pipefail
[ $# -eq 3 ] || [ $# -eq 4 ] || { sed -n '2,20p' "$0"; exit 2; }
here=$(cd "$(dirname "$0")/.." && pwd)
imudata=$1 fusion=$2 out=$3 avar=${4:--}
mkdir -p "$out"
bin="$here/target/release/imu-emu"
[ -x "$bin" ] || (cd "$here" && cargo build --release --bin imu-emu)
py="$out/venv/bin/python"
[ -x "$py" ] || { python3 -m venv "$out/venv" && "$out/venv/bin/pip" install -q rdata h5py numpy; }
conv="$here/scripts/fit_real_convert.py"

fit() { # name input [fit flags...]
    local name=$1 input=$2
    shift 2
    "$bin" fit "$input" "$@" -o "$out/$name.toml" --report "$out/$name.md" --plot "$out/$name.png" \
        > /dev/null 2> "$out/$name.log" || { cat "$out/$name.log"; return 1; }
    sed -n 's/^- \(gyro\|accel\) \([xyz]\): Allan deviation/'"$name"' \1 \2:/p' "$out/$name.md"
}

if [ "$imudata" != - ]; then
    for i in 1 2 3 4 5 6; do
        csv="$out/adis16405-run$i.csv"
        [ -s "$csv" ] || "$py" "$conv" adis16405 "$imudata/data/adis_16405_imu$i.rda" "$csv"
        fit "adis16405-run$i" "$csv" --gyro-unit deg/s --accel-unit g
    done
    csv="$out/mtig-gyro-x.csv"
    if [ ! -s "$csv" ]; then
        git -C "$imudata" show d054287:data/cont.imu1.rda > "$out/cont.imu1.rda"
        "$py" "$conv" mtig "$out/cont.imu1.rda" "$csv"
    fi
    fit mtig-gyro-x "$csv"
fi
if [ "$fusion" != - ]; then
    set2="$fusion/data/set-2"
    csv="$out/mpu6050-static.csv"
    [ -s "$csv" ] || "$py" "$conv" mpu6050 "$set2/unmoved-with-x-pointing-forward-10min" "$csv"
    # Its time tags are the host's (reads of the sensor's buffer in bursts, steps 1.2 ms to
    # 0.5 s): fit refuses them, so it is read without them at the mean rate, 65067 samples in
    # 655.13 s.
    if "$bin" fit "$csv" --gyro-unit deg/s --accel-unit g -o "$out/refused.toml" 2> "$out/refused.log"; then
        echo "expected fit to refuse the host time tags of $csv" >&2; exit 1
    fi
    sed 's/^/refused: /' "$out/refused.log" | tail -1
    fit mpu6050-static "$csv" --columns=-,gx,gy,gz,ax,ay,az --rate 99.32 --gyro-unit deg/s --accel-unit g
    moving="$out/mpu6050-moving.csv"
    [ -s "$moving" ] || "$py" "$conv" mpu6050 "$set2/rotate-ccw-around-z-pointing-up" "$moving"
    if "$bin" fit "$moving" --columns=-,gx,gy,gz,ax,ay,az --rate 100 --gyro-unit deg/s --accel-unit g \
        -o "$out/moving.toml" 2> "$out/moving.log"; then
        echo "expected fit to refuse the moving record $moving" >&2; exit 1
    fi
    sed 's/^/refused: /' "$out/moving.log" | tail -1
fi
tables="${IMU_EMU_TEST_DATA:-$here/../shared/data}/imu_utils"
if [ -d "$tables" ]; then
    for unit in adis16448 bmi160; do
        fit "$unit" "$tables/$unit-adev.csv"
    done
else
    echo "skipped: the imu_utils tables, not found at $tables (set IMU_EMU_TEST_DATA)" >&2
fi
if [ "$avar" != - ]; then
    for set in ln200 imar kvh1750 navchip adis; do
        table="$out/avar-$set.csv"
        [ -s "$table" ] || "$py" "$conv" avar "$avar/data/${set}_av.rda" "$table"
        fit "avar-$set" "$table"
    done
fi
