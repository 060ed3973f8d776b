//! The stride Arduino link (`SPEC.md` in this crate, version 1.0): frames of type, sequence
//! number, length, payload and CRC-16/CCITT, COBS-encoded and delimited by `0x00`, and the
//! messages between the host and a joint-controller board. The codec is pure (no I/O); the
//! host side of a session (handshake, commands, heartbeats, what the board sends) over a
//! serial line is `stride-link-host`'s. The same codec exists in portable C
//! (`c/stride_link.h`, `c/stride_link.c`) for the firmware; the test suite checks the two
//! against each other.

/// Protocol version this codec speaks.
pub const MAJOR: u8 = 1;
/// Minor version.
pub const MINOR: u8 = 0;
/// Largest payload.
pub const MAX_PAYLOAD: usize = 240;
/// Largest encoded frame, delimiters included.
pub const MAX_ENCODED: usize = MAX_PAYLOAD + 9;

/// Message types.
pub mod kind {
    /// Host: start a session.
    pub const HELLO: u8 = 0x01;
    /// Host: still here.
    pub const HEARTBEAT: u8 = 0x02;
    /// Host: joint set-points.
    pub const COMMAND: u8 = 0x10;
    /// Board: session started.
    pub const HELLO_ACK: u8 = 0x81;
    /// Board: answer to a heartbeat.
    pub const HEARTBEAT_ACK: u8 = 0x82;
    /// Board: a frame refused.
    pub const NACK: u8 = 0x8f;
    /// Board: joint and driver state.
    pub const STATE: u8 = 0x90;
    /// Board: a raw MPU-6050 sample.
    pub const IMU: u8 = 0x91;
    /// Board: a fault.
    pub const FAULT: u8 = 0x92;
}

/// Fault bits (as in `stride.arduino_joint_state_t`).
pub mod fault {
    /// A driver's current above its limit.
    pub const OVER_CURRENT: u8 = 1;
    /// A driver too hot.
    pub const OVER_TEMPERATURE: u8 = 2;
    /// Commands stopped: motors braked.
    pub const WATCHDOG: u8 = 4;
    /// The driver reports a fault.
    pub const DRIVER: u8 = 8;
    /// Frames lost on the link.
    pub const LINK: u8 = 16;

    /// The faults set in `bits`, named, comma-separated.
    pub fn names(bits: u8) -> String {
        [
            (OVER_CURRENT, "over-current"),
            (OVER_TEMPERATURE, "over-temperature"),
            (WATCHDOG, "watchdog"),
            (DRIVER, "driver"),
            (LINK, "link"),
        ]
        .iter()
        .filter(|(b, _)| bits & b != 0)
        .map(|(_, n)| *n)
        .collect::<Vec<_>>()
        .join(", ")
    }
}

/// NACK reasons.
pub mod nack {
    /// Unknown message type.
    pub const TYPE: u8 = 1;
    /// Payload of the wrong size.
    pub const PAYLOAD: u8 = 2;
    /// A value beyond the board's limits.
    pub const RANGE: u8 = 3;
    /// Another major version.
    pub const VERSION: u8 = 4;
    /// A command before the handshake.
    pub const NO_HANDSHAKE: u8 = 5;
}

/// Why bytes are not a frame or a message.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum LinkError {
    /// COBS structure broken.
    #[error("bad COBS encoding")]
    Cobs,
    /// The length byte does not match the frame.
    #[error("length {len} does not match a {have}-byte frame")]
    Length {
        /// The length byte.
        len: usize,
        /// Decoded bytes.
        have: usize,
    },
    /// The CRC does not match.
    #[error("bad CRC: got {got:#06x}, computed {want:#06x}")]
    Crc {
        /// In the frame.
        got: u16,
        /// Computed.
        want: u16,
    },
    /// Longer than the protocol allows.
    #[error("frame too long")]
    TooLong,
    /// A type this codec does not know.
    #[error("unknown message type {0:#04x}")]
    UnknownType(u8),
    /// The payload does not fit the type.
    #[error("payload of {len} bytes does not fit message type {kind:#04x}")]
    Payload {
        /// Type.
        kind: u8,
        /// Payload length.
        len: usize,
    },
}

/// CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) of `data`, continuing from `crc`.
pub fn crc16(data: &[u8], mut crc: u16) -> u16 {
    for &b in data {
        crc ^= (b as u16) << 8;
        for _ in 0..8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ 0x1021
            } else {
                crc << 1
            };
        }
    }
    crc
}

/// COBS-encodes `data` (no delimiter).
pub fn cobs_encode(data: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(data.len() + data.len() / 254 + 2);
    let mut code_at = 0;
    out.push(0);
    let mut code = 1u8;
    for &b in data {
        if b == 0 {
            out[code_at] = code;
            code = 1;
            code_at = out.len();
            out.push(0);
        } else {
            out.push(b);
            code += 1;
            if code == 0xff {
                out[code_at] = code;
                code = 1;
                code_at = out.len();
                out.push(0);
            }
        }
    }
    out[code_at] = code;
    out
}

/// Decodes one COBS block (no delimiter).
pub fn cobs_decode(data: &[u8]) -> Result<Vec<u8>, LinkError> {
    let mut out = Vec::with_capacity(data.len());
    let mut i = 0;
    while i < data.len() {
        let code = data[i] as usize;
        i += 1;
        if code == 0 || i + code - 1 > data.len() {
            return Err(LinkError::Cobs);
        }
        out.extend_from_slice(&data[i..i + code - 1]);
        i += code - 1;
        if code != 0xff && i < data.len() {
            out.push(0);
        }
    }
    Ok(out)
}

/// A frame: type, sequence number and payload.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Frame {
    /// Message type.
    pub kind: u8,
    /// Sender's sequence number.
    pub seq: u8,
    /// Payload.
    pub payload: Vec<u8>,
}

impl Frame {
    /// The bytes on the wire: `0x00`, COBS of (type, seq, len, payload, CRC), `0x00`.
    pub fn encode(&self) -> Result<Vec<u8>, LinkError> {
        if self.payload.len() > MAX_PAYLOAD {
            return Err(LinkError::TooLong);
        }
        let mut raw = Vec::with_capacity(self.payload.len() + 5);
        raw.extend_from_slice(&[self.kind, self.seq, self.payload.len() as u8]);
        raw.extend_from_slice(&self.payload);
        let crc = crc16(&raw, 0xffff);
        raw.extend_from_slice(&crc.to_le_bytes());
        let mut out = Vec::with_capacity(raw.len() + 4);
        out.push(0);
        out.extend(cobs_encode(&raw));
        out.push(0);
        Ok(out)
    }

    /// Decodes the bytes between two delimiters.
    pub fn decode(block: &[u8]) -> Result<Frame, LinkError> {
        if block.len() > MAX_ENCODED {
            return Err(LinkError::TooLong);
        }
        let raw = cobs_decode(block)?;
        if raw.len() < 5 || raw[2] as usize + 5 != raw.len() {
            return Err(LinkError::Length {
                len: raw.get(2).copied().unwrap_or(0) as usize,
                have: raw.len(),
            });
        }
        let n = raw.len();
        let (got, want) = (
            u16::from_le_bytes([raw[n - 2], raw[n - 1]]),
            crc16(&raw[..n - 2], 0xffff),
        );
        if got != want {
            return Err(LinkError::Crc { got, want });
        }
        Ok(Frame {
            kind: raw[0],
            seq: raw[1],
            payload: raw[3..n - 2].to_vec(),
        })
    }
}

/// Counters of a decoder.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DecoderStats {
    /// Good frames.
    pub frames: u64,
    /// Frames dropped (bad COBS, length, CRC, too long).
    pub bad: u64,
    /// Frames a sender sent that never arrived (gaps in its sequence numbers).
    pub lost: u64,
}

/// Takes the line's bytes and gives whole frames; a bad frame costs only itself (the next
/// `0x00` starts afresh). Counts gaps in the peer's sequence numbers.
#[derive(Debug, Default)]
pub struct Decoder {
    buf: Vec<u8>,
    overflow: bool,
    stats: DecoderStats,
    last_seq: Option<u8>,
}

