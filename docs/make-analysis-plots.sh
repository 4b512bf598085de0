#!/bin/sh
# Regenerates the analysis figures in docs/ (README, "analyze"): run from the repository root.
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
