#!/usr/bin/env python3
"""Compares a soak run's real-time frames with the lockstep replay of its recorded input
(scripts/soak.sh): frames of the f64 spec written there (sync, time of validity, Δθ, Δv as
little-endian doubles, 60 bytes). Prints one line per check and exits 1 when one fails.

usage: soak_compare.py RT.bin REPLAY.bin RATE SKIPPED [EVENTS]
  SKIPPED: the frames the run reported as skipped (too late); EVENTS: the time tags (s) where
  the sender paused or stalled (comma-separated), to say which transient each difference is in.
"""
import struct
import sys

FRAME = 60
SYNC = 0x34364649


def frames(path):
    data = open(path, "rb").read()
    if len(data) % FRAME:
        sys.exit(f"{path}: {len(data)} bytes is not a whole number of {FRAME}-byte frames")
    out = {}
    for i in range(0, len(data), FRAME):
        sync, t = struct.unpack_from("<Id", data, i)
        if sync != SYNC:
            sys.exit(f"{path}: frame {i // FRAME}: sync {sync:#x}")
        out[round(t * 1e6)] = data[i + 12 : i + FRAME]
    return out, len(data) // FRAME


def main():
    rt_path, replay_path, rate, skipped = sys.argv[1], sys.argv[2], float(sys.argv[3]), int(sys.argv[4])
    events = [float(x) for x in sys.argv[5].split(",") if x] if len(sys.argv) > 5 else []
    rt, n_rt = frames(rt_path)
    rp, n_rp = frames(replay_path)
    ok = True
    step = round(1e6 / rate)
    keys = sorted(rt)
    first, last = keys[0], keys[-1]
    expected = (last - first) // step + 1
    missing = expected - len(rt)
    print(f"real-time frames: {n_rt} from t = {first / 1e6} s to {last / 1e6} s; "
          f"{missing} missing in the grid, {skipped} reported skipped")
    if missing != skipped:
        print("FAIL: frames missing that were not reported (or reported and present)")
        ok = False
    common = sorted(set(rt) & set(rp))
    diff = [k for k in common if rt[k] != rp[k]]
    print(f"lockstep replay: {n_rp} frames; {len(common)} on both; {len(diff)} differ")
    # Group the differing frames into runs (a gap of more than 2 frames starts a new one).
    runs = []
    for k in diff:
        if runs and k - runs[-1][1] <= 2 * step:
            runs[-1][1] = k
            runs[-1][2] += 1
        else:
            runs.append([k, k, 1])
    worst = [0.0] * 6
    for k in diff:
        a = struct.unpack("<6d", rt[k])
        b = struct.unpack("<6d", rp[k])
        worst = [max(w, abs(x - y) * rate) for w, x, y in zip(worst, a, b)]
    print(f"{len(runs)} transients; largest difference gyro {max(worst[:3]):.3e} rad/s, "
          f"accel {max(worst[3:]):.3e} m/s²")
    # A transient that starts within 20 ms (two input periods) of a stall or pause is that
    # event's; the others
    # follow a lost state (the real-time run extrapolated over the gap that lockstep
    # interpolates).
    at_event, other = [], []
    for r in runs:
        near = [e for e in events if abs(e - r[0] / 1e6) <= 0.02]
        (at_event if near else other).append(r)
    for r in at_event:
        a = [struct.unpack("<6d", rt[k]) for k in range(r[0], r[1] + 1, step) if k in rt and k in rp]
        b = [struct.unpack("<6d", rp[k]) for k in range(r[0], r[1] + 1, step) if k in rt and k in rp]
        g = max(max(abs(x - y) * rate for x, y in zip(p[:3], q[:3])) for p, q in zip(a, b))
        f = max(max(abs(x - y) * rate for x, y in zip(p[3:], q[3:])) for p, q in zip(a, b))
        print(f"  event transient {r[0] / 1e6:.3f}–{r[1] / 1e6:.3f} s: {r[2]} frames differ, "
              f"largest gyro {g:.3e} rad/s, accel {f:.3e} m/s²")
    longest = max((r[1] - r[0]) / 1e6 + 1 / rate for r in other) if other else 0.0
    print(f"{len(other)} other transients (after lost states), the longest {longest:.3f} s, "
          f"{sum(r[2] for r in other)} frames in all")
    if common and rt[common[-1]] != rp[common[-1]]:
        print("FAIL: the last common frame differs (drift)")
        ok = False
    if runs:
        gaps = [(b[0] - a[1]) / 1e6 for a, b in zip(runs, runs[1:])]
        print(f"between transients the frames are lockstep's bytes; the shortest such stretch "
              f"{min(gaps, default=0):.3f} s, the last transient ends at {runs[-1][1] / 1e6:.3f} s "
              f"of {common[-1] / 1e6:.3f} s")
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