impl Decoder {
    /// A fresh decoder.
    pub fn new() -> Decoder {
        Decoder::default()
    }

    /// Counters so far.
    pub fn stats(&self) -> DecoderStats {
        self.stats
    }

    /// Forgets the peer's sequence (a new session).
    pub fn reset_sequence(&mut self) {
        self.last_seq = None;
    }

    /// Feeds bytes; returns the frames (and errors) they completed, in order.
    pub fn push(&mut self, bytes: &[u8]) -> Vec<Result<Frame, LinkError>> {
        let mut out = Vec::new();
        for &b in bytes {
            if b != 0 {
                if self.buf.len() < MAX_ENCODED {
                    self.buf.push(b);
                } else {
                    self.overflow = true;
                }
                continue;
            }
            if self.buf.is_empty() && !self.overflow {
                continue;
            }
            let r = if self.overflow {
                Err(LinkError::TooLong)
            } else {
                Frame::decode(&self.buf)
            };
            self.buf.clear();
            self.overflow = false;
            match &r {
                Ok(f) => {
                    self.stats.frames += 1;
                    if let Some(last) = self.last_seq {
                        self.stats.lost += f.seq.wrapping_sub(last).wrapping_sub(1) as u64;
                    }
                    self.last_seq = Some(f.seq);
                }
                Err(_) => self.stats.bad += 1,
            }
            out.push(r);
        }
        out
    }
}

/// One joint's set-point in a COMMAND.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct JointCommand {
    /// Joint index on the board.
    pub joint: u8,
    /// What to do.
    pub mode: Mode,
    /// Duty in 1/10000 (mode duty) or position in 1/10000 rad (mode position).
    pub value: i16,
}

/// COMMAND modes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Mode {
    /// Driver disabled, brake released.
    Coast,
    /// PWM duty, sign = direction.
    Duty,
    /// Brake engaged.
    Brake,
    /// The board's own position loop.
    Position,
}

impl Mode {
    /// Wire code.
    pub fn code(self) -> u8 {
        match self {
            Mode::Coast => 0,
            Mode::Duty => 1,
            Mode::Brake => 2,
            Mode::Position => 3,
        }
    }

    /// From the wire code.
    pub fn from_code(c: u8) -> Option<Mode> {
        Some(match c {
            0 => Mode::Coast,
            1 => Mode::Duty,
            2 => Mode::Brake,
            3 => Mode::Position,
            _ => return None,
        })
    }
}

/// One joint in a STATE.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct JointState {
    /// Position, 1e-5 rad.
    pub position: i32,
    /// Velocity, 1e-3 rad/s.
    pub velocity: i16,
    /// Current, mA.
    pub current: i16,
    /// Temperature, °C.
    pub temperature: i8,
    /// Duty applied, 1/10000.
    pub duty: i16,
    /// Bit 0: brake engaged; bits 1..: fault bits.
    pub flags: u8,
}

impl JointState {
    /// Position, rad.
    pub fn position_rad(&self) -> f64 {
        self.position as f64 * 1e-5
    }

    /// Velocity, rad/s.
    pub fn velocity_rad_s(&self) -> f64 {
        self.velocity as f64 * 1e-3
    }

    /// Current, A.
    pub fn current_a(&self) -> f64 {
        self.current as f64 / 1000.0
    }

    /// Duty applied, a fraction of full (-1 to 1).
    pub fn duty_fraction(&self) -> f64 {
        self.duty as f64 / 10_000.0
    }

    /// True while the brake is engaged.
    pub fn braked(&self) -> bool {
        self.flags & 1 != 0
    }

    /// The fault bits ([`fault`]), the flags without the brake's.
    pub fn faults(&self) -> u8 {
        self.flags >> 1
    }
}

impl JointCommand {
    /// The brake on `joint`.
    pub fn brake(joint: u8) -> JointCommand {
        JointCommand {
            joint,
            mode: Mode::Brake,
            value: 0,
        }
    }

