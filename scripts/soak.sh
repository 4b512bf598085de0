#!/bin/sh
# Soak benchmark of the live real-time path (docs/live-input.md, "Soak"): a live sine
# manoeuvre at 100 Hz as binary datagrams over UDP loopback (examples/live_sender.py) with
# 1 % loss, 1 % reordering, a 2 s stall caught up by a burst and a 3 s pause with continuous
# time tags every 300 s, to `imu-emu run --motion udp://…` in real time (default output
# delay), ideal IMU, 1 kHz frames of IEEE doubles with their time of validity (a spec written
# below) to a file. Every 10 s the run's resident memory (VmRSS) and the machine's load are
# logged. At the end the recorded input is replayed in lockstep and every frame compared
# (scripts/soak_compare.py): frames missing from the grid against those the run reported
# skipped, the transients where the real-time frames differ from lockstep's, and whether they
# are lockstep's again after each.
#
# usage: scripts/soak.sh [SECONDS (default 3600)] [OUTDIR (default a temporary directory)]
# (from a clone's root; takes SECONDS of wall-clock time, little CPU; runs under nice).
# IMU_EMU: the binary (default target/release/imu-emu, copied so a rebuild cannot disturb
# the run); PORT: the UDP port (default 5651).
set -eu
secs=${1:-3600}
root=$(pwd)
if [ -n "${2:-}" ]; then dir=$2; mkdir -p "$dir"; else dir=$(mktemp -d); fi
cp "${IMU_EMU:-target/release/imu-emu}" "$dir/imu-emu"
bin="$dir/imu-emu"
sender="$root/examples/live_sender.py"
compare="$root/scripts/soak_compare.py"
port=${PORT:-5651}
cd "$dir"
cat > f64t.toml <<'SPEC'
name = "f64-time-increments"
description = "soak frame: sync word, time of validity, dtheta and dv as little-endian IEEE doubles"
byte_order = "little"

[[field]]
name = "sync"
type = "u32"
value = 0x34364649

[[field]]
name = "t"
type = "f64"
source = "time"

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
# Events every 300 s (every 60 s in runs shorter than 20 minutes): a stall at +60 s (the
# next 2 s of states held, then sent at once), a pause at +210 s (+40 s) with continuous tags.
every=300; stall_at=60; pause_at=210
if [ "$secs" -lt 1200 ]; then every=60; stall_at=15; pause_at=40; fi
events=""; flags=""
k=0
while [ $((k * every + pause_at)) -lt $((secs - 10)) ]; do
    s=$((k * every + stall_at)); p=$((k * every + pause_at))
    flags="$flags --stall $s:2 --pause $p:3"
    events="$events$s,$p,"
    k=$((k + 1))
done
echo "soak: $secs s, events (stall 2 s, pause 3 s) at tags $events" | tee soak.log
nice "$bin" run --motion "udp://127.0.0.1:$port" --input-format bin --input-timeout 5 \
    --imu ideal --rate 1000 --protocol-file f64t.toml --file rt.bin --record-input in.rec \
    2> run.log &
run=$!
( while kill -0 "$run" 2>/dev/null; do
    printf '%s %s %s\n' "$(date +%s)" "$(awk '/VmRSS/ {print $2}' /proc/$run/status 2>/dev/null)" \
        "$(cut -d' ' -f1-3 /proc/loadavg)"
    sleep 10
  done ) > rss.log &
sleep 1
# shellcheck disable=SC2086
nice python3 "$sender" --sine --seconds "$secs" --rate 100 --format bin --loss 0.01 --reorder 0.01 \
    --seed 23 $flags "udp://127.0.0.1:$port" 2> sender.log
wait "$run" || { cat run.log >&2; exit 1; }
cat sender.log | tee -a soak.log
tail -n 3 run.log | tee -a soak.log
awk 'NF >= 2 && $2 != "" { if (!n++) first = $2; last = $2; if ($2 > max) max = $2; if (min == "" || $2 < min) min = $2; load += $3; m++ }
     END { printf "RSS (kB): first %d, last %d, min %d, max %d over %d samples; mean 1-min load %.2f\n", first, last, min, max, n, load / m }' rss.log | tee -a soak.log
nice "$bin" run --motion in.rec --input-format bin --time-mode lockstep --imu ideal --rate 1000 \
    --protocol-file f64t.toml --file replay.bin 2> replay.log || { cat replay.log >&2; exit 1; }
skipped=$(sed -n 's/.*, \([0-9]*\) skipped (too late).*/\1/p' run.log | tail -n 1)
python3 "$compare" rt.bin replay.bin 1000 "${skipped:-0}" "$events" | tee -a soak.log
echo "soak: results in $dir"
