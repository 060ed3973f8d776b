//! CiA 402 (DS402) drives: the power state machine from statusword and controlword, modes of
//! operation, and the objects the host uses.

/// Controlword (0x6040).
pub const CONTROLWORD: u16 = 0x6040;
/// Statusword (0x6041).
pub const STATUSWORD: u16 = 0x6041;
/// Quick stop option code (0x605A).
pub const QUICK_STOP_OPTION: u16 = 0x605a;
/// Modes of operation (0x6060).
pub const MODES_OF_OPERATION: u16 = 0x6060;
/// Modes of operation display (0x6061).
pub const MODES_DISPLAY: u16 = 0x6061;
/// Position actual value (0x6064).
pub const POSITION_ACTUAL: u16 = 0x6064;
/// Following error actual value (0x60F4).
pub const FOLLOWING_ERROR: u16 = 0x60f4;
/// Velocity actual value (0x606C).
pub const VELOCITY_ACTUAL: u16 = 0x606c;
/// Target position (0x607A).
pub const TARGET_POSITION: u16 = 0x607a;
/// Interpolation sub-mode select (0x60C0): 0 linear, -1 cubic (Elmo: PVT-like).
pub const IP_SUBMODE: u16 = 0x60c0;
/// Interpolation data record (0x60C1): sub 1 position, sub 2 velocity (cubic).
pub const IP_DATA: u16 = 0x60c1;
/// Interpolation time period (0x60C2): sub 1 value, sub 2 exponent (Elmo: always ms).
pub const IP_PERIOD: u16 = 0x60c2;
/// Interpolation data configuration (0x60C4): buffer sizes.
pub const IP_BUFFER: u16 = 0x60c4;
/// Profile velocity (0x6081), counts/s.
pub const PROFILE_VELOCITY: u16 = 0x6081;
/// Profile acceleration (0x6083), counts/s².
pub const PROFILE_ACCELERATION: u16 = 0x6083;
/// Profile deceleration (0x6084), counts/s².
pub const PROFILE_DECELERATION: u16 = 0x6084;
/// Following error window (0x6065), counts.
pub const FOLLOWING_ERROR_WINDOW: u16 = 0x6065;
/// Quick stop deceleration (0x6085), counts/s².
pub const QUICK_STOP_DECELERATION: u16 = 0x6085;
/// Abort connection option code (0x6007): what the drive does on a communication error (a
/// heartbeat it consumes timed out, bus-off), an [`AbortConnection`] value.
pub const ABORT_CONNECTION_OPTION: u16 = 0x6007;

/// A value of 0x6007 (CiA 402-2, 6.2.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AbortConnection {
    /// 0: no action.
    NoAction,
    /// 1: fault signal (the drive faults).
    Fault,
    /// 2: disable voltage (torque off at once).
    DisableVoltage,
    /// 3: quick stop (decelerate at 0x6085, then hold).
    QuickStop,
}

impl AbortConnection {
    /// The 16-bit value of 0x6007.
    pub fn code(self) -> i16 {
        match self {
            AbortConnection::NoAction => 0,
            AbortConnection::Fault => 1,
            AbortConnection::DisableVoltage => 2,
            AbortConnection::QuickStop => 3,
        }
    }

    /// Reads a value of 0x6007 (`None` for manufacturer-specific ones).
    pub fn from_code(c: i16) -> Option<AbortConnection> {
        Some(match c {
            0 => AbortConnection::NoAction,
            1 => AbortConnection::Fault,
            2 => AbortConnection::DisableVoltage,
            3 => AbortConnection::QuickStop,
            _ => return None,
        })
    }
}

/// The controlword sent as a PDO (`cob`: the RPDO the drive maps 0x6040 to, RPDO1 by
/// default).
pub fn controlword_frame(cob: u16, controlword: u16) -> crate::CanFrame {
    crate::CanFrame::standard(cob, &controlword.to_le_bytes()).expect("an RPDO identifier")
}

