"""An object dictionary for python-canopen of the objects a CiA 402 drive (and the fake
Elmo drive) has, laid out as CiA 301 and 402 prescribe: what a master reads and writes."""

import canopen
from canopen.objectdictionary import (
    ODRecord, ODVariable, UNSIGNED8, UNSIGNED16, UNSIGNED32, INTEGER8, INTEGER16,
    INTEGER32, VISIBLE_STRING,
)


def var(name, index, sub, kind, access="rw"):
    v = ODVariable(name, index, sub)
    v.data_type = kind
    v.access_type = access
    return v


def record(name, index, subs, cls=ODRecord):
    r = cls(name, index)
    for sub, (sub_name, kind, access) in subs.items():
        r.add_member(var(sub_name, index, sub, kind, access))
    return r


def dictionary():
    od = canopen.ObjectDictionary()
    od.add_object(var("Device type", 0x1000, 0, UNSIGNED32, "ro"))
    od.add_object(var("Error register", 0x1001, 0, UNSIGNED8, "ro"))
    od.add_object(var("Manufacturer device name", 0x1008, 0, VISIBLE_STRING, "ro"))
    od.add_object(var("Producer heartbeat time", 0x1017, 0, UNSIGNED16))
    od.add_object(record("Identity", 0x1018, {
        0: ("Highest sub-index", UNSIGNED8, "ro"),
        1: ("Vendor", UNSIGNED32, "ro"),
        2: ("Product", UNSIGNED32, "ro"),
        3: ("Revision", UNSIGNED32, "ro"),
        4: ("Serial", UNSIGNED32, "ro"),
    }))
    for n in range(4):
        for base, kind in ((0x1400, "RPDO"), (0x1800, "TPDO")):
            od.add_object(record(f"{kind} {n + 1} communication", base + n, {
                0: ("Highest sub-index", UNSIGNED8, "ro"),
                1: ("COB-ID", UNSIGNED32, "rw"),
                2: ("Transmission type", UNSIGNED8, "rw"),
            }))
        for base, kind in ((0x1600, "RPDO"), (0x1A00, "TPDO")):
            subs = {0: ("Number of mapped objects", UNSIGNED8, "rw")}
            subs.update({s: (f"Mapped object {s}", UNSIGNED32, "rw") for s in range(1, 9)})
            od.add_object(record(f"{kind} {n + 1} mapping", base + n, subs))
    od.add_object(var("Abort connection option code", 0x6007, 0, INTEGER16))
    od.add_object(var("Controlword", 0x6040, 0, UNSIGNED16))
    od.add_object(var("Statusword", 0x6041, 0, UNSIGNED16, "ro"))
    od.add_object(var("Modes of operation", 0x6060, 0, INTEGER8))
    od.add_object(var("Modes of operation display", 0x6061, 0, INTEGER8, "ro"))
    od.add_object(var("Position actual value", 0x6064, 0, INTEGER32, "ro"))
    od.add_object(var("Following error window", 0x6065, 0, UNSIGNED32))
    od.add_object(var("Velocity actual value", 0x606C, 0, INTEGER32, "ro"))
    od.add_object(var("Target position", 0x607A, 0, INTEGER32))
    od.add_object(var("Profile velocity", 0x6081, 0, UNSIGNED32))
    od.add_object(var("Profile acceleration", 0x6083, 0, UNSIGNED32))
    od.add_object(var("Profile deceleration", 0x6084, 0, UNSIGNED32))
    od.add_object(var("Quick stop deceleration", 0x6085, 0, UNSIGNED32))
    od.add_object(var("Unknown to the drive", 0x2222, 0, UNSIGNED16))
    return od
