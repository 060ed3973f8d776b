//! Elmo drives: the binary interpreter carried by PDO2, and the PT/PVT motion objects
//! (0x2001 PVT rows, 0x2002 PT points) with the table pointers the host tracks.

use crate::frame::{CanFrame, CobId, FrameError, Function, NodeId};

/// A binary-interpreter value: integer or float.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Value {
    /// A 32-bit integer.
    Int(i32),
    /// A 32-bit float.
    Float(f32),
}

/// A binary-interpreter command: two letters, an array index, and a value to set or a query.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Command {
    /// The two command letters, e.g. `*b"MO"`.
    pub name: [u8; 2],
    /// The array index (0 for scalar commands), 0..=16383.
    pub index: u16,
    /// `Some` to set, `None` to query.
    pub value: Option<Value>,
}

impl Command {
    /// `NAME[index]=value`.
    pub fn set(name: &[u8; 2], index: u16, value: Value) -> Command {
        Command {
            name: *name,
            index,
            value: Some(value),
        }
    }

    /// `NAME[index]` (query).
    pub fn get(name: &[u8; 2], index: u16) -> Command {
        Command {
            name: *name,
            index,
            value: None,
        }
    }

    /// The 8 data bytes of the RPDO2 message.
    pub fn bytes(&self) -> Result<[u8; 8], FrameError> {
        if self.index > 0x3fff || !self.name.iter().all(u8::is_ascii_uppercase) {
            return Err(FrameError::Unexpected("bad interpreter command"));
        }
        let mut d = [0u8; 8];
        d[..2].copy_from_slice(&self.name);
        d[2] = self.index as u8;
        d[3] = (self.index >> 8) as u8 & 0x3f;
        match self.value {
            None => d[3] |= 0x40,
            Some(Value::Int(v)) => d[4..].copy_from_slice(&v.to_le_bytes()),
            Some(Value::Float(v)) => {
                d[3] |= 0x80;
                d[4..].copy_from_slice(&v.to_le_bytes());
            }
        }
        Ok(d)
    }

    /// The RPDO2 frame to `node` (0x300 + node).
    pub fn encode(&self, node: NodeId) -> Result<CanFrame, FrameError> {
        Ok(CanFrame::standard(
            CobId::of(Function::Rpdo(2), node).raw(),
            &self.bytes()?,
        )?)
    }

    /// Reads a command (as a drive does).
    pub fn decode(data: &[u8]) -> Result<Command, FrameError> {
        if data.len() < 4 {
            return Err(FrameError::short(4, data.len()));
        }
        let name = [data[0], data[1]];
        let index = data[2] as u16 | ((data[3] & 0x3f) as u16) << 8;
        let value = if data[3] & 0x40 != 0 {
            None
        } else {
            if data.len() < 8 {
                return Err(FrameError::short(8, data.len()));
            }
            let raw = [data[4], data[5], data[6], data[7]];
            Some(if data[3] & 0x80 != 0 {
                Value::Float(f32::from_le_bytes(raw))
            } else {
                Value::Int(i32::from_le_bytes(raw))
            })
        };
        Ok(Command { name, index, value })
    }
}

/// The drive's answer on TPDO2 (0x280 + node).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reply {
    /// The command letters answered.
    pub name: [u8; 2],
    /// The array index.
    pub index: u16,
    /// The value, or the Elmo error code (as `EC` reports it) when the command failed.
    pub result: Result<Value, u32>,
}

impl Reply {
    /// Reads a TPDO2 payload.
    pub fn decode(data: &[u8]) -> Result<Reply, FrameError> {
        if data.len() < 8 {
            return Err(FrameError::short(8, data.len()));
        }
        let raw = [data[4], data[5], data[6], data[7]];
        let result = if data[3] & 0x40 != 0 {
            Err(u32::from_le_bytes(raw))
        } else if data[3] & 0x80 != 0 {
            Ok(Value::Float(f32::from_le_bytes(raw)))
        } else {
            Ok(Value::Int(i32::from_le_bytes(raw)))
        };
        Ok(Reply {
            name: [data[0], data[1]],
            index: data[2] as u16 | ((data[3] & 0x3f) as u16) << 8,
            result,
        })
    }

    /// The TPDO2 payload (as a drive sends it).
    pub fn bytes(&self) -> [u8; 8] {
        let mut d = [0u8; 8];
        d[..2].copy_from_slice(&self.name);
        d[2] = self.index as u8;
        d[3] = (self.index >> 8) as u8 & 0x3f;
        match self.result {
            Ok(Value::Int(v)) => d[4..].copy_from_slice(&v.to_le_bytes()),
            Ok(Value::Float(v)) => {
                d[3] |= 0x80;
                d[4..].copy_from_slice(&v.to_le_bytes());
            }
            Err(code) => {
                d[3] |= 0x40;
                d[4..].copy_from_slice(&code.to_le_bytes());
            }
        }
        d
    }
}

