#!/usr/bin/env python3
"""Decode an imu-emu frame stream with another party's decoder and print one line per frame,
`key=value;key=value;…` (floats as Python's shortest round-trip repr, nested header left out): MAVLink with pymavlink, NovAtel RAWIMUSXB with NovAtel EDIE (novatel_edie). Used by
tests/external_decoders.rs (run by .ci/run in a venv under target/).

NMEA 0183 with pynmea2 and u-blox UBX with pyubx2 likewise.

usage: cross_check.py mavlink|novatel|nmea|ubx FILE, or cross_check.py pack-hil-state N (frames
packed by pymavlink for our live MAVLink decoder)
"""
import sys


def mavlink(data):
    from pymavlink.dialects.v20 import common

    mav = common.MAVLink(None)
    mav.robust_parsing = True  # bad CRCs come out as BAD_DATA instead of raising
    for msg in mav.parse_buffer(data) or []:
        if msg.get_type() == "BAD_DATA":
            yield {"mavpackettype": "BAD_DATA"}
            continue
        d = msg.to_dict()
        d["seq"] = msg.get_seq()
        yield d


def novatel(data):
    from novatel_edie import oem

    parser = oem.Parser()
    parser.write(data)
    for msg in parser:
        if not hasattr(msg, "to_dict"):  # UnknownBytes: what EDIE could not frame or check
            yield {"name": type(msg).__name__}
            continue
        d = msg.to_dict()
        d["name"] = msg.name
        yield d


def nmea(data):
    import pynmea2

    for line in data.decode("ascii").splitlines():
        msg = pynmea2.parse(line, check=True)  # raises on a bad checksum
        d = {"type": msg.sentence_type}
        for name in msg.name_to_idx:
            d[name] = getattr(msg, name)
        for name in ("latitude", "longitude", "timestamp", "datestamp"):
            v = getattr(msg, name, None)
            if v is not None:
                d[name] = v.strftime("%H:%M:%S.%f") if name == "timestamp" else v
        yield {k: (v if isinstance(v, (int, float, str)) else str(v)) for k, v in d.items()}


def ubx(data):
    import io

    from pyubx2 import UBXReader

    for _raw, msg in UBXReader(io.BytesIO(data), protfilter=2):  # checks the checksums
        d = {k: v for k, v in vars(msg).items() if not k.startswith("_")}
        d["identity"] = msg.identity
        yield d


def pack_hil_state(n):
    """n HIL_STATE_QUATERNION frames packed by pymavlink (a yaw turn, drifting position and
    velocity; every fifth with zero airspeeds and accelerations, so MAVLink 2 truncates it),
    one line each: the frame's hex and the values given."""
    import math

    from pymavlink.dialects.v20 import common

    for k in range(int(n)):
        mav = common.MAVLink(None, srcSystem=1 + k % 3, srcComponent=1 + k % 7)
        mav.seq = k % 256
        a = 0.01 * k
        q = [math.cos(a / 2), 0.01 * math.sin(a), -0.02 * math.sin(a), math.sin(a / 2)]
        norm = math.sqrt(sum(x * x for x in q))
        q = [x / norm for x in q]
        rates = [0.01 * math.sin(0.1 * k), -0.02, 0.5 * math.cos(0.05 * k)]
        pos = [451000000 + 37 * k, -75000000 - 53 * k, 100000 + 250 * k]
        vel = [1000 + k, -200 - 3 * k, 30 - k]
        extra = [0, 0, 0, 0, 0] if k % 5 == 0 else [1500 + k, 1510 + k, 12 - k, -7, -1000 + k]
        t_us = 1_234_567 + 10_000 * k
        msg = common.MAVLink_hil_state_quaternion_message(t_us, q, *rates, *pos, *vel, *extra)
        buf = msg.pack(mav)
        yield {"hex": buf.hex(), "time_usec": t_us, "q": ",".join(map(repr, q)),
               "rates": ",".join(map(repr, rates)), "pos": ",".join(map(str, pos)),
               "vel": ",".join(map(str, vel)), "seq": k % 256}


def main():
    kind, path = sys.argv[1], sys.argv[2]
    if kind == "pack-hil-state":
        for d in pack_hil_state(path):
            print(";".join(f"{k}={v}" for k, v in d.items()))
        return
    with open(path, "rb") as f:
        data = f.read()
    for d in {"mavlink": mavlink, "novatel": novatel, "nmea": nmea, "ubx": ubx}[kind](data):
        print(";".join(f"{k}={v!r}" for k, v in d.items() if not isinstance(v, dict)))


if __name__ == "__main__":
    main()