/// An interpolated-position set-point (0x60C1:1, counts) sent as a PDO (`cob`: the RPDO
/// the drive maps it to).
pub fn ip_setpoint_frame(cob: u16, position: i32) -> crate::CanFrame {
    crate::CanFrame::standard(cob, &position.to_le_bytes()).expect("an RPDO identifier")
}

/// True when the statusword's fault bit (3) is set.
pub fn fault_bit(statusword: u16) -> bool {
    statusword & 0x0008 != 0
}

/// A mode of operation (0x6060 / 0x6061).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Mode {
    /// 1: profile position.
    ProfilePosition,
    /// 3: profile velocity.
    ProfileVelocity,
    /// 4: profile torque.
    ProfileTorque,
    /// 6: homing.
    Homing,
    /// 7: interpolated position.
    InterpolatedPosition,
    /// 8: cyclic synchronous position.
    CyclicPosition,
    /// 9: cyclic synchronous velocity.
    CyclicVelocity,
    /// 10: cyclic synchronous torque.
    CyclicTorque,
    /// Any other (manufacturer-specific, negative) value.
    Other(i8),
}

impl Mode {
    /// The object value.
    pub fn code(self) -> i8 {
        match self {
            Mode::ProfilePosition => 1,
            Mode::ProfileVelocity => 3,
            Mode::ProfileTorque => 4,
            Mode::Homing => 6,
            Mode::InterpolatedPosition => 7,
            Mode::CyclicPosition => 8,
            Mode::CyclicVelocity => 9,
            Mode::CyclicTorque => 10,
            Mode::Other(c) => c,
        }
    }

    /// Parses an object value.
    pub fn from_code(c: i8) -> Mode {
        match c {
            1 => Mode::ProfilePosition,
            3 => Mode::ProfileVelocity,
            4 => Mode::ProfileTorque,
            6 => Mode::Homing,
            7 => Mode::InterpolatedPosition,
            8 => Mode::CyclicPosition,
            9 => Mode::CyclicVelocity,
            10 => Mode::CyclicTorque,
            c => Mode::Other(c),
        }
    }
}

/// A state of the CiA 402 power state machine.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum State {
    /// Not ready to switch on (initialising).
    NotReadyToSwitchOn,
    /// Switch on disabled.
    SwitchOnDisabled,
    /// Ready to switch on.
    ReadyToSwitchOn,
    /// Switched on (power stage on, no torque).
    SwitchedOn,
    /// Operation enabled (torque on, following set-points).
    OperationEnabled,
    /// Quick stop active.
    QuickStopActive,
    /// Fault reaction active.
    FaultReactionActive,
    /// Fault.
    Fault,
}

impl State {
    /// Decodes the statusword's state bits (0, 1, 2, 3, 5, 6).
    pub fn from_statusword(sw: u16) -> State {
        if sw & 0x4f == 0x00 {
            State::NotReadyToSwitchOn
        } else if sw & 0x4f == 0x40 {
            State::SwitchOnDisabled
        } else if sw & 0x6f == 0x21 {
            State::ReadyToSwitchOn
        } else if sw & 0x6f == 0x23 {
            State::SwitchedOn
        } else if sw & 0x6f == 0x27 {
            State::OperationEnabled
        } else if sw & 0x6f == 0x07 {
            State::QuickStopActive
        } else if sw & 0x4f == 0x0f {
            State::FaultReactionActive
        } else if sw & 0x4f == 0x08 {
            State::Fault
        } else {
            // Bit patterns the standard leaves undefined: treat them as not ready.
            State::NotReadyToSwitchOn
        }
    }

    /// True in the states where the motor carries torque (following set-points, or
    /// decelerating in a quick stop or a fault reaction).
    pub fn torque(self) -> bool {
        matches!(
            self,
            State::OperationEnabled | State::QuickStopActive | State::FaultReactionActive
        )
    }

