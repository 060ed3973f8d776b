//! NMT: the network management commands (COB-ID 0x000) and node states.

use crate::frame::{CanFrame, FrameError};

/// Error behaviour (0x1029): sub 1 says what a node does on a communication error (a
/// consumer heartbeat timed out, bus-off) with a [`ErrorBehaviour`] value.
pub const ERROR_BEHAVIOUR: u16 = 0x1029;

/// A value of 0x1029:1 (CiA 301, 7.5.2.32).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ErrorBehaviour {
    /// 0: to pre-operational (if operational).
    PreOperational,
    /// 1: no change of the NMT state.
    NoChange,
    /// 2: to stopped.
    Stopped,
}

impl ErrorBehaviour {
    /// The value of 0x1029:1.
    pub fn code(self) -> u8 {
        match self {
            ErrorBehaviour::PreOperational => 0,
            ErrorBehaviour::NoChange => 1,
            ErrorBehaviour::Stopped => 2,
        }
    }

    /// Reads a value of 0x1029:1.
    pub fn from_code(c: u8) -> Option<ErrorBehaviour> {
        Some(match c {
            0 => ErrorBehaviour::PreOperational,
            1 => ErrorBehaviour::NoChange,
            2 => ErrorBehaviour::Stopped,
            _ => return None,
        })
    }
}

/// An NMT command.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Command {
    /// Start remote node (0x01): to Operational.
    Start,
    /// Stop remote node (0x02): to Stopped.
    Stop,
    /// Enter pre-operational (0x80).
    EnterPreOperational,
    /// Reset node (0x81).
    ResetNode,
    /// Reset communication (0x82).
    ResetCommunication,
}

impl Command {
    /// The command specifier byte.
    pub fn code(self) -> u8 {
        match self {
            Command::Start => 0x01,
            Command::Stop => 0x02,
            Command::EnterPreOperational => 0x80,
            Command::ResetNode => 0x81,
            Command::ResetCommunication => 0x82,
        }
    }

    /// Parses a command specifier.
    pub fn from_code(c: u8) -> Option<Command> {
        Some(match c {
            0x01 => Command::Start,
            0x02 => Command::Stop,
            0x80 => Command::EnterPreOperational,
            0x81 => Command::ResetNode,
            0x82 => Command::ResetCommunication,
            _ => return None,
        })
    }
}

/// `command` for node `node` (0 addresses every node).
pub fn encode(command: Command, node: u8) -> CanFrame {
    CanFrame::standard(0x000, &[command.code(), node]).expect("valid NMT frame")
}

/// Reads an NMT frame: the command and the addressed node (0 = all).
pub fn decode(frame: &CanFrame) -> Result<(Command, u8), FrameError> {
    if frame.raw_id() != 0 || frame.is_extended() {
        return Err(FrameError::Unexpected("not an NMT frame"));
    }
    let d = frame.data_at_least(2)?;
    let cmd = Command::from_code(d[0]).ok_or(FrameError::Unexpected("unknown NMT command"))?;
    Ok((cmd, d[1]))
}

/// A node's NMT state, as its heartbeat reports it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum State {
    /// Boot-up (0x00), sent once after reset.
    BootUp,
    /// Stopped (0x04).
    Stopped,
    /// Operational (0x05).
    Operational,
    /// Pre-operational (0x7F).
    PreOperational,
}

impl State {
    /// The heartbeat byte (without the toggle bit).
    pub fn code(self) -> u8 {
        match self {
            State::BootUp => 0x00,
            State::Stopped => 0x04,
            State::Operational => 0x05,
            State::PreOperational => 0x7f,
        }
    }

    /// Parses a heartbeat byte (the node-guarding toggle bit 7 is ignored).
    pub fn from_code(c: u8) -> Option<State> {
        Some(match c & 0x7f {
            0x00 => State::BootUp,
            0x04 => State::Stopped,
            0x05 => State::Operational,
            0x7f => State::PreOperational,
            _ => return None,
        })
    }

    /// The state a node moves to on `command` (reset commands end in boot-up, then
    /// pre-operational).
    pub fn after(self, command: Command) -> State {
        match command {
            Command::Start => State::Operational,
            Command::Stop => State::Stopped,
            Command::EnterPreOperational => State::PreOperational,
            Command::ResetNode | Command::ResetCommunication => State::BootUp,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn golden_frames() {
        // "Start node 1" and "reset communication of all nodes" on the wire.
        let f = encode(Command::Start, 1);
        assert_eq!((f.raw_id(), f.data()), (0x000, &[0x01, 0x01][..]));
        assert_eq!(encode(Command::ResetCommunication, 0).data(), [0x82, 0x00]);
        assert_eq!(
            decode(&encode(Command::Stop, 7)).unwrap(),
            (Command::Stop, 7)
        );
        let bad = CanFrame::standard(0, &[0x55, 1]).unwrap();
        assert!(decode(&bad).is_err());
        assert!(decode(&CanFrame::standard(0, &[1]).unwrap()).is_err());
    }

    #[test]
    fn states() {
        assert_eq!(State::from_code(0x85), Some(State::Operational));
        assert_eq!(
            State::PreOperational.after(Command::Start),
            State::Operational
        );
        assert_eq!(State::Operational.after(Command::ResetNode), State::BootUp);
        assert_eq!(State::from_code(0x33), None);
    }
}
