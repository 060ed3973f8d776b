//! The classic CAN frame ([`CanFrame`]) below every CAN protocol of stride (CANopen, SLCAN)
//! and every CAN transport: an 11- or 29-bit identifier, up to 8 data bytes or a remote
//! request, `embedded_can::Frame`, and the frame's length on the wire: exact (its CRC-15 and
//! its stuff bits computed, [`CanFrame::wire_bits`]) and its worst and best case. No I/O.

pub mod dump;

pub use embedded_can::{ExtendedId, Id, StandardId};

/// Why a frame could not be built or read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// More than 8 data bytes.
    #[error("{0} data bytes; classic CAN carries at most 8")]
    TooLong(usize),
    /// An identifier outside the 11-bit or 29-bit range.
    #[error("identifier {0:#x} out of range")]
    BadId(u32),
    /// Fewer data bytes than a protocol needs.
    #[error("expected at least {expected} data bytes, found {found}")]
    Short {
        /// Bytes needed.
        expected: usize,
        /// Bytes present.
        found: usize,
    },
}

/// A classic CAN frame: identifier, up to 8 data bytes, remote flag.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CanFrame {
    id: Id,
    rtr: bool,
    len: u8,
    data: [u8; 8],
}

impl CanFrame {
    /// A data frame with a standard (11-bit) identifier.
    pub fn standard(id: u16, data: &[u8]) -> Result<CanFrame, FrameError> {
        let sid = StandardId::new(id).ok_or(FrameError::BadId(id as u32))?;
        Self::data_frame(Id::Standard(sid), data)
    }

    /// A data frame with an extended (29-bit) identifier.
    pub fn extended(id: u32, data: &[u8]) -> Result<CanFrame, FrameError> {
        let eid = ExtendedId::new(id).ok_or(FrameError::BadId(id))?;
        Self::data_frame(Id::Extended(eid), data)
    }

    /// A data frame with any identifier.
    pub fn data_frame(id: Id, data: &[u8]) -> Result<CanFrame, FrameError> {
        if data.len() > 8 {
            return Err(FrameError::TooLong(data.len()));
        }
        let mut d = [0u8; 8];
        d[..data.len()].copy_from_slice(data);
        Ok(CanFrame {
            id,
            rtr: false,
            len: data.len() as u8,
            data: d,
        })
    }

    /// A remote (RTR) frame asking for `dlc` bytes.
    pub fn remote(id: Id, dlc: u8) -> Result<CanFrame, FrameError> {
        if dlc > 8 {
            return Err(FrameError::TooLong(dlc as usize));
        }
        Ok(CanFrame {
            id,
            rtr: true,
            len: dlc,
            data: [0; 8],
        })
    }

    /// The identifier.
    pub fn id(&self) -> Id {
        self.id
    }

    /// The identifier as a number (11 or 29 bits).
    pub fn raw_id(&self) -> u32 {
        match self.id {
            Id::Standard(s) => s.as_raw() as u32,
            Id::Extended(e) => e.as_raw(),
        }
    }

    /// True for a 29-bit identifier.
    pub fn is_extended(&self) -> bool {
        matches!(self.id, Id::Extended(_))
    }

    /// True for a remote frame.
    pub fn is_remote(&self) -> bool {
        self.rtr
    }

    /// Data length code.
    pub fn dlc(&self) -> usize {
        self.len as usize
    }

    /// The data bytes (empty for remote frames).
    pub fn data(&self) -> &[u8] {
        if self.rtr {
            &[]
        } else {
            &self.data[..self.len as usize]
        }
    }

    /// The data, checked to be at least `n` bytes long.
    pub fn data_at_least(&self, n: usize) -> Result<&[u8], FrameError> {
        let d = self.data();
        if d.len() < n {
            Err(FrameError::Short {
                expected: n,
                found: d.len(),
            })
        } else {
            Ok(d)
        }
    }

