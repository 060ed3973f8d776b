//! EMCY: emergency messages (COB-ID 0x080 + node), with CiA 301's error classes and Elmo's
//! manufacturer-specific PVT/PT codes.

use crate::frame::{CanFrame, CobId, FrameError, Function, NodeId};

/// A decoded emergency message.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Emcy {
    /// The node that sent it.
    pub node: NodeId,
    /// The 16-bit emergency error code (0x0000: error reset).
    pub code: u16,
    /// The error register (object 0x1001).
    pub register: u8,
    /// The five manufacturer-specific bytes.
    pub manufacturer: [u8; 5],
}

impl Emcy {
    /// Error reset or no error: sent when an error condition clears.
    pub const ERROR_RESET: u16 = 0x0000;
    /// Life guard or heartbeat error: a heartbeat the node consumes timed out.
    pub const HEARTBEAT_ERROR: u16 = 0x8130;
    /// Following error (CiA 402).
    pub const FOLLOWING_ERROR: u16 = 0x8611;
    /// A PDO not processed because of its length (CiA 301).
    pub const PDO_LENGTH: u16 = 0x8210;

    /// The "error reset" a node sends when its error condition clears (register as it is
    /// after the reset, usually 0).
    pub fn error_reset(node: NodeId, register: u8) -> Emcy {
        Emcy {
            node,
            code: Self::ERROR_RESET,
            register,
            manufacturer: [0; 5],
        }
    }

    /// Encodes the message.
    pub fn encode(&self) -> CanFrame {
        let mut d = [0u8; 8];
        d[..2].copy_from_slice(&self.code.to_le_bytes());
        d[2] = self.register;
        d[3..].copy_from_slice(&self.manufacturer);
        CanFrame::standard(CobId::of(Function::Emcy, self.node).raw(), &d).expect("valid EMCY")
    }

    /// Decodes an EMCY frame.
    pub fn decode(frame: &CanFrame) -> Result<Emcy, FrameError> {
        let cob = CobId::parse(frame.raw_id() as u16)
            .filter(|c| c.function == Function::Emcy && !frame.is_extended())
            .ok_or(FrameError::Unexpected("not an EMCY frame"))?;
        let d = frame.data_at_least(8)?;
        let mut manufacturer = [0u8; 5];
        manufacturer.copy_from_slice(&d[3..8]);
        Ok(Emcy {
            node: cob.node.expect("EMCY has a node"),
            code: u16::from_le_bytes([d[0], d[1]]),
            register: d[2],
            manufacturer,
        })
    }

    /// What the code means, in words (CiA 301 classes; Elmo's codes for 0xFF00).
    pub fn describe(&self) -> String {
        if let Some(e) = ElmoEmcy::from_emcy(self) {
            return e.to_string();
        }
        describe_code(self.code).to_owned()
    }
}

/// The CiA 301 meaning of an emergency error code.
pub fn describe_code(code: u16) -> &'static str {
    match code {
        0x0000 => "error reset or no error",
        0x8110 => "CAN overrun (objects lost)",
        0x8120 => "CAN in error passive mode",
        0x8130 => "life guard or heartbeat error",
        0x8140 => "recovered from bus off",
        0x8150 => "CAN-ID collision",
        Emcy::PDO_LENGTH => "PDO not processed due to length error",
        0x8220 => "PDO length exceeded",
        0x8240 => "unexpected SYNC data length",
        0x8250 => "RPDO timeout",
        c => match c & 0xff00 {
            0x1000 => "generic error",
            0x2000 | 0x2100 | 0x2200 | 0x2300 => "current",
            0x3000 | 0x3100 | 0x3200 | 0x3300 => "voltage",
            0x4000 | 0x4100 | 0x4200 | 0x4300 => "temperature",
            0x5000 | 0x5100 | 0x5200 | 0x5300 | 0x5400 | 0x5500 => "device hardware",
            0x6000 | 0x6100 | 0x6200 | 0x6300 => "device software",
            0x7000 | 0x7100 | 0x7200 | 0x7300 => "additional modules",
            0x8000 | 0x8100 | 0x8200 | 0x8300 | 0x8400 | 0x8500 | 0x8600 | 0x8700 | 0x8800 => {
                "monitoring / communication"
            }
            0x9000 => "external error",
            0xf000 => "additional functions",
            0xff00 => "device specific",
            _ => "unknown error code",
        },
    }
}

/// Elmo's manufacturer-specific emergencies of PVT/PT motion (code 0xFF00, register 0x81,
/// Elmo code in byte 3, two 16-bit data fields after it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ElmoEmcy {
    /// 0x56: fewer unexecuted rows than MP[4]: a refill request.
    QueueLow {
        /// Write pointer.
        write: u16,
        /// Read pointer.
        read: u16,
    },
    /// 0x5B: write pointer outside the table (bad MP[6]).
    BadHeadPointer {
        /// The value of MP[6].
        mp6: u16,
    },
    /// 0x5C: the PDO 0x3xx is not mapped.
    PdoNotMapped,
    /// 0x34: more points than the queue holds.
    QueueFull {
        /// Table index that could not be programmed.
        index: u16,
    },
    /// 0x07: motion could not start (write pointer outside start..end).
    BadModeInit,
    /// 0x08: mode terminated, motor stopped.
    MotionTerminated {
        /// Write pointer.
        write: u16,
        /// 1: end of trajectory, 2: zero or negative time, 3: read reached write (underflow).
        reason: u16,
    },
    /// 0x09: a CAN message was lost.
    MessageLost,
    /// Another Elmo code.
    Other {
        /// Elmo's code.
        code: u8,
        /// Data field 1.
        field1: u16,
        /// Data field 2.
        field2: u16,
    },
}