    /// The state bits a drive in this state reports (voltage-enabled bit 4 set when powered).
    pub fn statusword_bits(self) -> u16 {
        match self {
            State::NotReadyToSwitchOn => 0x00,
            State::SwitchOnDisabled => 0x40,
            State::ReadyToSwitchOn => 0x21,
            State::SwitchedOn => 0x23 | 0x10,
            State::OperationEnabled => 0x27 | 0x10,
            State::QuickStopActive => 0x07 | 0x10,
            State::FaultReactionActive => 0x0f,
            State::Fault => 0x08,
        }
    }
}

/// A controlword command.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Command {
    /// Transitions 2, 6, 8: to ready to switch on.
    Shutdown,
    /// Transition 3: to switched on.
    SwitchOn,
    /// Transitions 3 + 4 at once: to operation enabled.
    SwitchOnAndEnable,
    /// Transitions 7, 9, 10, 12: to switch on disabled.
    DisableVoltage,
    /// Transitions 7, 10, 11: quick stop.
    QuickStop,
    /// Transition 5: back to switched on.
    DisableOperation,
    /// Transitions 4, 16: to operation enabled.
    EnableOperation,
    /// Transition 15 (rising edge of bit 7): fault to switch on disabled.
    FaultReset,
}

impl Command {
    /// The controlword value (bits 0..3 and 7; the mode-specific bits 4..6 and 8 are left 0).
    pub fn controlword(self) -> u16 {
        match self {
            Command::Shutdown => 0x0006,
            Command::SwitchOn => 0x0007,
            Command::SwitchOnAndEnable => 0x000f,
            Command::DisableVoltage => 0x0000,
            Command::QuickStop => 0x0002,
            Command::DisableOperation => 0x0007,
            Command::EnableOperation => 0x000f,
            Command::FaultReset => 0x0080,
        }
    }
}

/// The operation-mode-specific controlword bits (4, 5, 6 and 8), added to a [`Command`]'s
/// value while operation is enabled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ModeControl {
    /// Profile position (mode 1): a rising edge of bit 4 hands over a new set-point; bit 5
    /// makes it replace the one under way, bit 6 makes it relative.
    ProfilePosition {
        /// Bit 4: new set-point.
        new_setpoint: bool,
        /// Bit 5: change set immediately.
        immediately: bool,
        /// Bit 6: the target is relative to the present one.
        relative: bool,
    },
    /// Interpolated position (mode 7): bit 4 enables interpolation (the buffer plays).
    InterpolatedPosition {
        /// Bit 4: enable interpolation.
        enable: bool,
    },
    /// Cyclic synchronous position (mode 8): no mode bits; the target (0x607A) written every
    /// SYNC is followed.
    CyclicPosition,
}

impl ModeControl {
    /// The full controlword: `base` (see [`Command::controlword`]), the mode bits, and bit 8
    /// (halt) when `halt` is set.
    pub fn controlword(self, base: Command, halt: bool) -> u16 {
        let bits = match self {
            ModeControl::ProfilePosition {
                new_setpoint,
                immediately,
                relative,
            } => (new_setpoint as u16) << 4 | (immediately as u16) << 5 | (relative as u16) << 6,
            ModeControl::InterpolatedPosition { enable } => (enable as u16) << 4,
            ModeControl::CyclicPosition => 0,
        };
        base.controlword() | bits | (halt as u16) << 8
    }
}

/// The operation-mode-specific statusword bits (10 to 13), read in the mode they belong to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ModeStatus {
    /// Bit 10: target reached (in profile position: the set-point is reached; after a halt:
    /// the axis stands).
    pub target_reached: bool,
    /// Bit 11: an internal limit is active.
    pub internal_limit: bool,
    /// Bit 12: profile position: set-point acknowledged; interpolated position: interpolation
    /// active; cyclic synchronous position: the drive follows the target.
    pub mode_bit: bool,
    /// Bit 13: profile position and cyclic synchronous position: following error.
    pub following_error: bool,
}

impl ModeStatus {
    /// Reads bits 10 to 13 of a statusword.
    pub fn from_statusword(sw: u16) -> ModeStatus {
        let bit = |b: u16| sw & (1 << b) != 0;
        ModeStatus {
            target_reached: bit(10),
            internal_limit: bit(11),
            mode_bit: bit(12),
            following_error: bit(13),
        }
    }

