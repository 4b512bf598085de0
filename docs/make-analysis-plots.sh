#!/bin/sh
# Regenerates the figures in docs/ (docs/analysis.md, docs/navigator.md): run from the
# repository root after `cargo build --release`.
set -eu
bin=${IMU_EMU:-target/release/imu-emu}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# LN-200: white noise and carried LSB quantization, 400 Hz, 600 s static.
"$bin" generate --scene static --imu ln200 --rate 400 --duration 600 --format bin -o "$tmp/ln200.bin"
"$bin" analyze "$tmp/ln200.bin" --imu ln200 --plot docs/adev-ln200.png
# STIM300: adds bias instability, 200 Hz, 2 h static.
"$bin" generate --scene static --imu stim300 --rate 200 --duration 7200 --format bin -o "$tmp/stim300.bin"
"$bin" analyze "$tmp/stim300.bin" --imu stim300 --plot docs/adev-stim300.png
# compare: error growth over 60 s GNSS outages on the survey scene, five grades.
"$bin" compare --imu ln200,hg1700,stim300,adis16405,mpu6000 --scene survey --runs 20 --outage 60 \
    --csv "$tmp/growth.csv" --plot docs/compare-survey-60s.png
# compare: a rig's three units, GNSS-aided before 10 s and 30 s outages (docs/navigator.md).
"$bin" compare --scene-file examples/compare_rig.toml --outage 10,30 --aided 60 --runs 20 \
    --plot docs/compare-rig-aided.png
