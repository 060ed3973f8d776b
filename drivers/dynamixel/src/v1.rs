//! Dynamixel Protocol 1.0: `FF FF ID LEN INST PARAMS… CHK`, LEN = parameters + 2, CHK = the
//! inverted low byte of the sum from ID to the last parameter. Status packets carry an error
//! byte in place of the instruction ([`ErrorBits`]). Addresses and lengths are one byte.

use crate::{bit_names, CodecError, Instruction, Status};

/// Instruction codes.
pub mod inst {
    /// Ping.
    pub const PING: u8 = 0x01;
    /// Read.
    pub const READ: u8 = 0x02;
    /// Write.
    pub const WRITE: u8 = 0x03;
    /// Reg write.
    pub const REG_WRITE: u8 = 0x04;
    /// Action.
    pub const ACTION: u8 = 0x05;
    /// Reset to factory settings.
    pub const RESET: u8 = 0x06;
    /// Reboot (MX series with recent firmware).
    pub const REBOOT: u8 = 0x08;
    /// Sync write.
    pub const SYNC_WRITE: u8 = 0x83;
    /// Bulk read (MX series).
    pub const BULK_READ: u8 = 0x92;
}

/// The error bits of a Protocol 1.0 status packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct ErrorBits(pub u8);

impl ErrorBits {
    /// Bit 0: input voltage outside the configured range.
    pub const INPUT_VOLTAGE: u8 = 0x01;
    /// Bit 1: goal position outside the angle limits.
    pub const ANGLE_LIMIT: u8 = 0x02;
    /// Bit 2: internal temperature above the limit.
    pub const OVERHEATING: u8 = 0x04;
    /// Bit 3: an instruction value out of range.
    pub const RANGE: u8 = 0x08;
    /// Bit 4: the instruction's checksum was wrong.
    pub const CHECKSUM: u8 = 0x10;
    /// Bit 5: the load exceeds the maximum torque.
    pub const OVERLOAD: u8 = 0x20;
    /// Bit 6: an undefined instruction, or an action without a reg write.
    pub const INSTRUCTION: u8 = 0x40;

    /// The names of the bits set.
    pub fn names(self) -> Vec<&'static str> {
        bit_names(
            self.0,
            &[
                (Self::INPUT_VOLTAGE, "input voltage"),
                (Self::ANGLE_LIMIT, "angle limit"),
                (Self::OVERHEATING, "overheating"),
                (Self::RANGE, "range"),
                (Self::CHECKSUM, "checksum"),
                (Self::OVERLOAD, "overload"),
                (Self::INSTRUCTION, "instruction"),
            ],
        )
    }
}

fn checksum(body: &[u8]) -> u8 {
    !body.iter().fold(0u8, |a, b| a.wrapping_add(*b))
}

fn frame(id: u8, code: u8, params: &[u8]) -> Result<Vec<u8>, CodecError> {
    if params.len() > 253 {
        return Err(CodecError::Unsupported(
            "Protocol 1.0 packets carry at most 253 parameter bytes",
        ));
    }
    let mut p = Vec::with_capacity(params.len() + 6);
    p.extend_from_slice(&[0xff, 0xff, id, params.len() as u8 + 2, code]);
    p.extend_from_slice(params);
    p.push(checksum(&p[2..]));
    Ok(p)
}

fn byte(v: u16, what: &'static str) -> Result<u8, CodecError> {
    u8::try_from(v).map_err(|_| CodecError::Unsupported(what))
}

