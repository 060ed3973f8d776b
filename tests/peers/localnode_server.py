"""A third-party CANopen server for the project's host side: python-canopen's LocalNode
(node 5, a CiA 402 device's dictionary) on a python-can virtual bus, reached through a small
Lawicel (SLCAN) device on a pseudo-terminal. It writes the terminal's path to PTY_FILE and
serves until it is killed.

Usage: localnode_server.py PTY_FILE
"""

import os
import sys
import threading

import can
import canopen
from canopen.objectdictionary import DOMAIN, UNSIGNED8, UNSIGNED16, UNSIGNED32, ODVariable

from od_elmo import dictionary, record, var

od = dictionary()
del od[0x2222]
for obj, value in ((0x1000, 0x00020192), (0x1017, 0), (0x1018, None), (0x6065, 20_000)):
    if value is not None:
        od[obj].default = value
od[0x1008].default = "python-canopen LocalNode"
od[0x1018][0].default = 4
od[0x1018][1].default = 0x9A
for n in range(4):
    for base in (0x1400, 0x1800):
        od[base + n][0].default = 2
        od[base + n][1].default = (0x200 if base == 0x1400 else 0x180) + 0x100 * n + 5
        od[base + n][2].default = 255
    for base in (0x1600, 0x1A00):
        od[base + n][0].default = 0
        for s in range(1, 9):
            od[base + n][s].default = 0
od.add_object(record("Consumer heartbeat time", 0x1016, {
    0: ("Number of entries", UNSIGNED8, "ro"), 1: ("Consumer 1", UNSIGNED32, "rw")}))
od[0x1016][0].default = 1
od[0x1016][1].default = 0
od.add_object(record("Error behaviour", 0x1029, {
    0: ("Number of entries", UNSIGNED8, "ro"), 1: ("Communication error", UNSIGNED8, "rw")}))
od[0x1029][0].default = 1
od[0x1029][1].default = 0
od[0x6007].default = 1
od[0x6085].default = 1_000_000
od.add_object(var("PVT data", 0x2001, 0, UNSIGNED32, "wo"))
od.add_object(var("Read pointer", 0x2F12, 0, UNSIGNED16, "ro"))
od[0x2F12].default = 1
blob = ODVariable("A domain", 0x2500, 0)
blob.data_type = DOMAIN
blob.access_type = "rw"
od.add_object(blob)

bus = can.interface.Bus(interface="virtual", channel="localnode", receive_own_messages=False)
net = canopen.Network(bus)
net.connect = lambda *a, **k: None
node = canopen.LocalNode(5, od)
net.add_node(node)
node.sdo[0x2500].raw = b""
notifier = can.Notifier(bus, net.listeners, 0.1)
net.notifier = notifier
wire = can.interface.Bus(interface="virtual", channel="localnode", receive_own_messages=False)

master, slave = os.openpty()
with open(sys.argv[1], "w") as f:
    f.write(os.ttyname(slave))
opened = False
lock = threading.Lock()


def send(line):
    with lock:
        os.write(master, line.encode() + b"\r")


def bel():
    with lock:
        os.write(master, b"\x07")


def to_host():
    while True:
        m = wire.recv(0.1)
        if m is None or not opened:
            continue
        kind = ("R" if m.is_remote_frame else "T") if m.is_extended_id else ("r" if m.is_remote_frame else "t")
        ident = f"{m.arbitration_id:08X}" if m.is_extended_id else f"{m.arbitration_id:03X}"
        data = "" if m.is_remote_frame else bytes(m.data).hex().upper()
        send(f"{kind}{ident}{m.dlc}{data}")


threading.Thread(target=to_host, daemon=True).start()
buf = b""
while True:
    chunk = os.read(master, 256)
    if not chunk:
        break
    buf += chunk
    while b"\r" in buf:
        line, buf = buf.split(b"\r", 1)
        line = line.decode(errors="replace")
        if line == "":
            send("")
        elif line == "C":
            (send("") if opened else bel())
            opened = False
        elif line.startswith("S") or line.startswith("s"):
            send("") if not opened else bel()
        elif line in ("O", "L"):
            if opened:
                bel()
            else:
                opened = True
                send("")
        elif line[0] in "tTrR" and opened:
            ext = line[0] in "TR"
            n = 8 if ext else 3
            ident = int(line[1:1 + n], 16)
            dlc = int(line[1 + n])
            remote = line[0] in "rR"
            data = b"" if remote else bytes.fromhex(line[2 + n:2 + n + 2 * dlc])
            wire.send(can.Message(arbitration_id=ident, is_extended_id=ext, is_remote_frame=remote, dlc=dlc, data=data))
            send("Z" if ext else "z")
        elif line == "V":
            send("V1013")
        elif line == "N":
            send("NLOCL")
        elif line == "F" and opened:
            send("F00")
        else:
            bel()