    /// `joint`'s driver disabled, its brake released.
    pub fn coast(joint: u8) -> JointCommand {
        JointCommand {
            joint,
            mode: Mode::Coast,
            value: 0,
        }
    }

    /// A duty set-point: `fraction` of full (-1 to 1) in the wire's 1/10000; None beyond.
    pub fn duty(joint: u8, fraction: f64) -> Option<JointCommand> {
        wire_ten_thousandths(fraction).map(|value| JointCommand {
            joint,
            mode: Mode::Duty,
            value,
        })
    }

    /// A position set-point for the board's own loop: `rad` in the wire's 1/10000 rad
    /// (±3.2767 rad); None beyond.
    pub fn position(joint: u8, rad: f64) -> Option<JointCommand> {
        wire_ten_thousandths(rad).map(|value| JointCommand {
            joint,
            mode: Mode::Position,
            value,
        })
    }
}

/// `v` in 1/10000 as the wire's i16, or None when it does not fit (or is not finite).
fn wire_ten_thousandths(v: f64) -> Option<i16> {
    let x = (v * 10_000.0).round();
    (x.is_finite() && x >= i16::MIN as f64 && x <= i16::MAX as f64).then_some(x as i16)
}

/// The board's MPU-6050 at ±2 g and ±250 °/s, in SI units.
pub mod imu {
    /// Accelerometer counts per g.
    pub const ACCEL_COUNTS_PER_G: f64 = 16_384.0;
    /// Gyroscope counts per rad/s.
    pub const GYRO_COUNTS_PER_RAD_S: f64 = 131.0 * 180.0 / std::f64::consts::PI;
    /// Standard gravity, m/s².
    pub const G: f64 = 9.806_65;

    /// Acceleration, in g.
    pub fn accel_g(counts: [i16; 3]) -> [f64; 3] {
        counts.map(|a| a as f64 / ACCEL_COUNTS_PER_G)
    }

    /// Angular velocity, rad/s.
    pub fn gyro_rad_s(counts: [i16; 3]) -> [f64; 3] {
        counts.map(|g| g as f64 / GYRO_COUNTS_PER_RAD_S)
    }

    /// The die's temperature, °C (the MPU-6050's datasheet: counts / 340 + 36.53).
    pub fn temperature_c(counts: i16) -> f64 {
        counts as f64 / 340.0 + 36.53
    }
}

/// What HELLO_ACK says of the board.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct BoardInfo {
    /// Its protocol version.
    pub major: u8,
    /// Minor version.
    pub minor: u8,
    /// The HELLO's nonce, echoed.
    pub nonce: u32,
    /// Joints it drives.
    pub joints: u8,
    /// Its watchdog, ms.
    pub watchdog_ms: u16,
    /// Largest duty it accepts, 1/10000.
    pub max_duty: u16,
    /// Its current limit, mA.
    pub current_limit_ma: u16,
    /// Firmware name.
    pub firmware: String,
}

/// A message of the link.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum Message {
    /// Host: start a session.
    Hello {
        /// Version.
        major: u8,
        /// Minor version.
        minor: u8,
        /// Echoed by the board.
        nonce: u32,
    },
    /// Host: still here (ms).
    Heartbeat(u32),
    /// Host: joint set-points.
    Command(Vec<JointCommand>),
    /// Board: session started.
    HelloAck(BoardInfo),
    /// Board: answer to a heartbeat (board ms).
    HeartbeatAck(u32),
    /// Board: a frame refused.
    Nack {
        /// Its sequence number.
        seq: u8,
        /// Why (see [`nack`]).
        reason: u8,
    },
    /// Board: joint and driver state.
    State {
        /// Board time, ms.
        t_ms: u32,
        /// Sequence number of the last COMMAND applied.
        ack: u8,
        /// Per joint.
        joints: Vec<JointState>,
    },
    /// Board: a raw MPU-6050 sample.
    Imu {
        /// Board time, µs.
        t_us: u32,
        /// Accelerometer counts.
        accel: [i16; 3],
        /// Temperature counts.
        temperature: i16,
        /// Gyroscope counts.
        gyro: [i16; 3],
    },
    /// Board: a fault.
    Fault {
        /// Joint, or 0xFF for the board.
        joint: u8,
        /// Fault bits (see [`fault`]).
        bits: u8,
        /// E.g. the current, mA.
        detail: u16,
    },
}

