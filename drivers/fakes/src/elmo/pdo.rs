//! The fake drive's PDOs: mapping as CiA 301 rules it, transmit PDOs on SYNC, receive PDOs
//! written into the dictionary.

use std::time::Instant;

use stride_canbus::CanFrame;
use stride_canopen::elmo::{PT_OBJECT, PVT_OBJECT};
use stride_canopen::emcy::Emcy;
use stride_canopen::pdo::{Direction, MapEntry, PdoConfig};
use stride_canopen::sdo::AbortCode;

use super::FakeElmo;

/// The PDO a communication (0x1400/0x1800) or mapping (0x1600/0x1A00) index belongs to.
fn pdo_of(index: u16) -> Option<(Direction, u8, bool)> {
    let (direction, base, comm) = match index {
        0x1400..=0x1403 => (Direction::Receive, 0x1400, true),
        0x1600..=0x1603 => (Direction::Receive, 0x1600, false),
        0x1800..=0x1803 => (Direction::Transmit, 0x1800, true),
        0x1a00..=0x1a03 => (Direction::Transmit, 0x1a00, false),
        _ => return None,
    };
    Some((direction, (index - base) as u8 + 1, comm))
}

fn le_u32(data: &[u8]) -> u32 {
    let mut b = [0u8; 4];
    b[..data.len().min(4)].copy_from_slice(&data[..data.len().min(4)]);
    u32::from_le_bytes(b)
}

impl FakeElmo {
    /// True while PDO `n` exists (bit 31 of its COB-ID clear).
    fn pdo_valid(&self, direction: Direction, n: u8) -> bool {
        self.od.get_u(direction.comm_index(n), 1) as u32 & 0x8000_0000 == 0
    }

    /// The CiA 301 rules for writing a PDO's parameters: the COB-ID of a valid PDO does not
    /// change; a mapping changes only while the PDO is invalid and its count is 0; a mapping
    /// names existing, mappable objects at their own length, 64 bits at most in all.
    pub(super) fn check_pdo_write(
        &self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        let Some((direction, n, comm)) = pdo_of(index) else {
            return Ok(());
        };
        if comm {
            if sub == 1 {
                let old = self.od.get_u(index, 1) as u32;
                let new = le_u32(data);
                let valid_before = old & 0x8000_0000 == 0;
                let valid_after = new & 0x8000_0000 == 0;
                if valid_before && valid_after && (old & 0x1fff_ffff) != (new & 0x1fff_ffff) {
                    return Err(AbortCode::INVALID_VALUE);
                }
            }
            return Ok(());
        }
        if self.pdo_valid(direction, n) {
            return Err(AbortCode::DEVICE_STATE);
        }
        let count = self.od.get_u(index, 0) as u8;
        if sub == 0 {
            let want = data.first().copied().unwrap_or(0);
            if want > 8 {
                return Err(AbortCode::VALUE_TOO_HIGH);
            }
            let mut bits = 0u32;
            for s in 1..=want {
                let e = MapEntry::from_u32(self.od.get_u(index, s) as u32);
                self.check_mappable(e)?;
                bits += e.bits as u32;
            }
            if bits > 64 {
                return Err(AbortCode::PDO_TOO_LONG);
            }
            return Ok(());
        }
        if count != 0 {
            return Err(AbortCode::DEVICE_STATE);
        }
        let e = MapEntry::from_u32(le_u32(data));
        if e.to_u32() != 0 {
            self.check_mappable(e)?;
        }
        Ok(())
    }

    /// An entry may be mapped when its object exists, is mappable and has that length.
    fn check_mappable(&self, e: MapEntry) -> Result<(), AbortCode> {
        let obj = self.od.entry(e.index, e.sub)?;
        if !obj.mappable || obj.value.len() * 8 != e.bits as usize {
            return Err(AbortCode::NOT_MAPPABLE);
        }
        Ok(())
    }

    /// PDO `n`'s mapping as it stands.
    pub(super) fn mapping(&self, direction: Direction, n: u8) -> PdoConfig {
        let base = direction.map_index(n);
        let count = self.od.get_u(base, 0) as u8;
        PdoConfig {
            direction,
            number: n,
            transmission: self.od.get_u(direction.comm_index(n), 2) as u8,
            entries: (1..=count.min(8))
                .map(|s| MapEntry::from_u32(self.od.get_u(base, s) as u32))
                .collect(),
        }
    }

    /// A SYNC: the synchronous TPDOs due at this count go out.
    pub(super) fn on_sync(&mut self) {
        if self.nmt != stride_canopen::nmt::State::Operational {
            return;
        }
        self.sync_count = self.sync_count.wrapping_add(1);
        for n in [1u8, 3, 4] {
            let cob = self.od.get_u(Direction::Transmit.comm_index(n), 1) as u32;
            let cfg = self.mapping(Direction::Transmit, n);
            let kind = cfg.transmission as u32;
            if cob & 0x8000_0000 != 0
                || !(1..=240).contains(&kind)
                || !self.sync_count.is_multiple_of(kind)
            {
                continue;
            }
            let values: Vec<u64> = cfg
                .entries
                .iter()
                .map(|e| self.od.get_u(e.index, e.sub))
                .collect();
            if let Ok(frame) = CanFrame::standard((cob & 0x7ff) as u16, &cfg.pack(&values)) {
                self.send(frame);
            }
        }
    }

    /// A frame that may be one of the receive PDOs 1, 3, 4.
    pub(super) fn on_rpdo(&mut self, id: u16, data: &[u8], now: Instant) {
        for n in [1u8, 3, 4] {
            let cob = self.od.get_u(Direction::Receive.comm_index(n), 1) as u32;
            if cob & 0x8000_0000 == 0 && cob & 0x7ff == id as u32 {
                self.write_rpdo(n, data, now);
            }
        }
    }

    fn write_rpdo(&mut self, n: u8, data: &[u8], now: Instant) {
        let cfg = self.mapping(Direction::Receive, n);
        let Some(values) = cfg.unpack(data) else {
            // PDO not processed: length error.
            let e = Emcy {
                node: self.cfg.node,
                code: Emcy::PDO_LENGTH,
                register: 0x11,
                manufacturer: [0; 5],
            };
            self.emcy(e);
            return;
        };
        // A PVT row or two PT points, mapped as one 64-bit object.
        if cfg.entries.len() == 1
            && [PVT_OBJECT, PT_OBJECT].contains(&cfg.entries[0].index)
            && data.len() == 8
        {
            let _ = self.write_object(cfg.entries[0].index, 0, data, now);
            return;
        }
        for (e, v) in cfg.entries.iter().zip(values) {
            let _ = self.write_object(
                e.index,
                e.sub,
                &v.to_le_bytes()[..(e.bits as usize).div_ceil(8)],
                now,
            );
        }
    }
}
