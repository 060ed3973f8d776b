//! The fake drive's object dictionary: what exists, who may read and write it, what may be
//! mapped into a PDO, and (through [`Served`], what the SDO server writes through) what a
//! write does to the drive.

use std::collections::BTreeMap;
use std::time::Instant;

use stride_canopen::ds402;
use stride_canopen::elmo::{PT_OBJECT, PVT_OBJECT, READ_POINTER, WRITE_POINTER};
use stride_canopen::frame::{CobId, Function, NodeId};
use stride_canopen::heartbeat;
use stride_canopen::nmt;
use stride_canopen::sdo::{AbortCode, Dictionary};

use super::FakeElmo;

/// Who may do what with an object.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Access {
    /// Read only.
    Ro,
    /// Read and write.
    Rw,
    /// Write only.
    Wo,
}

/// One object (index, sub-index) of the dictionary.
#[derive(Debug, Clone)]
pub(super) struct Entry {
    pub access: Access,
    pub value: Vec<u8>,
    /// May be mapped into a PDO.
    pub mappable: bool,
}

/// The object dictionary.
#[derive(Debug, Clone)]
pub(super) struct Od {
    entries: BTreeMap<(u16, u8), Entry>,
}

pub(super) fn le(v: i64, bytes: usize) -> Vec<u8> {
    v.to_le_bytes()[..bytes].to_vec()
}

/// The communication area of CiA 301: objects 0x1000 to 0x1FFF.
pub(super) fn communication(index: u16) -> bool {
    (0x1000..0x2000).contains(&index)
}

impl Od {
    /// The dictionary at power-on.
    pub fn new(node: NodeId, following_error_window: u32) -> Od {
        use Access::*;
        let mut od = Od {
            entries: BTreeMap::new(),
        };
        let mut put = |i: u16, s: u8, access: Access, value: Vec<u8>, mappable: bool| {
            od.entries.insert(
                (i, s),
                Entry {
                    access,
                    value,
                    mappable,
                },
            );
        };
        put(0x1000, 0, Ro, le(0x0002_0192, 4), false);
        put(0x1001, 0, Ro, vec![0], true);
        put(0x1008, 0, Ro, b"Elmo Gold Twitter (fake)".to_vec(), false);
        // The consumer heartbeat: one entry, unused at power-on.
        put(heartbeat::CONSUMER_TIME, 0, Ro, vec![1], false);
        put(heartbeat::CONSUMER_TIME, 1, Rw, le(0, 4), false);
        put(heartbeat::PRODUCER_TIME, 0, Rw, le(0, 2), false);
        // Identity: vendor, product, revision, serial.
        put(0x1018, 0, Ro, vec![4], false);
        put(0x1018, 1, Ro, le(0x9a, 4), false);
        put(0x1018, 2, Ro, le(0x0002_0192, 4), false);
        put(0x1018, 3, Ro, le(0x0001_0110, 4), false);
        put(0x1018, 4, Ro, le(node.get() as i64 + 0x1000, 4), false);
        // Error behaviour on a communication error: to pre-operational.
        put(nmt::ERROR_BEHAVIOUR, 0, Ro, vec![1], false);
        put(nmt::ERROR_BEHAVIOUR, 1, Rw, vec![0], false);
        for n in 1..=4u8 {
            let i = (n - 1) as u16;
            let rx = CobId::of(Function::Rpdo(n), node).raw() as i64;
            let tx = CobId::of(Function::Tpdo(n), node).raw() as i64;
            // Communication records: COB-ID and transmission type.
            put(0x1400 + i, 0, Ro, vec![2], false);
            put(0x1400 + i, 1, Rw, le(rx, 4), false);
            put(0x1400 + i, 2, Rw, vec![255], false);
            put(0x1800 + i, 0, Ro, vec![2], false);
            put(
                0x1800 + i,
                1,
                Rw,
                le(tx | if n > 2 { 0x8000_0000 } else { 0 }, 4),
                false,
            );
            put(0x1800 + i, 2, Rw, vec![if n == 1 { 1 } else { 255 }], false);
            // Mapping records: a count and eight entries.
            put(0x1600 + i, 0, Rw, vec![0], false);
            put(0x1a00 + i, 0, Rw, vec![0], false);
            for s in 1..=8 {
                put(0x1600 + i, s, Rw, le(0, 4), false);
                put(0x1a00 + i, s, Rw, le(0, 4), false);
            }
        }
        // RPDO1 = controlword, RPDO2 = the interpreter, TPDO1 = statusword + actual position
        // (Elmo-like defaults).
        put(0x1600, 0, Rw, vec![1], false);
        put(0x1600, 1, Rw, le(0x6040_0010, 4), false);
        put(0x1a00, 0, Rw, vec![2], false);
        put(0x1a00, 1, Rw, le(0x6041_0010, 4), false);
        put(0x1a00, 2, Rw, le(0x6064_0020, 4), false);
        put(ds402::ABORT_CONNECTION_OPTION, 0, Rw, le(1, 2), false);
        put(ds402::CONTROLWORD, 0, Rw, le(0, 2), true);
        put(ds402::STATUSWORD, 0, Ro, le(0, 2), true);
        put(ds402::QUICK_STOP_OPTION, 0, Rw, le(2, 2), false);
        put(ds402::MODES_OF_OPERATION, 0, Rw, vec![0], true);
        put(ds402::MODES_DISPLAY, 0, Ro, vec![0], true);
        put(ds402::POSITION_ACTUAL, 0, Ro, le(0, 4), true);
        put(ds402::VELOCITY_ACTUAL, 0, Ro, le(0, 4), true);
        put(ds402::TARGET_POSITION, 0, Rw, le(0, 4), true);
        put(ds402::FOLLOWING_ERROR, 0, Ro, le(0, 4), true);
        put(
            ds402::FOLLOWING_ERROR_WINDOW,
            0,
            Rw,
            le(following_error_window as i64, 4),
            false,
        );
        put(
            ds402::QUICK_STOP_DECELERATION,
            0,
            Rw,
            le(2_000_000, 4),
            false,
        );
        put(ds402::PROFILE_VELOCITY, 0, Rw, le(100_000, 4), false);
        put(ds402::PROFILE_ACCELERATION, 0, Rw, le(1_000_000, 4), false);
        put(ds402::PROFILE_DECELERATION, 0, Rw, le(1_000_000, 4), false);
        put(ds402::IP_SUBMODE, 0, Rw, le(0, 2), false);
        put(ds402::IP_PERIOD, 0, Ro, vec![2], false);
        put(ds402::IP_PERIOD, 1, Rw, vec![10], false);
        put(ds402::IP_PERIOD, 2, Rw, vec![(-3i8) as u8], false);
        put(ds402::IP_DATA, 0, Ro, vec![1], false);
        put(ds402::IP_DATA, 1, Rw, le(0, 4), true);
        put(PVT_OBJECT, 0, Wo, le(0, 8), true);
        put(PT_OBJECT, 0, Wo, le(0, 8), true);
        put(WRITE_POINTER, 0, Ro, le(1, 2), true);
        put(READ_POINTER, 0, Ro, le(1, 2), true);
        od
    }

