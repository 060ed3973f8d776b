"""python-can's slcan interface against the fake dongle (fake-can-rig --echo --nodes '').

Usage: slcan_pycan.py PTY
"""

import sys
import time

import can

from check import Checks, wait_for

PTY = sys.argv[1]
c = Checks("python-can slcan")


def bus(**kw):
    kw.setdefault("bitrate", 1_000_000)
    return can.interface.Bus(interface="slcan", channel=PTY, sleep_after_open=0.1, **kw)


def answer(b, want_id, timeout=1.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        m = b.recv(timeout=0.05)
        if m is not None and m.arbitration_id == want_id:
            return m
    return None


def frames():
    b = bus()
    try:
        hw, sw = b.get_version(1.0)
        c.equal("get_version", (hw, sw), (10, 13))
        c.equal("get_serial_number", b.get_serial_number(1.0), "F4KE")
        b.send(can.Message(arbitration_id=0x6A0, data=[1, 2, 3, 4, 5, 6, 7, 8], is_extended_id=False))
        m = answer(b, 0x6A1)
        c.check("a standard 8-byte frame out and back", m is not None and list(m.data) == list(range(1, 9)), m)
        b.send(can.Message(arbitration_id=0x1ABCDE00, data=[0xDE, 0xAD, 0xBE, 0xEF], is_extended_id=True))
        m = answer(b, 0x1ABCDE01)
        c.check("an extended frame out and back", m is not None and m.is_extended_id and bytes(m.data) == b"\xde\xad\xbe\xef", m)
        b.send(can.Message(arbitration_id=0x6A4, data=[], is_extended_id=False))
        m = answer(b, 0x6A5)
        c.check("a frame of no data", m is not None and len(m.data) == 0, m)
        b.send(can.Message(arbitration_id=0x6B0, is_remote_frame=True, dlc=5, is_extended_id=False))
        m = answer(b, 0x6B0)
        c.check("a remote request answered with its length", m is not None and not m.is_remote_frame and list(m.data) == [0, 1, 2, 3, 4], m)
        b.send(can.Message(arbitration_id=0x1ABCDF00, is_remote_frame=True, dlc=3, is_extended_id=True))
        m = answer(b, 0x1ABCDF00)
        c.check("an extended remote request", m is not None and list(m.data) == [0, 1, 2], m)
        # A paced burst of 100 comes back whole and in order.
        for i in range(100):
            b.send(can.Message(arbitration_id=0x6A2, data=[i], is_extended_id=False))
            time.sleep(0.001)
        got = []
        end = time.monotonic() + 3
        while len(got) < 100 and time.monotonic() < end:
            m = b.recv(timeout=0.05)
            if m is not None and m.arbitration_id == 0x6A3:
                got.append(m.data[0])
        c.equal("a paced burst of 100 comes back in order", got, list(range(100)))
    finally:
        b.shutdown()


def listen_only():
    b = bus(listen_only=True)
    try:
        b.send(can.Message(arbitration_id=0x6A6, data=[9], is_extended_id=False))
        m = answer(b, 0x6A7, timeout=0.5)
        c.check("listen-only does not transmit", m is None, m)
    finally:
        b.shutdown()


def btr():
    # 1 Mbit/s on the SJA1000's 8 MHz clock: BTR0 0x00, BTR1 0x14.
    t = can.BitTiming(f_clock=8_000_000, brp=1, tseg1=5, tseg2=2, sjw=1)
    b = can.interface.Bus(interface="slcan", channel=PTY, timing=t, sleep_after_open=0.1)
    try:
        b.send(can.Message(arbitration_id=0x6A8, data=[7], is_extended_id=False))
        m = answer(b, 0x6A9)
        c.check("a bit rate set by BTR opens and carries frames", m is not None, m)
    finally:
        b.shutdown()


c.run("frames", frames)
c.run("listen-only", listen_only)
c.run("BTR", btr)
c.done()