/// Encodes an instruction packet to `id`. Instructions Protocol 1.0 lacks (sync read, bulk
/// write, clear, the fast reads), addresses above 255 and lengths above 255 are refused.
pub fn encode_instruction(id: u8, ins: &Instruction) -> Result<Vec<u8>, CodecError> {
    const ADDR: &str = "Protocol 1.0 addresses are 0..=255";
    const LEN: &str = "Protocol 1.0 lengths are 0..=255";
    match ins {
        Instruction::Ping => frame(id, inst::PING, &[]),
        Instruction::Read { address, length } => frame(
            id,
            inst::READ,
            &[byte(*address, ADDR)?, byte(*length, LEN)?],
        ),
        Instruction::Write { address, data } | Instruction::RegWrite { address, data } => {
            let code = if matches!(ins, Instruction::Write { .. }) {
                inst::WRITE
            } else {
                inst::REG_WRITE
            };
            let mut p = vec![byte(*address, ADDR)?];
            p.extend_from_slice(data);
            frame(id, code, &p)
        }
        Instruction::Action => frame(id, inst::ACTION, &[]),
        Instruction::FactoryReset { .. } => frame(id, inst::RESET, &[]),
        Instruction::Reboot => frame(id, inst::REBOOT, &[]),
        Instruction::SyncWrite {
            address,
            length,
            data,
        } => {
            let mut p = vec![byte(*address, ADDR)?, byte(*length, LEN)?];
            for (sid, d) in data {
                if d.len() != *length as usize {
                    return Err(CodecError::Parameters {
                        instruction: inst::SYNC_WRITE,
                        why: "every servo's data must be `length` bytes",
                    });
                }
                p.push(*sid);
                p.extend_from_slice(d);
            }
            frame(crate::BROADCAST, inst::SYNC_WRITE, &p)
        }
        Instruction::BulkRead { reads } => {
            // 0x00, then (length, id, address) per servo.
            let mut p = vec![0x00];
            for (sid, address, length) in reads {
                p.extend_from_slice(&[byte(*length, LEN)?, *sid, byte(*address, ADDR)?]);
            }
            frame(crate::BROADCAST, inst::BULK_READ, &p)
        }
        Instruction::Clear { .. }
        | Instruction::SyncRead { .. }
        | Instruction::FastSyncRead { .. }
        | Instruction::BulkWrite { .. }
        | Instruction::FastBulkRead { .. } => Err(CodecError::Unsupported(
            "Protocol 1.0 has no sync read, bulk write, clear or fast reads",
        )),
    }
}

/// Splits one whole, checked packet into (id, code, params).
pub fn unframe(p: &[u8]) -> Result<(u8, u8, &[u8]), CodecError> {
    if p.len() < 6 {
        return Err(CodecError::Truncated {
            have: p.len(),
            need: 6,
        });
    }
    if p[0] != 0xff || p[1] != 0xff {
        return Err(CodecError::NoHeader);
    }
    let len = p[3] as usize;
    if len < 2 {
        return Err(CodecError::Length(len));
    }
    let need = len + 4;
    if p.len() < need {
        return Err(CodecError::Truncated {
            have: p.len(),
            need,
        });
    }
    let want = checksum(&p[2..need - 1]);
    if p[need - 1] != want {
        return Err(CodecError::Checksum {
            got: p[need - 1] as u16,
            want: want as u16,
        });
    }
    Ok((p[2], p[4], &p[5..need - 1]))
}

