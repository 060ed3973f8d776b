"""ROBOTIS's dynamixel_sdk, Protocol 1.0, against a fake chain of 18 AX-12A at 1 Mbit/s
(fake-dynamixel-chain --model AX-12A --ids 1-18).

Usage: dxl_p1.py PTY
"""

import sys
import time

from dynamixel_sdk import COMM_SUCCESS, COMM_RX_TIMEOUT, GroupSyncWrite, PacketHandler

from check import Checks, wait_for
from dxl import port, raw, v1_packet, v1_status

c = Checks("dynamixel_sdk protocol 1.0")
p = port(sys.argv[1], 1_000_000)
ph = PacketHandler(1.0)
GOAL, SPEED, POSITION, TORQUE = 30, 32, 36, 24


def basics():
    models = [ph.ping(p, i) for i in range(1, 19)]
    c.check("ping 1..18: model 12 each", all(m == (12, COMM_SUCCESS, 0) for m in models), models)
    c.equal("ping 19: nobody", ph.ping(p, 19)[1], COMM_RX_TIMEOUT)
    c.equal("present temperature, voltage, position", (ph.read1ByteTxRx(p, 1, 43)[0], ph.read1ByteTxRx(p, 1, 42)[0],
            ph.read2ByteTxRx(p, 1, POSITION)[0]), (32, 120, 512))
    c.equal("the baud-rate item says 1 Mbit/s (1)", ph.read1ByteTxRx(p, 1, 4)[0], 1)
    ph.write1ByteTxRx(p, 1, TORQUE, 1)
    ph.write2ByteTxRx(p, 1, GOAL, 600)
    c.check("a goal is reached", wait_for(lambda: ph.read2ByteTxRx(p, 1, POSITION)[0] == 600, 2.0),
            ph.read2ByteTxRx(p, 1, POSITION))
    # The CW angle limit at 300: a goal of 100 is an angle-limit error (bit 1).
    ph.write1ByteTxRx(p, 2, TORQUE, 0)
    ph.write2ByteTxRx(p, 2, 6, 300)
    c.equal("a goal past the angle limit", ph.write2ByteTxRx(p, 2, GOAL, 100)[1] & 0x02, 0x02)
    c.equal("a goal past the range (1024)", ph.write2ByteTxRx(p, 3, GOAL, 1024)[1] & 0x08, 0x08)


def groups():
    sw = GroupSyncWrite(p, ph, GOAL, 2)
    for i in range(1, 19):
        sw.addParam(i, [0x20, 0x02])  # 544
    c.equal("a sync write of 18 goals", sw.txPacket(), COMM_SUCCESS)
    c.check("every goal reads back", all(ph.read2ByteTxRx(p, i, GOAL)[0] == 544 for i in range(4, 19)))
    sw = GroupSyncWrite(p, ph, GOAL, 4)
    for i in range(4, 19):
        sw.addParam(i, [0x00, 0x02, 0x64, 0x00])  # goal 512, speed 100
    sw.txPacket()
    c.check("a 4-byte sync write (goal and speed)", all(ph.read2ByteTxRx(p, i, SPEED)[0] == 100 for i in range(4, 19)))


def registered():
    c.equal("REG_WRITE answered", ph.regWriteTxRx(p, 5, GOAL, 2, [0x20, 0x02])[0], COMM_SUCCESS)
    c.equal("the registered item (44) is 1", ph.read1ByteTxRx(p, 5, 44)[0], 1)
    ph.action(p, 0xFE)
    time.sleep(0.02)
    c.equal("ACTION applies it, registered back to 0", (ph.read2ByteTxRx(p, 5, GOAL)[0], ph.read1ByteTxRx(p, 5, 44)[0]),
            (544, 0))


def resets():
    ph.write1ByteTxRx(p, 6, 5, 10)  # return delay
    ph.write2ByteTxRx(p, 6, 8, 900)  # CCW limit
    got = raw(p, v1_packet(6, 0x08))  # REBOOT (the SDK has none for 1.0)
    c.check("a reboot is answered", v1_status(got) == (6, 0), got.hex())
    c.equal("a reboot keeps the EEPROM", (ph.read1ByteTxRx(p, 6, 5)[0], ph.read2ByteTxRx(p, 6, 8)[0]), (10, 900))
    c.equal("factory reset of 18 answered", ph.factoryReset(p, 18)[0], COMM_SUCCESS)
    time.sleep(0.05)
    c.equal("after it, 18 is id 1", ph.ping(p, 18)[1], COMM_RX_TIMEOUT)


def bad_packets():
    got = raw(p, [0xFF, 0xFF, 0x07, 0x02, 0x01, 0x00])  # ping 7, bad checksum (F5)
    s = v1_status(got)
    c.check("a bad checksum is answered with the checksum bit", s is not None and s[0] == 7 and s[1] & 0x10, got.hex())
    got = raw(p, v1_packet(8, 0x7F))
    s = v1_status(got)
    c.check("an unknown instruction gets the instruction bit", s is not None and s[0] == 8 and s[1] & 0x40, got.hex())


def status_level():
    ph.write1ByteTxRx(p, 9, 16, 1)
    c.equal("status return level 1: a write is not answered", ph.write1ByteTxRx(p, 9, 25, 1)[0], COMM_RX_TIMEOUT)
    c.equal("a read is", ph.read1ByteTxRx(p, 9, 25)[1], COMM_SUCCESS)


for name, fn in (("basics", basics), ("groups", groups), ("registered", registered), ("resets", resets),
                 ("bad packets", bad_packets), ("status level", status_level)):
    c.run(name, fn)
p.closePort()
c.done()
