//! PDO mapping and communication parameters, and the SDO writes that configure them.

use crate::frame::{CobId, Function, NodeId};

/// Receive (host to drive) or transmit (drive to host).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Direction {
    /// RPDO: communication 0x1400 + n - 1, mapping 0x1600 + n - 1.
    Receive,
    /// TPDO: communication 0x1800 + n - 1, mapping 0x1A00 + n - 1.
    Transmit,
}

impl Direction {
    /// Index of PDO `n`'s communication parameter object (`n` from 1).
    pub fn comm_index(self, n: u8) -> u16 {
        let base: u16 = match self {
            Direction::Receive => 0x1400,
            Direction::Transmit => 0x1800,
        };
        base + n as u16 - 1
    }

    /// Index of PDO `n`'s mapping object (`n` from 1).
    pub fn map_index(self, n: u8) -> u16 {
        let base: u16 = match self {
            Direction::Receive => 0x1600,
            Direction::Transmit => 0x1a00,
        };
        base + n as u16 - 1
    }
}

/// One mapped object: index, sub-index and length in bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct MapEntry {
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Length in bits (8, 16, 24, 32).
    pub bits: u8,
}

impl MapEntry {
    /// The 32-bit value stored in the mapping object.
    pub fn to_u32(self) -> u32 {
        (self.index as u32) << 16 | (self.sub as u32) << 8 | self.bits as u32
    }

    /// Parses a mapping value.
    pub fn from_u32(v: u32) -> MapEntry {
        MapEntry {
            index: (v >> 16) as u16,
            sub: (v >> 8) as u8,
            bits: v as u8,
        }
    }
}

/// A PDO's configuration: which one, its COB-ID, transmission type and mapped objects.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PdoConfig {
    /// Receive or transmit.
    pub direction: Direction,
    /// PDO number, 1..=4 in the predefined connection set.
    pub number: u8,
    /// Transmission type: 1..=240 synchronous every n SYNCs, 254/255 event-driven.
    pub transmission: u8,
    /// Mapped objects, in frame order.
    pub entries: Vec<MapEntry>,
}

impl PdoConfig {
    /// Index of the communication parameter object.
    pub fn comm_index(&self) -> u16 {
        self.direction.comm_index(self.number)
    }

    /// Index of the mapping object.
    pub fn map_index(&self) -> u16 {
        self.direction.map_index(self.number)
    }

    /// The predefined COB-ID of this PDO on `node`.
    pub fn cob_id(&self, node: NodeId) -> u16 {
        let f = match self.direction {
            Direction::Receive => Function::Rpdo(self.number),
            Direction::Transmit => Function::Tpdo(self.number),
        };
        CobId::of(f, node).raw()
    }

    /// Bytes the mapped objects occupy in the frame (at most 8 for a valid mapping).
    pub fn data_len(&self) -> usize {
        self.entries
            .iter()
            .map(|e| e.bits as usize)
            .sum::<usize>()
            .div_ceil(8)
    }

    /// The SDO writes that configure the PDO, in the order CiA 301 requires: invalidate,
    /// clear the mapping, write the entries, set their count, set the transmission type, then
    /// make the PDO valid again. Each is `(index, sub, little-endian value)`.
    pub fn sdo_writes(&self, node: NodeId) -> Vec<(u16, u8, Vec<u8>)> {
        let cob = self.cob_id(node) as u32;
        let mut w = vec![
            (
                self.comm_index(),
                1,
                (cob | 0x8000_0000).to_le_bytes().to_vec(),
            ),
            (self.map_index(), 0, vec![0]),
        ];
        for (i, e) in self.entries.iter().enumerate() {
            w.push((
                self.map_index(),
                i as u8 + 1,
                e.to_u32().to_le_bytes().to_vec(),
            ));
        }
        w.push((self.map_index(), 0, vec![self.entries.len() as u8]));
        w.push((self.comm_index(), 2, vec![self.transmission]));
        w.push((self.comm_index(), 1, cob.to_le_bytes().to_vec()));
        w
    }

    /// The reads that verify the mapping afterwards: `(index, sub, expected value)`.
    pub fn verification(&self) -> Vec<(u16, u8, Vec<u8>)> {
        let mut v = vec![(self.map_index(), 0, vec![self.entries.len() as u8])];
        for (i, e) in self.entries.iter().enumerate() {
            v.push((
                self.map_index(),
                i as u8 + 1,
                e.to_u32().to_le_bytes().to_vec(),
            ));
        }
        v
    }

