#!/usr/bin/env python3
"""Decode an imu-emu frame stream with another party's decoder and print one line per frame,
`key=value;key=value;…` (floats as Python's shortest round-trip repr, nested header left out): MAVLink with pymavlink, NovAtel RAWIMUSXB with NovAtel EDIE (novatel_edie). Used by
tests/external_decoders.rs (run by .ci/run in a venv under target/).

NMEA 0183 with pynmea2 and u-blox UBX with pyubx2 likewise.

usage: cross_check.py mavlink|novatel|nmea|ubx FILE
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


def main():
    kind, path = sys.argv[1], sys.argv[2]
    with open(path, "rb") as f:
        data = f.read()
    for d in {"mavlink": mavlink, "novatel": novatel, "nmea": nmea, "ubx": ubx}[kind](data):
        print(";".join(f"{k}={v!r}" for k, v in d.items() if not isinstance(v, dict)))


if __name__ == "__main__":
    main()
