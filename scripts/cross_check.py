#!/usr/bin/env python3
"""Decode an imu-emu frame stream with another party's decoder and print one line per frame,
`key=value;key=value;…` (floats as Python's shortest round-trip repr, nested header left out): MAVLink with pymavlink, NovAtel RAWIMUSXB with NovAtel EDIE (novatel_edie). Used by
tests/external_decoders.rs (run by .ci/run in a venv under target/).

usage: cross_check.py mavlink|novatel FILE
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


def main():
    kind, path = sys.argv[1], sys.argv[2]
    with open(path, "rb") as f:
        data = f.read()
    for d in {"mavlink": mavlink, "novatel": novatel}[kind](data):
        print(";".join(f"{k}={v!r}" for k, v in d.items() if not isinstance(v, dict)))


if __name__ == "__main__":
    main()
