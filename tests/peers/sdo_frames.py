"""python-canopen's own SDO client (RemoteNode) and server (LocalNode) of node 1, in one
process on a python-can virtual bus: the frames of the segmented transfers that
drivers/canopen/tests/sdo_golden.rs writes out by hand, as tests/tests/peers.rs compares
them with stride's. Each transfer is reported as a line

    trace NAME ID#DATA ID#DATA ...

(every frame on the bus, in order, the data as 16 hex digits) and checked for its result.

Usage: sdo_frames.py
"""

import can
import canopen
from canopen.objectdictionary import DOMAIN, VISIBLE_STRING, ODVariable

from check import Checks

c = Checks("python-canopen SDO frames")

DOWNLOADS = (
    ("download-10", b"0123456789"),
    ("download-7", b"ABCDEFG"),
    ("download-14", b"Harmonica Gold"),
    ("download-13", b"A long string"),
    ("download-0", b""),
)
UPLOADS = (
    ("upload-14", "Elmo Harmonica"),
    ("upload-26", "Tiny Node - Mega Domains !"),
)


def dictionary(name):
    od = canopen.ObjectDictionary()
    v = ODVariable("Manufacturer device name", 0x1008, 0)
    v.data_type = VISIBLE_STRING
    v.access_type = "ro"
    v.default = name
    od.add_object(v)
    v = ODVariable("Domain", 0x2000, 0)
    v.data_type = DOMAIN
    v.access_type = "rw"
    od.add_object(v)
    return od


def bus():
    return can.Bus(interface="virtual", channel="stride-sdo-frames")


tap = bus()


def frames():
    """Every frame on the bus since the last call."""
    out = []
    while (m := tap.recv(0.1)) is not None:
        out.append(f"{m.arbitration_id:03X}#{bytes(m.data).hex().upper()}")
    return out


def trace(name, lines):
    print(f"trace {name} {' '.join(lines)}", flush=True)


def transfers():
    for name, data in DOWNLOADS:
        client, server = canopen.Network(bus()), canopen.Network(bus())
        client.connect()
        server.connect()
        remote = client.add_node(canopen.RemoteNode(1, dictionary("")))
        local = server.add_node(canopen.LocalNode(1, dictionary("")))
        remote.sdo.download(0x2000, 0, data)
        trace(name, frames())
        c.equal(f"{name}: the LocalNode holds what was written", local.sdo.upload(0x2000, 0), data)
        client.disconnect()
        server.disconnect()
    for name, text in UPLOADS:
        client, server = canopen.Network(bus()), canopen.Network(bus())
        client.connect()
        server.connect()
        remote = client.add_node(canopen.RemoteNode(1, dictionary(text)))
        server.add_node(canopen.LocalNode(1, dictionary(text)))
        got = remote.sdo.upload(0x1008, 0)
        trace(name, frames())
        c.equal(f"{name}: the RemoteNode read the name", got, text.encode())
        client.disconnect()
        server.disconnect()


c.run("the transfers", transfers)
tap.shutdown()
c.done()