    /// Splits a received PDO's data into the values of its entries (little-endian, up to 64
    /// bits each, sign extension left to the caller); `None` when the frame is shorter than
    /// the mapping or an entry is longer than 64 bits.
    pub fn unpack(&self, data: &[u8]) -> Option<Vec<u64>> {
        if data.len() < self.data_len() || self.entries.iter().any(|e| e.bits > 64) {
            return None;
        }
        let mut bit = 0usize;
        let mut out = Vec::with_capacity(self.entries.len());
        for e in &self.entries {
            let bytes = (e.bits as usize).div_ceil(8);
            let start = bit / 8;
            let mut v = 0u64;
            for (k, b) in data.get(start..start + bytes)?.iter().enumerate() {
                v |= (*b as u64) << (8 * k);
            }
            out.push(v);
            bit += e.bits as usize;
        }
        Some(out)
    }

    /// Packs entry values into frame data (each entry's low bytes, little-endian).
    pub fn pack(&self, values: &[u64]) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.data_len());
        for (e, v) in self.entries.iter().zip(values) {
            let bytes = (e.bits as usize).div_ceil(8).min(8);
            out.extend_from_slice(&v.to_le_bytes()[..bytes]);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mapping_values_and_sdo_sequence() {
        // Statusword (0x6041, 16 bits) + actual position (0x6064, 32 bits) in TPDO1.
        let t = PdoConfig {
            direction: Direction::Transmit,
            number: 1,
            transmission: 1,
            entries: vec![
                MapEntry {
                    index: 0x6041,
                    sub: 0,
                    bits: 16,
                },
                MapEntry {
                    index: 0x6064,
                    sub: 0,
                    bits: 32,
                },
            ],
        };
        assert_eq!(t.entries[1].to_u32(), 0x6064_0020);
        assert_eq!(MapEntry::from_u32(0x6041_0010), t.entries[0]);
        let n = NodeId::new(3).unwrap();
        let w = t.sdo_writes(n);
        assert_eq!(w[0], (0x1800, 1, vec![0x83, 0x01, 0x00, 0x80]));
        assert_eq!(w[1], (0x1a00, 0, vec![0]));
        assert_eq!(w[2], (0x1a00, 1, vec![0x10, 0x00, 0x41, 0x60]));
        assert_eq!(w[4], (0x1a00, 0, vec![2]));
        assert_eq!(w[5], (0x1800, 2, vec![1]));
        assert_eq!(w[6], (0x1800, 1, vec![0x83, 0x01, 0x00, 0x00]));
        assert_eq!(t.data_len(), 6);
        let data = t.pack(&[0x0637, 0xfffffff6]);
        assert_eq!(data, [0x37, 0x06, 0xf6, 0xff, 0xff, 0xff]);
        assert_eq!(t.unpack(&data).unwrap(), vec![0x0637, 0xfffffff6]);
        assert!(t.unpack(&data[..5]).is_none());
        let pvt = PdoConfig {
            direction: Direction::Receive,
            number: 3,
            transmission: 255,
            entries: vec![MapEntry {
                index: 0x2001,
                sub: 0,
                bits: 64,
            }],
        };
        assert_eq!(
            pvt.unpack(&[1, 0, 0, 0, 0, 0, 0, 0x80]).unwrap(),
            vec![0x8000_0000_0000_0001]
        );
        let bad = PdoConfig {
            entries: vec![MapEntry {
                index: 1,
                sub: 0,
                bits: 200,
            }],
            ..pvt
        };
        assert!(bad.unpack(&[0; 8]).is_none());
        assert_eq!(t.verification().len(), 3);
    }

    proptest::proptest! {
        #[test]
        fn unpack_never_panics(
            bits in proptest::collection::vec(0u8..=255, 0..10),
            data in proptest::collection::vec(proptest::num::u8::ANY, 0..=8),
        ) {
            let cfg = PdoConfig {
                direction: Direction::Receive,
                number: 1,
                transmission: 255,
                entries: bits.iter().map(|b| MapEntry { index: 0x2000, sub: 0, bits: *b }).collect(),
            };
            if let Some(v) = cfg.unpack(&data) {
                proptest::prop_assert_eq!(v.len(), bits.len());
            }
        }
    }
}