/// PVT row object (0x2001): written through an RPDO.
pub const PVT_OBJECT: u16 = 0x2001;
/// PT data object (0x2002): two positions per message.
pub const PT_OBJECT: u16 = 0x2002;
/// Table rows of the PVT buffer.
pub const PVT_ROWS: u16 = 64;
/// The table's write pointer (0x2F11), readable through a PDO.
pub const WRITE_POINTER: u16 = 0x2f11;
/// The table's read pointer (0x2F12), readable only through a PDO.
pub const READ_POINTER: u16 = 0x2f12;
/// The largest PVT velocity, counts/s: the field is 24 bits, signed.
pub const PVT_MAX_VELOCITY: i32 = (1 << 23) - 1;

/// One PVT row: position (counts), velocity (counts/s, 24 bits), time to the next row (ms).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct PvtRow {
    /// Position, encoder counts.
    pub position: i32,
    /// Velocity, counts per second, within ±2^23.
    pub velocity: i32,
    /// Time to the next row, 1..=255 ms.
    pub time_ms: u8,
}

impl PvtRow {
    /// The 8 bytes of object 0x2001: position (32 bits), velocity (24 bits), time (8 bits).
    pub fn bytes(&self) -> Result<[u8; 8], FrameError> {
        if !(-(1 << 23)..(1 << 23)).contains(&self.velocity) {
            return Err(FrameError::Unexpected("PVT velocity does not fit 24 bits"));
        }
        if self.time_ms == 0 {
            return Err(FrameError::Unexpected("PVT time must be 1..=255 ms"));
        }
        let mut d = [0u8; 8];
        d[..4].copy_from_slice(&self.position.to_le_bytes());
        d[4..7].copy_from_slice(&self.velocity.to_le_bytes()[..3]);
        d[7] = self.time_ms;
        Ok(d)
    }

    /// The row as the frame of the RPDO `cob` that maps object 0x2001.
    pub fn frame(&self, cob: u16) -> Result<CanFrame, FrameError> {
        Ok(CanFrame::standard(cob, &self.bytes()?)?)
    }

    /// Reads object 0x2001's bytes (sign-extending the 24-bit velocity).
    pub fn from_bytes(d: &[u8; 8]) -> PvtRow {
        let v = i32::from_le_bytes([d[4], d[5], d[6], if d[6] & 0x80 != 0 { 0xff } else { 0 }]);
        PvtRow {
            position: i32::from_le_bytes([d[0], d[1], d[2], d[3]]),
            velocity: v,
            time_ms: d[7],
        }
    }
}

/// Two PT positions for object 0x2002.
pub fn pt_bytes(first: i32, second: i32) -> [u8; 8] {
    let mut d = [0u8; 8];
    d[..4].copy_from_slice(&first.to_le_bytes());
    d[4..].copy_from_slice(&second.to_le_bytes());
    d
}

/// Two PT positions as the frame of the RPDO `cob` that maps object 0x2002.
pub fn pt_frame(cob: u16, first: i32, second: i32) -> CanFrame {
    CanFrame::standard(cob, &pt_bytes(first, second)).expect("an RPDO identifier")
}

/// The host's view of a drive's PVT ring: rows written, rows executed, room left.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PvtQueue {
    rows: u16,
    written: u64,
    executed: u64,
}

impl PvtQueue {
    /// A ring of `rows` rows (64 on Elmo drives).
    pub fn new(rows: u16) -> PvtQueue {
        PvtQueue {
            rows,
            written: 0,
            executed: 0,
        }
    }

    /// Rows written but not yet executed.
    pub fn pending(&self) -> u64 {
        self.written - self.executed
    }

    /// Rows that can be written without overrunning the drive.
    pub fn room(&self) -> u64 {
        self.rows as u64 - self.pending()
    }

    /// Counts a written row; its 1-based table index (the drive's write pointer after it).
    pub fn push(&mut self) -> Option<u16> {
        if self.room() == 0 {
            return None;
        }
        self.written += 1;
        Some(((self.written - 1) % self.rows as u64) as u16 + 1)
    }

    /// The 1-based table index of the next row to execute (`PV=n` / `PT=n` before `BG`).
    pub fn read_index(&self) -> u16 {
        (self.executed % self.rows as u64) as u16 + 1
    }

    /// Counts every written row as executed (the drive ended the motion: what was left is
    /// dropped); the write index carries on.
    pub fn drain(&mut self) {
        self.executed = self.written;
    }

    /// The 1-based table index the next row written lands at (the drive's write pointer, as
    /// its emergencies report it).
    pub fn write_index(&self) -> u16 {
        (self.written % self.rows as u64) as u16 + 1
    }