    /// The bits from the start of frame to the end of the CRC sequence, before stuffing:
    /// the part of the frame the CRC covers, then the CRC.
    fn stuffable_bits(&self) -> Vec<bool> {
        let mut bits = Vec::with_capacity(160);
        let push = |bits: &mut Vec<bool>, v: u32, n: u32| {
            for i in (0..n).rev() {
                bits.push(v >> i & 1 != 0);
            }
        };
        push(&mut bits, 0, 1); // start of frame
        match self.id {
            Id::Standard(s) => {
                push(&mut bits, s.as_raw() as u32, 11);
                push(&mut bits, self.rtr as u32, 1);
                push(&mut bits, 0, 2); // IDE, r0
            }
            Id::Extended(e) => {
                let raw = e.as_raw();
                push(&mut bits, raw >> 18, 11);
                push(&mut bits, 1, 2); // SRR, IDE
                push(&mut bits, raw & 0x3ffff, 18);
                push(&mut bits, self.rtr as u32, 1);
                push(&mut bits, 0, 2); // r1, r0
            }
        }
        push(&mut bits, self.len as u32, 4);
        for b in self.data() {
            push(&mut bits, *b as u32, 8);
        }
        let crc = crc15(&bits);
        push(&mut bits, crc as u32, 15);
        bits
    }

    /// Bits this frame occupies on the wire, exactly: its stuff bits counted on its own
    /// CRC-15, plus the CRC delimiter, acknowledgement, end of frame and the 3-bit interframe
    /// space.
    pub fn wire_bits(&self) -> u32 {
        let bits = self.stuffable_bits();
        let (mut run, mut last, mut stuffed) = (0u32, None, 0u32);
        for b in bits.iter().copied() {
            if Some(b) == last {
                run += 1;
            } else {
                last = Some(b);
                run = 1;
            }
            if run == 5 {
                // A stuff bit of the other level follows, and starts a run of its own.
                stuffed += 1;
                last = Some(!b);
                run = 1;
            }
        }
        bits.len() as u32 + stuffed + TRAILER_BITS
    }

    /// Bits this frame occupies on the wire at most (with worst-case bit stuffing and the
    /// 3-bit interframe space): 55 + 10 per data byte for standard frames, 80 + 10 for extended.
    pub fn max_wire_bits(&self) -> u32 {
        let data_bits = if self.rtr { 0 } else { 8 * self.len as u32 };
        // Stuffable bits: SOF..CRC (34 + data for standard, 54 + data for extended).
        let (fixed, stuffable) = if self.is_extended() {
            (67, 54)
        } else {
            (47, 34)
        };
        let stuff = (stuffable + data_bits - 1) / 4;
        fixed + data_bits + stuff
    }

    /// Bits this frame occupies on the wire without bit stuffing (interframe space included).
    pub fn min_wire_bits(&self) -> u32 {
        let data_bits = if self.rtr { 0 } else { 8 * self.len as u32 };
        (if self.is_extended() { 67 } else { 47 }) + data_bits
    }
}

/// CRC delimiter, ACK slot, ACK delimiter, 7 bits of end of frame, 3 of interframe space.
const TRAILER_BITS: u32 = 13;

/// The CAN CRC-15 (polynomial 0x4599, initial value 0) over a bit sequence.
fn crc15(bits: &[bool]) -> u16 {
    let mut crc: u16 = 0;
    for &b in bits {
        let next = b ^ (crc >> 14 & 1 != 0);
        crc = (crc << 1) & 0x7fff;
        if next {
            crc ^= 0x4599;
        }
    }
    crc
}