struct Reader<'a> {
    p: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
        let b = self.p.get(self.at..self.at + N)?.try_into().ok()?;
        self.at += N;
        Some(b)
    }
    fn u8(&mut self) -> Option<u8> {
        self.take::<1>().map(|b| b[0])
    }
    fn i8(&mut self) -> Option<i8> {
        self.u8().map(|b| b as i8)
    }
    fn u16(&mut self) -> Option<u16> {
        self.take().map(u16::from_le_bytes)
    }
    fn i16(&mut self) -> Option<i16> {
        self.take().map(i16::from_le_bytes)
    }
    fn u32(&mut self) -> Option<u32> {
        self.take().map(u32::from_le_bytes)
    }
    fn i32(&mut self) -> Option<i32> {
        self.take().map(i32::from_le_bytes)
    }
    fn done(&self) -> bool {
        self.at == self.p.len()
    }
}

impl Message {
    /// Its type byte.
    pub fn kind(&self) -> u8 {
        match self {
            Message::Hello { .. } => kind::HELLO,
            Message::Heartbeat(_) => kind::HEARTBEAT,
            Message::Command(_) => kind::COMMAND,
            Message::HelloAck(_) => kind::HELLO_ACK,
            Message::HeartbeatAck(_) => kind::HEARTBEAT_ACK,
            Message::Nack { .. } => kind::NACK,
            Message::State { .. } => kind::STATE,
            Message::Imu { .. } => kind::IMU,
            Message::Fault { .. } => kind::FAULT,
        }
    }

    /// Its payload.
    pub fn payload(&self) -> Vec<u8> {
        let mut p = Vec::new();
        match self {
            Message::Hello {
                major,
                minor,
                nonce,
            } => {
                p.extend_from_slice(&[*major, *minor]);
                p.extend_from_slice(&nonce.to_le_bytes());
            }
            Message::Heartbeat(t) | Message::HeartbeatAck(t) => {
                p.extend_from_slice(&t.to_le_bytes())
            }
            Message::Command(joints) => {
                p.push(joints.len() as u8);
                for j in joints {
                    p.extend_from_slice(&[j.joint, j.mode.code()]);
                    p.extend_from_slice(&j.value.to_le_bytes());
                }
            }
            Message::HelloAck(b) => {
                p.extend_from_slice(&[b.major, b.minor]);
                p.extend_from_slice(&b.nonce.to_le_bytes());
                p.push(b.joints);
                p.extend_from_slice(&b.watchdog_ms.to_le_bytes());
                p.extend_from_slice(&b.max_duty.to_le_bytes());
                p.extend_from_slice(&b.current_limit_ma.to_le_bytes());
                let mut name = [0u8; 16];
                let n = b.firmware.len().min(16);
                name[..n].copy_from_slice(&b.firmware.as_bytes()[..n]);
                p.extend_from_slice(&name);
            }
            Message::Nack { seq, reason } => p.extend_from_slice(&[*seq, *reason]),
            Message::State { t_ms, ack, joints } => {
                p.extend_from_slice(&t_ms.to_le_bytes());
                p.extend_from_slice(&[*ack, joints.len() as u8]);
                for j in joints {
                    p.extend_from_slice(&j.position.to_le_bytes());
                    p.extend_from_slice(&j.velocity.to_le_bytes());
                    p.extend_from_slice(&j.current.to_le_bytes());
                    p.push(j.temperature as u8);
                    p.extend_from_slice(&j.duty.to_le_bytes());
                    p.push(j.flags);
                }
            }
            Message::Imu {
                t_us,
                accel,
                temperature,
                gyro,
            } => {
                p.extend_from_slice(&t_us.to_le_bytes());
                for v in accel.iter().chain([temperature]).chain(gyro) {
                    p.extend_from_slice(&v.to_le_bytes());
                }
            }
            Message::Fault {
                joint,
                bits,
                detail,
            } => {
                p.extend_from_slice(&[*joint, *bits]);
                p.extend_from_slice(&detail.to_le_bytes());
            }
        }
        p
    }

