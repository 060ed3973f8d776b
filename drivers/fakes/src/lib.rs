//! Fake devices for tests without hardware. Each is driven only through its bus, as the real
//! device would be: tests never reach inside.

pub mod dongle;
pub mod due;
pub mod dynamixel;
pub mod elmo;
mod sim;

pub use sim::Sim;
