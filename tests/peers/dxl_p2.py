"""ROBOTIS's dynamixel_sdk, Protocol 2.0, against a fake chain of 6 XM430-W350 at 1 Mbit/s
(fake-dynamixel-chain --model XM430-W350 --ids 1-6).

Usage: dxl_p2.py PTY
"""

import sys
import time

from dynamixel_sdk import (
    COMM_RX_TIMEOUT, COMM_SUCCESS, GroupBulkRead, GroupBulkWrite, GroupSyncRead, GroupSyncWrite,
    PacketHandler,
)

from check import Checks, wait_for
from dxl import port, raw, v2_status

c = Checks("dynamixel_sdk protocol 2.0")
p = port(sys.argv[1], 1_000_000)
ph = PacketHandler(2.0)
TORQUE, GOAL, POSITION, DELAY, MAX_LIMIT, WATCHDOG, BAUD = 64, 116, 132, 9, 48, 98, 8


def basics():
    c.equal("ping 1: model 1020", ph.ping(p, 1), (1020, COMM_SUCCESS, 0))
    found, result = ph.broadcastPing(p)
    c.check("a broadcast ping finds all six", result == COMM_SUCCESS and sorted(found) == list(range(1, 7))
            and all(v == [1020, 46] for v in found.values()), found)
    c.equal("the baud-rate item says 1 Mbit/s (3)", ph.read1ByteTxRx(p, 1, BAUD)[0], 3)
    ph.write1ByteTxRx(p, 1, TORQUE, 1)
    ph.write4ByteTxRx(p, 1, GOAL, 2500)
    c.check("a goal is reached", wait_for(lambda: ph.read4ByteTxRx(p, 1, POSITION)[0] == 2500, 2.0))
    c.equal("an EEPROM write with the torque on: error 7", ph.write1ByteTxRx(p, 1, DELAY, 10)[1], 7)
    c.equal("a goal past the limit: error 6", ph.write4ByteTxRx(p, 1, GOAL, 5000)[1], 6)
    c.equal("a write to a read-only item: error 7", ph.write4ByteTxRx(p, 1, POSITION, 5)[1], 7)
    c.equal("2 bytes into the 4-byte goal: error 5", ph.write2ByteTxRx(p, 1, GOAL, 100)[1], 5)


def groups():
    sw = GroupSyncWrite(p, ph, GOAL, 4)
    for i in range(2, 7):
        ph.write1ByteTxRx(p, i, TORQUE, 1)
        sw.addParam(i, list((2100).to_bytes(4, "little")))
    c.equal("a sync write of goals", sw.txPacket(), COMM_SUCCESS)
    time.sleep(0.2)
    sr = GroupSyncRead(p, ph, POSITION, 4)
    for i in range(1, 7):
        sr.addParam(i)
    c.equal("a sync read of six positions", sr.txRxPacket(), COMM_SUCCESS)
    c.check("each position read", all(sr.isAvailable(i, POSITION, 4) for i in range(1, 7))
            and all(sr.getData(i, POSITION, 4) == 2100 for i in range(2, 7)),
            [sr.getData(i, POSITION, 4) for i in range(1, 7)])
    br = GroupBulkRead(p, ph)
    br.addParam(1, POSITION, 4)
    br.addParam(2, 144, 2)  # voltage
    br.addParam(3, 146, 1)  # temperature
    br.addParam(4, 70, 1)  # hardware error status
    c.equal("a bulk read", br.txRxPacket(), COMM_SUCCESS)
    c.equal("its values", (br.getData(1, POSITION, 4), br.getData(2, 144, 2), br.getData(3, 146, 1), br.getData(4, 70, 1)),
            (2500, 120, 32, 0))
    bw = GroupBulkWrite(p, ph)
    bw.addParam(5, 65, 1, [1])  # LED
    bw.addParam(6, GOAL, 4, list((2000).to_bytes(4, "little")))
    c.equal("a bulk write", bw.txPacket(), COMM_SUCCESS)
    c.equal("it wrote", (ph.read1ByteTxRx(p, 5, 65)[0], ph.read4ByteTxRx(p, 6, GOAL)[0]), (1, 2000))