    /// Updates from the drive's read pointer (1-based table index of the next row it will
    /// execute), as reported in a TPDO or a queue-low emergency. A pointer that would mean
    /// rows executed that were never written is a report from before the last rows went in
    /// (the previous motion's last row, a frame in flight): it is ignored, never taken as a
    /// wrap of the ring.
    pub fn on_read_pointer(&mut self, read: u16) {
        let rows = self.rows as u64;
        let base = self.executed - self.executed % rows;
        let mut executed = base + (read.max(1) as u64 - 1) % rows;
        if executed < self.executed {
            executed += rows;
        }
        if executed <= self.written {
            self.executed = executed;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stale_read_pointer_from_the_last_motion_is_not_taken_for_a_wrap() {
        let mut q = PvtQueue::new(64);
        for _ in 0..10 {
            q.push();
        }
        // The drive ends the motion on its last row (index 10) and the host drains.
        q.on_read_pointer(10);
        assert_eq!(q.pending(), 1);
        q.drain();
        for _ in 0..5 {
            q.push();
        }
        // A state sent before the next start still shows the old last row: five rows wait.
        q.on_read_pointer(10);
        assert_eq!(q.pending(), 5);
        assert_eq!(q.room(), 59);
        // The next motion plays from index 11 on.
        q.on_read_pointer(13);
        assert_eq!(q.pending(), 3);
        assert_eq!(q.write_index(), 16);
    }

    #[test]
    fn manual_examples() {
        // CA[18]=4096 -> 43 41 12 00 00 10 00 00 (Elmo DS301 guide, ch. 9).
        let c = Command::set(b"CA", 18, Value::Int(4096));
        assert_eq!(
            c.bytes().unwrap(),
            [0x43, 0x41, 0x12, 0x00, 0x00, 0x10, 0x00, 0x00]
        );
        // Query ET[992] -> 45 54 E0 43 00 00 00 00.
        let q = Command::get(b"ET", 992);
        assert_eq!(q.bytes().unwrap(), [0x45, 0x54, 0xe0, 0x43, 0, 0, 0, 0]);
        // Reply 45 54 E0 03 79 7D 00 00 = 32121.
        let r = Reply::decode(&[0x45, 0x54, 0xe0, 0x03, 0x79, 0x7d, 0x00, 0x00]).unwrap();
        assert_eq!(
            (r.name, r.index, r.result),
            (*b"ET", 992, Ok(Value::Int(32121)))
        );
        assert_eq!(Command::decode(&c.bytes().unwrap()).unwrap(), c);
        assert_eq!(Command::decode(&q.bytes().unwrap()).unwrap(), q);
        let f = c.encode(NodeId::new(4).unwrap()).unwrap();
        assert_eq!(f.raw_id(), 0x304);
    }

    #[test]
    fn floats_and_errors() {
        let c = Command::set(b"SP", 0, Value::Float(1.5));
        let b = c.bytes().unwrap();
        assert_eq!(b[3], 0x80);
        assert_eq!(Command::decode(&b).unwrap(), c);
        let r = Reply {
            name: *b"BG",
            index: 0,
            result: Err(21),
        };
        assert_eq!(Reply::decode(&r.bytes()).unwrap(), r);
        assert!(Command::set(b"mo", 0, Value::Int(1)).bytes().is_err());
        assert!(Command::get(b"MO", 0x4000).bytes().is_err());
        assert!(Reply::decode(&[0; 7]).is_err());
    }

    #[test]
    fn pvt_rows_and_queue() {
        let row = PvtRow {
            position: -1000,
            velocity: -2000,
            time_ms: 10,
        };
        let b = row.bytes().unwrap();
        assert_eq!(b, [0x18, 0xfc, 0xff, 0xff, 0x30, 0xf8, 0xff, 10]);
        assert_eq!(PvtRow::from_bytes(&b), row);
        assert!(PvtRow {
            velocity: 1 << 23,
            ..row
        }
        .bytes()
        .is_err());
        assert!(PvtRow { time_ms: 0, ..row }.bytes().is_err());
        assert_eq!(pt_bytes(1, -1), [1, 0, 0, 0, 0xff, 0xff, 0xff, 0xff]);

        let mut q = PvtQueue::new(PVT_ROWS);
        for i in 1..=64 {
            assert_eq!(q.push(), Some(i));
        }
        assert_eq!(q.push(), None);
        q.on_read_pointer(11); // rows 1..=10 executed
        assert_eq!((q.pending(), q.room()), (54, 10));
        for _ in 0..10 {
            q.push().unwrap();
        }
        q.on_read_pointer(5); // wrapped: 64 + 4 executed
        assert_eq!(q.pending(), 74 - 68);
        assert_eq!(q.read_index(), 5);
        // The drive ended the motion: the next one starts where the write pointer is.
        q.drain();
        assert_eq!((q.pending(), q.read_index()), (0, 11));
        assert_eq!(q.push(), Some(11));
    }
}