    /// The frame carrying it with sequence number `seq`.
    pub fn frame(&self, seq: u8) -> Frame {
        Frame {
            kind: self.kind(),
            seq,
            payload: self.payload(),
        }
    }

    /// Reads a frame's message.
    pub fn parse(f: &Frame) -> Result<Message, LinkError> {
        let bad = || LinkError::Payload {
            kind: f.kind,
            len: f.payload.len(),
        };
        let mut r = Reader {
            p: &f.payload,
            at: 0,
        };
        let m = (|| {
            Some(match f.kind {
                kind::HELLO => Message::Hello {
                    major: r.u8()?,
                    minor: r.u8()?,
                    nonce: r.u32()?,
                },
                kind::HEARTBEAT => Message::Heartbeat(r.u32()?),
                kind::HEARTBEAT_ACK => Message::HeartbeatAck(r.u32()?),
                kind::COMMAND => {
                    let n = r.u8()?;
                    let mut joints = Vec::with_capacity(n as usize);
                    for _ in 0..n {
                        joints.push(JointCommand {
                            joint: r.u8()?,
                            mode: Mode::from_code(r.u8()?)?,
                            value: r.i16()?,
                        });
                    }
                    Message::Command(joints)
                }
                kind::HELLO_ACK => {
                    let (major, minor, nonce, joints) = (r.u8()?, r.u8()?, r.u32()?, r.u8()?);
                    let (watchdog_ms, max_duty, current_limit_ma) = (r.u16()?, r.u16()?, r.u16()?);
                    let name = r.take::<16>()?;
                    let end = name.iter().position(|&b| b == 0).unwrap_or(16);
                    Message::HelloAck(BoardInfo {
                        major,
                        minor,
                        nonce,
                        joints,
                        watchdog_ms,
                        max_duty,
                        current_limit_ma,
                        firmware: String::from_utf8_lossy(&name[..end]).into_owned(),
                    })
                }
                kind::NACK => Message::Nack {
                    seq: r.u8()?,
                    reason: r.u8()?,
                },
                kind::STATE => {
                    let (t_ms, ack, n) = (r.u32()?, r.u8()?, r.u8()?);
                    let mut joints = Vec::with_capacity(n as usize);
                    for _ in 0..n {
                        joints.push(JointState {
                            position: r.i32()?,
                            velocity: r.i16()?,
                            current: r.i16()?,
                            temperature: r.i8()?,
                            duty: r.i16()?,
                            flags: r.u8()?,
                        });
                    }
                    Message::State { t_ms, ack, joints }
                }
                kind::IMU => Message::Imu {
                    t_us: r.u32()?,
                    accel: [r.i16()?, r.i16()?, r.i16()?],
                    temperature: r.i16()?,
                    gyro: [r.i16()?, r.i16()?, r.i16()?],
                },
                kind::FAULT => Message::Fault {
                    joint: r.u8()?,
                    bits: r.u8()?,
                    detail: r.u16()?,
                },
                _ => return None,
            })
        })();
        match m {
            Some(m) if r.done() => Ok(m),
            _ if !KNOWN.contains(&f.kind) => Err(LinkError::UnknownType(f.kind)),
            _ => Err(bad()),
        }
    }
}

const KNOWN: [u8; 9] = [
    kind::HELLO,
    kind::HEARTBEAT,
    kind::COMMAND,
    kind::HELLO_ACK,
    kind::HEARTBEAT_ACK,
    kind::NACK,
    kind::STATE,
    kind::IMU,
    kind::FAULT,
];

#[cfg(test)]
mod tests {
    use super::*;

