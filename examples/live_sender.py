#!/usr/bin/env python3
"""Streams vehicle states to `imu-emu run --motion ...` (docs/live-input.md), standard library only.

States come from a trajectory CSV file (`imu-emu trajectory` writes one) or from a live sine
manoeuvre (a lateral weave with a matching roll, computed as it is sent). Formats: `csv` (text
lines with the trajectory columns), `bin` (the 152-byte datagram of docs/live-input.md) and
`mavlink` (MAVLink 2 HIL_STATE_QUATERNION). Destinations: udp://HOST:PORT, tcp://HOST:PORT
(connects) or - (stdout).

    python3 live_sender.py --trajectory states.csv --format bin udp://127.0.0.1:5600
    python3 live_sender.py --sine --seconds 30 --format csv --fast - | imu-emu run --motion - ...

By default states are paced at their own time stamps (real time); --fast sends them as fast as
the destination takes them (for lockstep runs).

A hostile link or sender, for tests and scripts/soak.sh (all off by default; --seed fixes the
draws): --loss P drops each state with probability P, --reorder P sends a state after the
next one, --stall AT:S holds the states from time tag AT for S seconds then sends those owed
at once (a burst; the tags stay on the wall clock's schedule), --pause AT:S stops for S
seconds at time tag AT and resumes with continuous tags (the whole schedule moves S later).
A summary of what was done goes to stderr.
"""

import argparse
import math
import os
import random
import socket
import struct
import sys
import time
import zlib

A = 6378137.0  # WGS-84 semi-major axis (m)
F = 1.0 / 298.257223563
E2 = F * (2.0 - F)
COLUMNS = "t,lat,lon,h,vn,ve,vd,roll,pitch,yaw"


