"""Helpers of the dynamixel_sdk scripts: a port, raw packets, their answers."""

import time

from dynamixel_sdk import PortHandler


def port(path, baud):
    p = PortHandler(path)
    assert p.openPort(), f"cannot open {path}"
    assert p.setBaudRate(baud), f"cannot set {baud} baud"
    return p


def raw(p, packet, wait=0.05):
    """Writes a packet as bytes; returns what comes back within `wait` seconds."""
    p.clearPort()
    p.writePort(bytes(packet))
    end = time.monotonic() + wait
    got = b""
    while time.monotonic() < end:
        got += bytes(p.readPort(256))
        time.sleep(0.002)
    return got


def v1_packet(dxl_id, instruction, params=()):
    body = [dxl_id, len(params) + 2, instruction, *params]
    return [0xFF, 0xFF, *body, (~sum(body)) & 0xFF]


def v1_status(data):
    """(id, error) of the first 1.0 status packet in `data`."""
    i = data.find(b"\xff\xff")
    if i < 0 or len(data) < i + 6:
        return None
    return data[i + 2], data[i + 4]


def v2_status(data):
    """(id, error) of the first 2.0 status packet in `data`."""
    i = data.find(b"\xff\xff\xfd\x00")
    if i < 0 or len(data) < i + 11:
        return None
    return data[i + 4], data[i + 8]