impl ElmoEmcy {
    /// Reads Elmo's code from an EMCY with error code 0xFF00.
    pub fn from_emcy(e: &Emcy) -> Option<ElmoEmcy> {
        if e.code != 0xff00 {
            return None;
        }
        let m = e.manufacturer;
        let f1 = u16::from_le_bytes([m[1], m[2]]);
        let f2 = u16::from_le_bytes([m[3], m[4]]);
        Some(match m[0] {
            0x56 => ElmoEmcy::QueueLow {
                write: f1,
                read: f2,
            },
            0x5b => ElmoEmcy::BadHeadPointer { mp6: f1 },
            0x5c => ElmoEmcy::PdoNotMapped,
            0x34 => ElmoEmcy::QueueFull { index: f1 },
            0x07 => ElmoEmcy::BadModeInit,
            0x08 => ElmoEmcy::MotionTerminated {
                write: f1,
                reason: f2,
            },
            0x09 => ElmoEmcy::MessageLost,
            code => ElmoEmcy::Other {
                code,
                field1: f1,
                field2: f2,
            },
        })
    }

    /// The EMCY a drive sends for this event.
    pub fn to_emcy(self, node: NodeId) -> Emcy {
        let (code, f1, f2) = match self {
            ElmoEmcy::QueueLow { write, read } => (0x56, write, read),
            ElmoEmcy::BadHeadPointer { mp6 } => (0x5b, mp6, 0),
            ElmoEmcy::PdoNotMapped => (0x5c, 0, 0),
            ElmoEmcy::QueueFull { index } => (0x34, index, 0),
            ElmoEmcy::BadModeInit => (0x07, 0, 0),
            ElmoEmcy::MotionTerminated { write, reason } => (0x08, write, reason),
            ElmoEmcy::MessageLost => (0x09, 0, 0),
            ElmoEmcy::Other {
                code,
                field1,
                field2,
            } => (code, field1, field2),
        };
        let [a, b] = f1.to_le_bytes();
        let [c, d] = f2.to_le_bytes();
        Emcy {
            node,
            code: 0xff00,
            register: 0x81,
            manufacturer: [code, a, b, c, d],
        }
    }

    /// True when the drive asks for more trajectory rows (queue low, or stopped because the
    /// read pointer caught up with the write pointer).
    pub fn is_refill_request(&self) -> bool {
        matches!(
            self,
            ElmoEmcy::QueueLow { .. } | ElmoEmcy::MotionTerminated { reason: 3, .. }
        )
    }
}

impl std::fmt::Display for ElmoEmcy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ElmoEmcy::QueueLow { write, read } => {
                write!(f, "PVT queue low (write {write}, read {read})")
            }
            ElmoEmcy::BadHeadPointer { mp6 } => {
                write!(f, "PVT write pointer out of range (MP[6]={mp6})")
            }
            ElmoEmcy::PdoNotMapped => write!(f, "PDO 0x3xx not mapped"),
            ElmoEmcy::QueueFull { index } => write!(f, "PVT queue full (row {index})"),
            ElmoEmcy::BadModeInit => write!(f, "cannot start motion: bad PVT setup"),
            ElmoEmcy::MotionTerminated { write, reason } => write!(
                f,
                "motion terminated, motor stopped (write {write}, {})",
                match reason {
                    1 => "end of trajectory",
                    2 => "zero or negative time",
                    3 => "queue underflow",
                    _ => "unknown reason",
                }
            ),
            ElmoEmcy::MessageLost => write!(f, "a CAN message was lost"),
            ElmoEmcy::Other { code, .. } => write!(f, "Elmo emergency {code:#04x}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn golden_emcy() {
        let n = NodeId::new(2).unwrap();
        // Heartbeat error reported by node 2: 30 81 11 00 00 00 00 00 on 0x082.
        let f = CanFrame::standard(0x082, &[0x30, 0x81, 0x11, 0, 0, 0, 0, 0]).unwrap();
        let e = Emcy::decode(&f).unwrap();
        assert_eq!((e.node, e.code, e.register), (n, 0x8130, 0x11));
        assert_eq!(e.encode(), f);
        assert_eq!(e.describe(), "life guard or heartbeat error");
        assert_eq!(describe_code(0x2310), "current");
    }

    #[test]
    fn elmo_queue_low_is_a_refill_request() {
        let n = NodeId::new(1).unwrap();
        let e = ElmoEmcy::QueueLow {
            write: 40,
            read: 35,
        }
        .to_emcy(n);
        let f = e.encode();
        assert_eq!(f.data(), [0x00, 0xff, 0x81, 0x56, 40, 0, 35, 0]);
        let back = ElmoEmcy::from_emcy(&Emcy::decode(&f).unwrap()).unwrap();
        assert!(back.is_refill_request());
        assert!(ElmoEmcy::MotionTerminated {
            write: 9,
            reason: 3
        }
        .is_refill_request());
        assert!(!ElmoEmcy::QueueFull { index: 3 }.is_refill_request());
        assert!(Emcy::decode(&CanFrame::standard(0x081, &[0; 7]).unwrap()).is_err());
    }
}