    /// The bits as a drive sets them.
    pub fn statusword_bits(self) -> u16 {
        (self.target_reached as u16) << 10
            | (self.internal_limit as u16) << 11
            | (self.mode_bit as u16) << 12
            | (self.following_error as u16) << 13
    }
}

/// A profile-position move: the SDO writes that set it up (mode, target, profile velocity,
/// acceleration and deceleration, in this order) and the set-point handshake.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ProfileMove {
    /// Target position, counts.
    pub target: i32,
    /// Profile velocity, counts/s.
    pub velocity: u32,
    /// Profile acceleration, counts/s².
    pub acceleration: u32,
    /// Profile deceleration, counts/s².
    pub deceleration: u32,
    /// Relative to the present target.
    pub relative: bool,
    /// Replaces a move under way instead of queueing after it.
    pub immediately: bool,
}

impl ProfileMove {
    /// The objects to write before the handshake, as (index, sub, little-endian bytes).
    pub fn writes(&self) -> Vec<(u16, u8, Vec<u8>)> {
        vec![
            (
                MODES_OF_OPERATION,
                0,
                vec![Mode::ProfilePosition.code() as u8],
            ),
            (TARGET_POSITION, 0, self.target.to_le_bytes().to_vec()),
            (PROFILE_VELOCITY, 0, self.velocity.to_le_bytes().to_vec()),
            (
                PROFILE_ACCELERATION,
                0,
                self.acceleration.to_le_bytes().to_vec(),
            ),
            (
                PROFILE_DECELERATION,
                0,
                self.deceleration.to_le_bytes().to_vec(),
            ),
        ]
    }

    /// The controlword with bit 4 `set` (the handshake raises it, waits for statusword bit
    /// 12, then lowers it).
    pub fn controlword(&self, set: bool) -> u16 {
        ModeControl::ProfilePosition {
            new_setpoint: set,
            immediately: self.immediately,
            relative: self.relative,
        }
        .controlword(Command::EnableOperation, false)
    }
}

/// The drive side: the state a drive moves to when it receives `cw` in `state` (the
/// transitions of CiA 402 figure 13; a fault reset needs a rising edge of bit 7, so pass the
/// previous controlword too). Fault detection itself is the drive's business.
pub fn next_state(state: State, previous_cw: u16, cw: u16) -> State {
    let bit = |b: u16| cw & (1 << b) != 0;
    let fault_reset = bit(7) && previous_cw & 0x80 == 0;
    // Bits: 0 switch on, 1 enable voltage, 2 quick stop (active low), 3 enable operation.
    let disable_voltage = !bit(1);
    let quick_stop = bit(1) && !bit(2);
    let shutdown = bit(1) && bit(2) && !bit(0);
    let switch_on = bit(0) && bit(1) && bit(2);
    let enable = switch_on && bit(3);
    match state {
        State::NotReadyToSwitchOn => State::SwitchOnDisabled,
        State::SwitchOnDisabled if shutdown => State::ReadyToSwitchOn,
        State::ReadyToSwitchOn if disable_voltage || quick_stop => State::SwitchOnDisabled,
        State::ReadyToSwitchOn if enable => State::OperationEnabled,
        State::ReadyToSwitchOn if switch_on => State::SwitchedOn,
        State::SwitchedOn if shutdown => State::ReadyToSwitchOn,
        State::SwitchedOn if disable_voltage || quick_stop => State::SwitchOnDisabled,
        State::SwitchedOn if enable => State::OperationEnabled,
        State::OperationEnabled if shutdown => State::ReadyToSwitchOn,
        State::OperationEnabled if disable_voltage => State::SwitchOnDisabled,
        State::OperationEnabled if quick_stop => State::QuickStopActive,
        State::OperationEnabled if switch_on && !bit(3) => State::SwitchedOn,
        State::QuickStopActive if disable_voltage => State::SwitchOnDisabled,
        State::QuickStopActive if enable => State::OperationEnabled,
        State::FaultReactionActive => State::Fault,
        State::Fault if fault_reset => State::SwitchOnDisabled,
        s => s,
    }
}