/// Decodes an instruction packet (the servo's side): (id, instruction).
pub fn decode_instruction(p: &[u8]) -> Result<(u8, Instruction), CodecError> {
    let (id, code, params) = unframe(p)?;
    let bad = |why| CodecError::Parameters {
        instruction: code,
        why,
    };
    let ins = match code {
        inst::PING => Instruction::Ping,
        inst::READ if params.len() == 2 => Instruction::Read {
            address: params[0] as u16,
            length: params[1] as u16,
        },
        inst::READ => return Err(bad("read takes an address and a length")),
        inst::WRITE | inst::REG_WRITE if !params.is_empty() => {
            let (address, data) = (params[0] as u16, params[1..].to_vec());
            if code == inst::WRITE {
                Instruction::Write { address, data }
            } else {
                Instruction::RegWrite { address, data }
            }
        }
        inst::WRITE | inst::REG_WRITE => return Err(bad("a write needs an address")),
        inst::ACTION => Instruction::Action,
        inst::RESET => Instruction::FactoryReset { option: 0xff },
        inst::REBOOT => Instruction::Reboot,
        inst::SYNC_WRITE => {
            if params.len() < 2 {
                return Err(bad("sync write needs an address and a length"));
            }
            let (address, length) = (params[0] as u16, params[1] as usize);
            let rest = &params[2..];
            if rest.len() % (length + 1) != 0 {
                return Err(bad("sync write data is not a whole number of servos"));
            }
            Instruction::SyncWrite {
                address,
                length: length as u16,
                data: rest
                    .chunks(length + 1)
                    .map(|c| (c[0], c[1..].to_vec()))
                    .collect(),
            }
        }
        inst::BULK_READ => {
            if params.is_empty() || (params.len() - 1) % 3 != 0 {
                return Err(bad(
                    "bulk read is 0x00 then (length, id, address) per servo",
                ));
            }
            Instruction::BulkRead {
                reads: params[1..]
                    .chunks(3)
                    .map(|c| (c[1], c[2] as u16, c[0] as u16))
                    .collect(),
            }
        }
        other => return Err(CodecError::UnknownInstruction(other)),
    };
    Ok((id, ins))
}

/// Encodes a status packet (the servo's side).
pub fn encode_status(s: &Status) -> Result<Vec<u8>, CodecError> {
    frame(s.id, s.error, &s.params)
}

/// Decodes a status packet (the host's side).
pub fn decode_status(p: &[u8]) -> Result<Status, CodecError> {
    let (id, error, params) = unframe(p)?;
    Ok(Status {
        id,
        error,
        params: params.to_vec(),
    })
}

/// Protocol 1.0 framing, for [`crate::Splitter`].
#[derive(Debug)]
pub struct Framing1;

impl crate::Framing for Framing1 {
    const HEAD: usize = 4;
    fn header_at(buf: &[u8], i: usize) -> bool {
        buf[i] == 0xff && buf[i + 1] == 0xff && buf[i + 2] != 0xff
    }
    fn packet_len(head: &[u8]) -> Option<usize> {
        (head[3] >= 2).then(|| head[3] as usize + 4)
    }
    fn check(packet: &[u8]) -> Result<(), CodecError> {
        unframe(packet).map(|_| ())
    }
    fn id(packet: &[u8]) -> u8 {
        packet[2]
    }
}