def resets():
    for i in range(1, 7):
        ph.write1ByteTxRx(p, i, TORQUE, 0)
    ph.write1ByteTxRx(p, 2, DELAY, 10)
    ph.write4ByteTxRx(p, 2, MAX_LIMIT, 3000)
    c.equal("a reboot is answered", ph.reboot(p, 2)[0], COMM_SUCCESS)
    time.sleep(0.05)
    c.equal("a reboot keeps the EEPROM", (ph.read1ByteTxRx(p, 2, DELAY)[0], ph.read4ByteTxRx(p, 2, MAX_LIMIT)[0]), (10, 3000))
    for i in (3, 4, 5):
        ph.write1ByteTxRx(p, i, DELAY, 10)
    # A broadcast reset of everything is ignored (X firmware from v42).
    ph.factoryReset(p, 0xFE, 0xFF)
    time.sleep(0.05)
    c.equal("a broadcast reset-all is ignored", [ph.read1ByteTxRx(p, i, DELAY)[0] for i in (3, 4, 5)], [10, 10, 10])
    c.equal("reset 0x02 answered", ph.factoryReset(p, 3, 0x02)[0], COMM_SUCCESS)
    time.sleep(0.05)
    c.equal("0x02 keeps the id and the baud rate", (ph.read1ByteTxRx(p, 3, DELAY)[0], ph.read1ByteTxRx(p, 3, BAUD)[0]), (250, 3))
    ph.factoryReset(p, 4, 0x01)
    time.sleep(0.05)
    c.equal("0x01 keeps the id only", ph.read1ByteTxRx(p, 4, BAUD)[0], 1)
    ph.factoryReset(p, 5, 0xFF)
    time.sleep(0.05)
    c.equal("0xFF resets the id too", ph.ping(p, 5)[1], COMM_RX_TIMEOUT)


def bad_packets():
    got = raw(p, [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01, 0x19, 0x4F])  # ping 1, bad CRC
    s = v2_status(got)
    c.check("a bad CRC is answered with error 3", s is not None and s[0] == 1 and s[1] & 0x7F == 3, got.hex())
    # An unknown instruction (0x7F) to servo 6, with its CRC.
    from dynamixel_sdk.protocol2_packet_handler import Protocol2PacketHandler
    pkt = [0xFF, 0xFF, 0xFD, 0x00, 6, 3, 0, 0x7F, 0, 0]
    crc = Protocol2PacketHandler().updateCRC(0, pkt, len(pkt) - 2)
    pkt[-2:] = [crc & 0xFF, crc >> 8]
    got = raw(p, pkt)
    s = v2_status(got)
    c.check("an unknown instruction is answered with error 2", s is not None and s[0] == 6 and s[1] & 0x7F == 2, got.hex())


def watchdog():
    ph.write1ByteTxRx(p, 6, TORQUE, 1)
    c.equal("the bus watchdog (98) set to 100 ms", ph.write1ByteTxRx(p, 6, WATCHDOG, 5)[1], 0)
    ph.write4ByteTxRx(p, 6, GOAL, 4000)
    time.sleep(0.3)  # quiet: the servo stops on its own
    value, result, _ = ph.read1ByteTxRx(p, 6, WATCHDOG)
    c.equal("it tripped (-1)", (result, value), (COMM_SUCCESS, 0xFF))
    pos = ph.read4ByteTxRx(p, 6, POSITION)[0]
    c.check("the servo stopped short of its goal", pos < 3900, pos)
    c.equal("goals refused while it is tripped", ph.write4ByteTxRx(p, 6, GOAL, 2048)[1], 7)
    ph.write1ByteTxRx(p, 6, WATCHDOG, 0)
    c.equal("cleared by writing 0", ph.write4ByteTxRx(p, 6, GOAL, 2048)[1], 0)


for name, fn in (("basics", basics), ("groups", groups), ("resets", resets), ("bad packets", bad_packets),
                 ("watchdog", watchdog)):
    c.run(name, fn)
p.closePort()
c.done()