def quat_from_euler(roll, pitch, yaw):
    """C_b^n = Rz(yaw) Ry(pitch) Rx(roll) as (w, x, y, z); angles in radians."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )


def from_file(path):
    """Yields (t, lat°, lon°, h, vn, ve, vd, roll°, pitch°, yaw°, accel or None)."""
    with open(path) as f:
        order = None
        for line in f:
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            fields = line.split(",")
            if order is None:
                order = [fields.index(c) for c in COLUMNS.split(",")]
                continue
            yield tuple(float(fields[i]) for i in order) + (None,)


def sine(seconds, rate, lat0=45.0, lon0=7.0, h=300.0, speed=20.0, amp=5.0, period=8.0):
    """A vehicle heading north at `speed` m/s, weaving east by amp·sin(ωt) m, rolled into it.
    Exact NED accelerations go with each state."""
    w = 2.0 * math.pi / period
    s = math.sin(math.radians(lat0))
    rn = A * (1 - E2) / (1 - E2 * s * s) ** 1.5
    re = A / math.sqrt(1 - E2 * s * s)
    for k in range(int(seconds * rate) + 1):
        t = k / rate
        north = speed * t
        lat = lat0 + math.degrees(north / (rn + h))
        sl = math.sin(math.radians(lat))
        re = A / math.sqrt(1 - E2 * sl * sl)
        east = amp * math.sin(w * t)
        lon = lon0 + math.degrees(east / ((re + h) * math.cos(math.radians(lat))))
        ve = amp * w * math.cos(w * t)
        ae = -amp * w * w * math.sin(w * t)
        roll = math.degrees(math.atan2(ae, 9.81))
        yaw = math.degrees(math.atan2(ve, speed))
        # The NED velocity components' rates (north constant, east as written); the small
        # terms of a latitude-dependent R_N are below what this example needs to be exact.
        yield (t, lat, lon, h, speed, ve, 0.0, roll, 0.0, yaw, (0.0, ae, 0.0))


def csv_line(s, with_accel):
    vals = list(s[:10]) + (list(s[10]) if with_accel else [])
    return (",".join(repr(float(v)) for v in vals) + "\n").encode()


def datagram(seq, s):
    t, lat, lon, h, vn, ve, vd, roll, pitch, yaw, acc = s
    q = quat_from_euler(math.radians(roll), math.radians(pitch), math.radians(yaw))
    flags = 2 if acc else 0
    body = b"IMUS" + struct.pack("<BBHId", 1, flags, 0xFFFF, seq & 0xFFFFFFFF, t)
    body += struct.pack("<3d3d3d4d3d", lat, lon, h, vn, ve, vd, *(acc or (0.0, 0.0, 0.0)), *q, 0.0, 0.0, 0.0)
    return body + struct.pack("<I", zlib.crc32(body))


def x25(data, crc=0xFFFF):
    for b in data:
        tmp = b ^ (crc & 0xFF)
        tmp = (tmp ^ (tmp << 4)) & 0xFF
        crc = ((crc >> 8) ^ (tmp << 8) ^ (tmp << 3) ^ (tmp >> 4)) & 0xFFFF
    return crc


def mavlink(seq, s):
    t, lat, lon, h, vn, ve, vd, roll, pitch, yaw, _ = s
    q = quat_from_euler(math.radians(roll), math.radians(pitch), math.radians(yaw))
    payload = struct.pack(
        "<Q4ffffiiihhhHHhhh",
        int(round(t * 1e6)), *q, 0.0, 0.0, 0.0,
        int(round(lat * 1e7)), int(round(lon * 1e7)), int(round(h * 1e3)),
        int(round(vn * 100)), int(round(ve * 100)), int(round(vd * 100)), 0, 0, 0, 0, 0,
    ).rstrip(b"\0") or b"\0"
    head = struct.pack("<BBBBBBB", len(payload), 0, 0, seq & 0xFF, 1, 1, 115) + b"\0\0"
    crc = x25(bytes([4]), x25(head + payload))
    return b"\xfd" + head + payload + struct.pack("<H", crc)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--trajectory", help="trajectory CSV file")
    src.add_argument("--sine", action="store_true", help="a live sine manoeuvre")
    p.add_argument("--seconds", type=float, default=60.0, help="length of the sine manoeuvre")
    p.add_argument("--rate", type=float, default=100.0, help="state rate of the sine (Hz)")
    p.add_argument("--format", choices=["csv", "bin", "mavlink"], default="csv")
    p.add_argument("--fast", action="store_true", help="do not pace the states")
    p.add_argument("--loss", type=float, default=0.0, help="probability a state is not sent")
    p.add_argument("--reorder", type=float, default=0.0, help="probability a state is sent after the next")
    p.add_argument("--stall", action="append", default=[], metavar="AT:S",
                   help="hold states from tag AT for S s, then send them at once (repeatable)")
    p.add_argument("--pause", action="append", default=[], metavar="AT:S",
                   help="stop S s at tag AT, resume with continuous tags (repeatable)")
    p.add_argument("--seed", type=int, default=1, help="seed of the loss and reorder draws")
    p.add_argument("dest", help="udp://HOST:PORT, tcp://HOST:PORT or -")
    a = p.parse_args()
    spans = lambda xs: sorted(tuple(float(v) for v in x.split(":")) for x in xs)
    stalls, pauses = spans(a.stall), spans(a.pause)
    rng = random.Random(a.seed)

    if a.dest == "-":
        out = sys.stdout.buffer
        send = lambda b: (out.write(b), out.flush())
    else:
        scheme, _, rest = a.dest.partition("://")
        host, _, port = rest.rpartition(":")
        if scheme == "udp":
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            send = lambda b: sock.sendto(b, (host, int(port)))
        elif scheme == "tcp":
            sock = socket.create_connection((host, int(port)))
            send = sock.sendall
        else:
            sys.exit(f"{a.dest}: expected udp://HOST:PORT, tcp://HOST:PORT or -")

    def emit(seq, s):
        if a.format == "csv":
            if seq == 0:
                extra = ",an,ae,ad" if s[10] else ""
                send((COLUMNS + extra + "\n").encode())
            send(csv_line(s, s[10] is not None))
        elif a.format == "bin":
            send(datagram(seq, s))
        else:
            send(mavlink(seq, s))

    states = sine(a.seconds, a.rate) if a.sine else from_file(a.trajectory)
    start = None
    shift = 0.0  # the pauses so far (s)
    held = None  # a state kept back to be sent after the next one
    done = {"sent": 0, "lost": 0, "reordered": 0, "stalls": 0, "pauses": 0}
    for seq, s in enumerate(states):
        if not a.fast:
            if start is None:
                start = time.monotonic() - s[0]
            while pauses and s[0] >= pauses[0][0]:
                shift += pauses.pop(0)[1]
                done["pauses"] += 1
            due = s[0] + shift
            for at, length in stalls:
                if at <= s[0] < at + length:
                    due = at + length + shift
            delay = start + due - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            while stalls and s[0] >= stalls[0][0] + stalls[0][1]:
                stalls.pop(0)
                done["stalls"] += 1
        # Never the first states: the receiver needs a stencil of them to start.
        if seq > 20 and a.loss > 0 and rng.random() < a.loss:
            done["lost"] += 1
            continue
        if held is not None:
            emit(seq, s)
            emit(*held)
            done["sent"] += 2
            held = None
            continue
        if seq > 20 and a.reorder > 0 and rng.random() < a.reorder:
            held = (seq, s)
            done["reordered"] += 1
            continue
        emit(seq, s)
        done["sent"] += 1
    if held is not None:
        emit(*held)
        done["sent"] += 1
    print("live_sender: " + ", ".join(f"{v} {k}" for k, v in done.items()), file=sys.stderr)


if __name__ == "__main__":
    try:
        main()
    except (BrokenPipeError, ConnectionResetError):
        # The receiver stopped reading (its run is complete): not an error of the sender.
        # Python flushes stdout at exit; point it at /dev/null so that flush cannot fail.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        sys.exit(0)