/// Finds Protocol 1.0 packets in a byte stream (see [`crate::Splitter`]).
pub type Splitter = crate::Splitter<Framing1>;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hex;
    use crate::Split;

    #[test]
    fn manual_examples() {
        // Ping id 1, and its status.
        let ping = encode_instruction(1, &Instruction::Ping).unwrap();
        assert_eq!(ping, hex("FF FF 01 02 01 FB"));
        assert_eq!(
            decode_status(&hex("FF FF 01 02 00 FC")).unwrap(),
            Status {
                id: 1,
                error: 0,
                params: vec![]
            }
        );
        // Read the internal temperature (address 43, one byte) of id 1: 32 °C.
        let read = Instruction::Read {
            address: 43,
            length: 1,
        };
        assert_eq!(
            encode_instruction(1, &read).unwrap(),
            hex("FF FF 01 04 02 2B 01 CC")
        );
        assert_eq!(
            decode_status(&hex("FF FF 01 03 00 20 DB")).unwrap().params,
            [0x20]
        );
        // Set the id of the servo(s) on the bus to 1, through the broadcast id.
        let write = Instruction::Write {
            address: 3,
            data: vec![1],
        };
        assert_eq!(
            encode_instruction(0xfe, &write).unwrap(),
            hex("FF FF FE 04 03 03 01 F6")
        );
        // Sync write: goal position and speed (address 30, 4 bytes) of ids 0 and 1.
        let sync = Instruction::SyncWrite {
            address: 30,
            length: 4,
            data: vec![(0, hex("10 00 50 01")), (1, hex("20 02 60 03"))],
        };
        let bytes = encode_instruction(0xfe, &sync).unwrap();
        assert_eq!(
            bytes,
            hex("FF FF FE 0E 83 1E 04 00 10 00 50 01 01 20 02 60 03 67")
        );
        assert_eq!(decode_instruction(&bytes).unwrap(), (0xfe, sync));
        // Reg write of goal position 500, action, factory reset of id 0, reboot.
        let cases = [
            (
                1,
                Instruction::RegWrite {
                    address: 30,
                    data: vec![0xf4, 0x01],
                },
                "FF FF 01 05 04 1E F4 01 E2",
            ),
            (0xfe, Instruction::Action, "FF FF FE 02 05 FA"),
            (
                0,
                Instruction::FactoryReset { option: 0xff },
                "FF FF 00 02 06 F7",
            ),
            (1, Instruction::Reboot, "FF FF 01 02 08 F4"),
            (
                1,
                Instruction::Write {
                    address: 12,
                    data: vec![0x64, 0xaa],
                },
                "FF FF 01 05 03 0C 64 AA DC",
            ),
        ];
        for (id, ins, b) in cases {
            assert_eq!(encode_instruction(id, &ins).unwrap(), hex(b), "{ins:?}");
            assert_eq!(decode_instruction(&hex(b)).unwrap(), (id, ins));
        }
        // Overload and overheating.
        let st = decode_status(&hex("FF FF 01 02 24 D8")).unwrap();
        assert_eq!(ErrorBits(st.error).names(), ["overheating", "overload"]);
        // Bulk read: 2 bytes at 30 of id 1, 2 bytes at 36 of id 2.
        let bulk = Instruction::BulkRead {
            reads: vec![(1, 30, 2), (2, 36, 2)],
        };
        let bytes = encode_instruction(0xfe, &bulk).unwrap();
        assert_eq!(bytes, hex("FF FF FE 09 92 00 02 01 1E 02 02 24 1D"));
        assert_eq!(decode_instruction(&bytes).unwrap(), (0xfe, bulk));
        assert_eq!(
            decode_status(&hex("FF FF 01 04 00 00 80 7A"))
                .unwrap()
                .params,
            [0x00, 0x80]
        );
        assert_eq!(
            decode_status(&hex("FF FF 02 04 00 00 80 79")).unwrap().id,
            2
        );
    }

    #[test]
    fn error_bits_and_refusals() {
        let e = ErrorBits(ErrorBits::OVERHEATING | ErrorBits::OVERLOAD);
        assert_eq!(e.names(), ["overheating", "overload"]);
        assert!(encode_instruction(
            1,
            &Instruction::Read {
                address: 300,
                length: 2
            }
        )
        .is_err());
        assert!(encode_instruction(
            1,
            &Instruction::SyncRead {
                address: 36,
                length: 2,
                ids: vec![1]
            }
        )
        .is_err());
        assert!(matches!(
            decode_status(&hex("FF FF 01 02 00 FD")),
            Err(CodecError::Checksum { .. })
        ));
    }

    #[test]
    fn splitter_resynchronises() {
        let good = hex("FF FF 01 03 00 20 DB");
        let mut s = Splitter::new();
        // Garbage, a packet with a bad checksum that hides a good one, then the good one split
        // across pushes.
        s.push(&hex("00 13 FF"));
        s.push(&hex("FF 07 05"));
        s.push(&good[..3]);
        let mut out = vec![];
        while let Some(x) = s.next_item() {
            out.push(x);
        }
        s.push(&good[3..]);
        while let Some(x) = s.next_item() {
            out.push(x);
        }
        let packets: Vec<&Split> = out
            .iter()
            .filter(|x| matches!(x, Split::Packet(_)))
            .collect();
        assert_eq!(packets, [&Split::Packet(good.clone())]);
        assert_eq!(s.pending(), 0);
        assert_eq!(s.stats().packets, 1);
    }
}