    /// Puts the communication area (0x1000..0x1FFF) back to its power-on values (NMT reset
    /// communication), the rest as it is.
    pub fn reset_communication(&mut self, node: NodeId, following_error_window: u32) {
        let fresh = Od::new(node, following_error_window);
        self.entries.retain(|(i, _), _| !communication(*i));
        self.entries.extend(
            fresh
                .entries
                .into_iter()
                .filter(|((i, _), _)| communication(*i)),
        );
    }

    /// The entry, or the abort its absence earns: no sub-index of an object that exists, no
    /// object otherwise.
    pub fn entry(&self, index: u16, sub: u8) -> Result<&Entry, AbortCode> {
        self.entries.get(&(index, sub)).ok_or_else(|| {
            if self
                .entries
                .range((index, 0)..=(index, 255))
                .next()
                .is_some()
            {
                AbortCode::NO_SUBINDEX
            } else {
                AbortCode::NO_OBJECT
            }
        })
    }

    /// The object as an unsigned number (0 when absent).
    pub fn get_u(&self, i: u16, s: u8) -> u64 {
        let Some(e) = self.entries.get(&(i, s)) else {
            return 0;
        };
        let v = &e.value;
        let mut b = [0u8; 8];
        b[..v.len().min(8)].copy_from_slice(&v[..v.len().min(8)]);
        u64::from_le_bytes(b)
    }

    /// Sets an object's value as the drive does (no access check), truncated to its size.
    pub fn set_raw(&mut self, i: u16, s: u8, v: i64) {
        if let Some(e) = self.entries.get_mut(&(i, s)) {
            let n = e.value.len();
            e.value = le(v, n);
        }
    }

    /// Stores `data` in an object (no checks).
    pub fn store(&mut self, i: u16, s: u8, data: &[u8]) {
        if let Some(e) = self.entries.get_mut(&(i, s)) {
            e.value = data.to_vec();
        }
    }
}

/// The drive as the SDO server sees it: reads answer from the dictionary, writes go through
/// the drive's checks and side effects.
pub(super) struct Served<'a> {
    pub drive: &'a mut FakeElmo,
    pub now: Instant,
}

impl Dictionary for Served<'_> {
    fn upload(&mut self, index: u16, sub: u8) -> Result<Vec<u8>, AbortCode> {
        let e = self.drive.od.entry(index, sub)?;
        if e.access == Access::Wo {
            return Err(AbortCode::WRITE_ONLY);
        }
        Ok(e.value.clone())
    }

    fn may_download(&mut self, index: u16, sub: u8, _size: Option<u32>) -> Result<(), AbortCode> {
        match self.drive.od.entry(index, sub)?.access {
            Access::Ro => Err(AbortCode::READ_ONLY),
            _ => Ok(()),
        }
    }

    fn download(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.drive.write_object(index, sub, data, self.now)
    }
}

impl FakeElmo {
    /// Writes an object from the bus (SDO or RPDO): access, length and the PDO rules
    /// checked, then the drive's side effects.
    pub(super) fn write_object(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
        now: Instant,
    ) -> Result<(), AbortCode> {
        let e = self.od.entry(index, sub)?;
        if e.access == Access::Ro {
            return Err(AbortCode::READ_ONLY);
        }
        if index != 0x1008 && data.len() != e.value.len() {
            return Err(AbortCode::LENGTH_MISMATCH);
        }
        self.check_pdo_write(index, sub, data)?;
        self.od.store(index, sub, data);
        self.after_write(index, sub, data, now);
        Ok(())
    }
}