    fn hex(s: &str) -> Vec<u8> {
        s.split_whitespace()
            .map(|b| u8::from_str_radix(b, 16).unwrap())
            .collect()
    }

    #[test]
    fn spec_vectors() {
        assert_eq!(crc16(b"123456789", 0xffff), 0x29b1);
        let hello = Message::Hello {
            major: 1,
            minor: 0,
            nonce: 0x1234_5678,
        }
        .frame(0);
        let wire = hello.encode().unwrap();
        assert_eq!(wire, hex("00 02 01 03 06 01 07 78 56 34 12 2E C7 00"));
        assert_eq!(Frame::decode(&wire[1..wire.len() - 1]).unwrap(), hello);
        // COBS: the standard examples.
        assert_eq!(cobs_encode(&[0x00]), [0x01, 0x01]);
        assert_eq!(
            cobs_encode(&[0x11, 0x22, 0x00, 0x33]),
            [0x03, 0x11, 0x22, 0x02, 0x33]
        );
        assert_eq!(
            cobs_encode(&[0x11, 0x00, 0x00, 0x00]),
            [0x02, 0x11, 0x01, 0x01, 0x01]
        );
        let long: Vec<u8> = (1..=254).collect();
        let mut want = vec![0xff];
        want.extend(&long);
        want.push(0x01);
        assert_eq!(cobs_encode(&long), want);
        assert_eq!(cobs_decode(&want).unwrap(), long);
    }

    #[test]
    fn messages_round_trip() {
        let msgs = [
            Message::Heartbeat(7),
            Message::Command(vec![
                JointCommand {
                    joint: 0,
                    mode: Mode::Duty,
                    value: -2500,
                },
                JointCommand {
                    joint: 5,
                    mode: Mode::Brake,
                    value: 0,
                },
            ]),
            Message::HelloAck(BoardInfo {
                major: 1,
                minor: 0,
                nonce: 9,
                joints: 6,
                watchdog_ms: 100,
                max_duty: 9000,
                current_limit_ma: 8000,
                firmware: "stride-due 1.0".into(),
            }),
            Message::State {
                t_ms: 1000,
                ack: 3,
                joints: vec![
                    JointState {
                        position: -150_000,
                        velocity: 12,
                        current: 800,
                        temperature: 35,
                        duty: 2500,
                        flags: 1
                    };
                    6
                ],
            },
            Message::Imu {
                t_us: 5,
                accel: [0, 0, 16384],
                temperature: -521,
                gyro: [1, -1, 0],
            },
            Message::Fault {
                joint: 2,
                bits: fault::OVER_CURRENT,
                detail: 9100,
            },
            Message::Nack {
                seq: 4,
                reason: nack::RANGE,
            },
        ];
        for m in msgs {
            let f = m.frame(200);
            let wire = f.encode().unwrap();
            assert!(!wire[1..wire.len() - 1].contains(&0));
            let back = Frame::decode(&wire[1..wire.len() - 1]).unwrap();
            assert_eq!(Message::parse(&back).unwrap(), m);
        }
        let short = Frame {
            kind: kind::STATE,
            seq: 0,
            payload: vec![1, 2],
        };
        assert!(matches!(
            Message::parse(&short),
            Err(LinkError::Payload { .. })
        ));
        let odd = Frame {
            kind: 0x55,
            seq: 0,
            payload: vec![],
        };
        assert_eq!(Message::parse(&odd), Err(LinkError::UnknownType(0x55)));
    }

    #[test]
    fn decoder_counts_losses_and_survives_garbage() {
        let mut d = Decoder::new();
        let mut bytes = vec![0x42, 0x13, 0x00]; // garbage, ended by a delimiter
        for seq in [1u8, 2, 5] {
            bytes.extend(Message::Heartbeat(seq as u32).frame(seq).encode().unwrap());
        }
        let out = d.push(&bytes);
        assert_eq!(out.iter().filter(|r| r.is_ok()).count(), 3);
        assert_eq!(
            d.stats(),
            DecoderStats {
                frames: 3,
                bad: 1,
                lost: 2
            }
        );
    }
}