impl embedded_can::Frame for CanFrame {
    fn new(id: impl Into<Id>, data: &[u8]) -> Option<Self> {
        Self::data_frame(id.into(), data).ok()
    }
    fn new_remote(id: impl Into<Id>, dlc: usize) -> Option<Self> {
        Self::remote(id.into(), u8::try_from(dlc).ok()?).ok()
    }
    fn is_extended(&self) -> bool {
        CanFrame::is_extended(self)
    }
    fn is_remote_frame(&self) -> bool {
        self.rtr
    }
    fn id(&self) -> Id {
        self.id
    }
    fn dlc(&self) -> usize {
        self.len as usize
    }
    fn data(&self) -> &[u8] {
        CanFrame::data(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn frames_and_wire_time() {
        let f = CanFrame::standard(0x601, &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0]).unwrap();
        assert_eq!(f.dlc(), 8);
        assert_eq!(f.min_wire_bits(), 111);
        assert_eq!(f.max_wire_bits(), 135);
        let sync = CanFrame::standard(0x080, &[]).unwrap();
        assert_eq!((sync.min_wire_bits(), sync.max_wire_bits()), (47, 55));
        let ext = CanFrame::extended(0x1234567, &[0; 8]).unwrap();
        assert_eq!((ext.min_wire_bits(), ext.max_wire_bits()), (131, 160));
        assert!(CanFrame::standard(0x800, &[]).is_err());
        assert!(CanFrame::standard(1, &[0; 9]).is_err());
        let r = CanFrame::remote(Id::Standard(StandardId::new(0x705).unwrap()), 1).unwrap();
        assert!(r.is_remote() && r.data().is_empty() && r.dlc() == 1);
        assert_eq!(
            f.data_at_least(9),
            Err(FrameError::Short {
                expected: 9,
                found: 8
            })
        );
    }

    #[test]
    fn crc15_is_the_remainder_of_the_polynomial_division() {
        // The CRC as the textbook defines it: the bit sequence followed by 15 zero bits,
        // divided by x^15 + x^14 + x^10 + x^8 + x^7 + x^4 + x^3 + 1 (0xC599), bit by bit.
        fn division(bits: &[bool]) -> u16 {
            let mut rem: Vec<bool> = bits.to_vec();
            rem.extend([false; 15]);
            let g: Vec<bool> = (0..16).rev().map(|i| 0xc599u32 >> i & 1 != 0).collect();
            for i in 0..bits.len() {
                if rem[i] {
                    for (k, gb) in g.iter().enumerate() {
                        rem[i + k] ^= gb;
                    }
                }
            }
            rem[bits.len()..]
                .iter()
                .fold(0u16, |a, &b| a << 1 | b as u16)
        }
        for f in [
            CanFrame::standard(0x123, &[0x01]).unwrap(),
            CanFrame::standard(0x7ff, &[0xff; 8]).unwrap(),
            CanFrame::extended(0x1abc_def0, &[1, 2, 3]).unwrap(),
        ] {
            let bits = f.stuffable_bits();
            let body = &bits[..bits.len() - 15];
            let crc = bits[bits.len() - 15..]
                .iter()
                .fold(0u16, |a, &b| a << 1 | b as u16);
            assert_eq!(crc, division(body), "{f:?}");
        }
    }

    #[test]
    fn all_zero_frames_stuff_the_most() {
        // Identifier 0 and zero data: runs of five zeros all the way, so each 4 bits after the
        // first 5 carry a stuff bit until the CRC breaks the pattern.
        let f = CanFrame::standard(0, &[0; 8]).unwrap();
        assert!(f.wire_bits() > f.min_wire_bits() + 15, "{}", f.wire_bits());
        assert!(f.wire_bits() <= f.max_wire_bits());
    }

    proptest! {
        #[test]
        fn exact_length_lies_between_the_bounds(
            id in 0u32..0x2000_0000, extended: bool, remote: bool,
            data in proptest::collection::vec(any::<u8>(), 0..=8),
        ) {
            let f = if extended {
                CanFrame::extended(id, &data).unwrap()
            } else {
                CanFrame::standard((id & 0x7ff) as u16, &data).unwrap()
            };
            let f = if remote { CanFrame::remote(f.id(), data.len() as u8).unwrap() } else { f };
            prop_assert!(f.min_wire_bits() <= f.wire_bits());
            prop_assert!(f.wire_bits() <= f.max_wire_bits());
            prop_assert_eq!(crc15(&f.stuffable_bits()), 0);
        }
    }
}
