#!/bin/sh
# The navigator figure of a real-time live run (docs/live-input.md): the survey scene's states
# streamed at 100 Hz over UDP loopback in real time (examples/live_sender.py, binary
# datagrams) to `imu-emu run --motion udp://…` in realtime mode, ideal IMU, frames at
# 400 Hz in a frame of IEEE doubles (a spec written below: Δθ and Δv at full precision, so
# no quantisation hides the live path's own error) to a file; the frames are decoded and the
# reference navigator (docs/navigator.md) integrates them from the scene's state at the first
# record; its final and largest errors over the run are printed. A frame the pacer would skip
# as too late (a stalled machine) is a lost increment the navigator cannot recover from, so
# the file sink waits for every frame (--max-behind-ms 60000): what is measured is the live
# path's motion, not the machine's stalls (the summary counts the late frames).
#
# usage: scripts/live_nav600.sh [SECONDS (default 600)]   (from a clone's root; takes SECONDS
# of wall-clock time, little CPU). IMU_EMU: the binary (default target/release/imu-emu);
# PORT: the UDP port (default 5641).
set -eu
secs=${1:-600}
bin=$(realpath "${IMU_EMU:-target/release/imu-emu}")
sender=$(realpath examples/live_sender.py)
port=${PORT:-5641}
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
cd "$dir"
cat > f64.toml <<'SPEC'
name = "f64-increments"
description = "test frame: sync word, then dtheta and dv as little-endian IEEE doubles"
byte_order = "little"

[[field]]
name = "sync"
type = "u32"
value = 0x34364649

[[field]]
name = "dtheta_x"
type = "f64"
source = "dtheta.x"

[[field]]
name = "dtheta_y"
type = "f64"
source = "dtheta.y"

[[field]]
name = "dtheta_z"
type = "f64"
source = "dtheta.z"

[[field]]
name = "dv_x"
type = "f64"
source = "dv.x"

[[field]]
name = "dv_y"
type = "f64"
source = "dv.y"

[[field]]
name = "dv_z"
type = "f64"
source = "dv.z"
SPEC
# Half a second of states past the run, so the last records are interpolated.
"$bin" trajectory --scene survey --rate 100 --duration "$(echo "$secs + 0.5" | bc)" -o states.csv
"$bin" run --motion "udp://127.0.0.1:$port" --input-format bin --input-timeout 2 \
    --imu ideal --rate 400 --protocol-file f64.toml --duration "$secs" --max-behind-ms 60000 --file rt.bin \
    2> run.log &
run=$!
sleep 1
python3 "$sender" --trajectory states.csv --format bin "udp://127.0.0.1:$port"
wait "$run" || { cat run.log >&2; exit 1; }
grep -F 'frames at 400 Hz from' run.log
grep -F 'write lateness' run.log
# Decoded frames carry no time: record k ends at t0 + k/400 (t0 from the summary).
t0=$(sed -n 's/.*frames at 400 Hz from t = \([0-9.]*\) s.*/\1/p' run.log)
"$bin" decode --protocol-file f64.toml --rate 400 rt.bin 2> decode.log |
    awk -F, -v t0="$t0" 'NR == 1 { print; next } { $1 = sprintf("%.9f", t0 + (NR - 1) / 400); print }' OFS=, > rt.csv
"$bin" navigate rt.csv --scene survey --rate 400 2>&1 | grep -i error
