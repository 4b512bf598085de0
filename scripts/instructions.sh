#!/usr/bin/env bash
# Instructions per record (valgrind callgrind), the stable cost measure on a noisy machine.
# Runs `generate` twice per case (two durations) and divides the difference in instruction
# counts by the difference in records, so start-up and setup cancel out.
#
#   scripts/instructions.sh [BINARY]     # default target/release/imu-emu
set -euo pipefail
bin=${1:-target/release/imu-emu}
command -v valgrind >/dev/null || { echo "needs valgrind (apt-get install valgrind)" >&2; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
count() { # instructions executed by one run of the arguments
  valgrind --tool=callgrind --callgrind-out-file="$tmp/cg" "$bin" "$@" 2>"$tmp/err" >/dev/null
  grep -oE 'Collected : [0-9]+' "$tmp/err" | grep -oE '[0-9]+'
}
printf '| scene | imu | rate (Hz) | instructions per record |\n|---|---|---|---|\n'
for imu in ideal ln200; do
  args=(generate --scene survey --imu "$imu" --rate 1000 --format bin -o /dev/null)
  a=$(count "${args[@]}" --duration 20)
  b=$(count "${args[@]}" --duration 120)
  echo "| survey | $imu | 1000 | $(( (b - a) / 100000 )) |"
done