/// The host side: the command that moves a drive from `from` one step towards `to`, or
/// `None` when it is there (or cannot get there by command, e.g. out of fault reaction).
pub fn step_towards(from: State, to: State) -> Option<Command> {
    use State::*;
    if from == to {
        return None;
    }
    match (from, to) {
        (Fault, _) => Some(Command::FaultReset),
        (FaultReactionActive, _) | (NotReadyToSwitchOn, _) => None,
        (_, SwitchOnDisabled) => Some(Command::DisableVoltage),
        (QuickStopActive, OperationEnabled) => Some(Command::EnableOperation),
        (QuickStopActive, _) => Some(Command::DisableVoltage),
        (OperationEnabled, QuickStopActive) => Some(Command::QuickStop),
        (_, QuickStopActive) => None,
        (SwitchOnDisabled, _) => Some(Command::Shutdown),
        (ReadyToSwitchOn, SwitchedOn) => Some(Command::SwitchOn),
        (ReadyToSwitchOn, OperationEnabled) => Some(Command::SwitchOnAndEnable),
        (SwitchedOn, OperationEnabled) => Some(Command::EnableOperation),
        (SwitchedOn, ReadyToSwitchOn) | (OperationEnabled, ReadyToSwitchOn) => {
            Some(Command::Shutdown)
        }
        (OperationEnabled, SwitchedOn) => Some(Command::DisableOperation),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mode_bits_golden_values() {
        // Profile position: enable operation + new set-point = 0x1F; with "change set
        // immediately" 0x3F; relative 0x5F; bit 4 low again 0x0F; halt sets bit 8.
        let pp = |n, i, r| ModeControl::ProfilePosition {
            new_setpoint: n,
            immediately: i,
            relative: r,
        };
        let en = Command::EnableOperation;
        assert_eq!(pp(true, false, false).controlword(en, false), 0x001f);
        assert_eq!(pp(true, true, false).controlword(en, false), 0x003f);
        assert_eq!(pp(true, false, true).controlword(en, false), 0x005f);
        assert_eq!(pp(false, false, false).controlword(en, true), 0x010f);
        // Interpolated position: bit 4 enables interpolation.
        let ip = ModeControl::InterpolatedPosition { enable: true };
        assert_eq!(ip.controlword(en, false), 0x001f);
        assert_eq!(ModeControl::CyclicPosition.controlword(en, false), 0x000f);
        // Statusword 0x1637: operation enabled, remote, target reached, set-point acknowledged.
        let st = ModeStatus::from_statusword(0x1637);
        assert!(st.target_reached && st.mode_bit && !st.following_error && !st.internal_limit);
        assert_eq!(State::from_statusword(0x1637), State::OperationEnabled);
        assert_eq!(st.statusword_bits(), 0x1400);
        assert!(ModeStatus::from_statusword(0x2000).following_error);
        let mv = ProfileMove {
            target: -1000,
            velocity: 50_000,
            acceleration: 200_000,
            deceleration: 100_000,
            relative: false,
            immediately: true,
        };
        assert_eq!(
            mv.writes(),
            vec![
                (0x6060, 0, vec![1]),
                (0x607a, 0, vec![0x18, 0xfc, 0xff, 0xff]),
                (0x6081, 0, vec![0x50, 0xc3, 0x00, 0x00]),
                (0x6083, 0, vec![0x40, 0x0d, 0x03, 0x00]),
                (0x6084, 0, vec![0xa0, 0x86, 0x01, 0x00]),
            ]
        );
        assert_eq!(
            (mv.controlword(true), mv.controlword(false)),
            (0x003f, 0x002f)
        );
    }

    #[test]
    fn statusword_golden_values() {
        // Values drives report (voltage bit and others set where they usually are).
        assert_eq!(State::from_statusword(0x0250), State::SwitchOnDisabled);
        assert_eq!(State::from_statusword(0x0231), State::ReadyToSwitchOn);
        assert_eq!(State::from_statusword(0x0233), State::SwitchedOn);
        assert_eq!(State::from_statusword(0x0237), State::OperationEnabled);
        assert_eq!(State::from_statusword(0x1637), State::OperationEnabled);
        assert_eq!(State::from_statusword(0x0217), State::QuickStopActive);
        assert_eq!(State::from_statusword(0x021f), State::FaultReactionActive);
        assert_eq!(State::from_statusword(0x0218), State::Fault);
        assert_eq!(State::from_statusword(0x0000), State::NotReadyToSwitchOn);
        for s in [
            State::NotReadyToSwitchOn,
            State::SwitchOnDisabled,
            State::ReadyToSwitchOn,
            State::SwitchedOn,
            State::OperationEnabled,
            State::QuickStopActive,
            State::FaultReactionActive,
            State::Fault,
        ] {
            assert_eq!(State::from_statusword(s.statusword_bits()), s);
        }
    }

    #[test]
    fn every_transition_of_the_standard() {
        use State::*;
        let t = |s, cw| next_state(s, 0, cw);
        assert_eq!(t(NotReadyToSwitchOn, 0), SwitchOnDisabled); // 1 (automatic)
        assert_eq!(t(SwitchOnDisabled, 0x06), ReadyToSwitchOn); // 2
        assert_eq!(t(ReadyToSwitchOn, 0x07), SwitchedOn); // 3
        assert_eq!(t(SwitchedOn, 0x0f), OperationEnabled); // 4
        assert_eq!(t(OperationEnabled, 0x07), SwitchedOn); // 5
        assert_eq!(t(SwitchedOn, 0x06), ReadyToSwitchOn); // 6
        assert_eq!(t(ReadyToSwitchOn, 0x00), SwitchOnDisabled); // 7
        assert_eq!(t(ReadyToSwitchOn, 0x02), SwitchOnDisabled); // 7 via quick stop
        assert_eq!(t(OperationEnabled, 0x06), ReadyToSwitchOn); // 8
        assert_eq!(t(OperationEnabled, 0x00), SwitchOnDisabled); // 9
        assert_eq!(t(SwitchedOn, 0x00), SwitchOnDisabled); // 10
        assert_eq!(t(OperationEnabled, 0x02), QuickStopActive); // 11
        assert_eq!(t(QuickStopActive, 0x00), SwitchOnDisabled); // 12
        assert_eq!(t(FaultReactionActive, 0), Fault); // 14 (automatic)
        assert_eq!(next_state(Fault, 0x00, 0x80), SwitchOnDisabled); // 15
        assert_eq!(next_state(Fault, 0x80, 0x80), Fault); // no rising edge
        assert_eq!(t(QuickStopActive, 0x0f), OperationEnabled); // 16
        assert_eq!(t(ReadyToSwitchOn, 0x0f), OperationEnabled); // 3 + 4
    }

    #[test]
    fn host_reaches_operation_enabled_from_anywhere() {
        use State::*;
        for start in [
            SwitchOnDisabled,
            ReadyToSwitchOn,
            SwitchedOn,
            QuickStopActive,
            Fault,
            OperationEnabled,
        ] {
            let mut s = start;
            let mut prev = 0;
            for _ in 0..6 {
                let Some(cmd) = step_towards(s, OperationEnabled) else {
                    break;
                };
                let cw = cmd.controlword();
                s = next_state(s, prev, cw);
                prev = cw;
            }
            assert_eq!(s, OperationEnabled, "from {start:?}");
        }
        assert_eq!(
            step_towards(OperationEnabled, QuickStopActive),
            Some(Command::QuickStop)
        );
        assert_eq!(
            step_towards(OperationEnabled, SwitchOnDisabled),
            Some(Command::DisableVoltage)
        );
        assert_eq!(Mode::from_code(7), Mode::InterpolatedPosition);
        assert_eq!(Mode::Other(-3).code(), -3);
    }
}
