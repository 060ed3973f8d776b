//! Linux SocketCAN interfaces (`can0`, `vcan0`, `slcan0`) as a [`CanBus`] (feature
//! `socketcan`). Tests that need an interface are behind the feature `hardware-tests`.

use std::time::Instant;

use embedded_can::Frame as _;
use socketcan::{CanSocket, ErrorCause, Frame as _, Socket};

use crate::{BusError, CanBus, CanFrame};

/// A SocketCAN interface.
pub struct SocketCanBus {
    sock: CanSocket,
    name: String,
}

impl std::fmt::Debug for SocketCanBus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SocketCanBus")
            .field("iface", &self.name)
            .finish()
    }
}

fn dev(e: impl std::fmt::Display) -> BusError {
    BusError::Device(e.to_string())
}

impl SocketCanBus {
    /// Opens interface `iface` (it must be up, with its bit rate set by `ip link`).
    pub fn open(iface: &str) -> Result<SocketCanBus, BusError> {
        let sock = CanSocket::open(iface).map_err(|e| dev(format!("opening {iface}: {e}")))?;
        Ok(SocketCanBus {
            sock,
            name: iface.to_owned(),
        })
    }
}

impl CanBus for SocketCanBus {
    fn send(&mut self, frame: &CanFrame, deadline: Instant) -> Result<(), BusError> {
        let f = if frame.is_remote() {
            socketcan::CanFrame::new_remote(frame.id(), frame.dlc())
        } else {
            socketcan::CanFrame::new(frame.id(), frame.data())
        }
        .ok_or_else(|| dev("frame not representable"))?;
        let wait = deadline.saturating_duration_since(Instant::now());
        self.sock
            .set_write_timeout(Some(wait.max(std::time::Duration::from_micros(100))))
            .map_err(dev)?;
        self.sock.write_frame(&f).map_err(|e| match e.kind() {
            std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut => BusError::TxQueueFull,
            _ => dev(e),
        })
    }

    fn recv(&mut self, deadline: Instant) -> Result<CanFrame, BusError> {
        loop {
            let wait = deadline.saturating_duration_since(Instant::now());
            if wait.is_zero() {
                return Err(BusError::Timeout);
            }
            let f = match self.sock.read_frame_timeout(wait) {
                Ok(f) => f,
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) =>
                {
                    return Err(BusError::Timeout)
                }
                Err(e) => return Err(dev(e)),
            };
            if f.is_error_frame() {
                // Error frames carry the controller's state; bus-off ends the link.
                if let socketcan::CanFrame::Error(err) = f {
                    if err.into_error().causes().any(|c| *c == ErrorCause::BusOff) {
                        return Err(BusError::BusOff);
                    }
                }
                continue;
            }
            let out = if f.is_remote_frame() {
                CanFrame::remote(f.id(), f.dlc() as u8)
            } else {
                CanFrame::data_frame(f.id(), f.data())
            };
            return out.map_err(dev);
        }
    }
}

#[cfg(all(test, feature = "hardware-tests"))]
mod tests {
    use super::*;
    use std::time::Duration;

    /// Needs `ip link add dev vcan0 type vcan && ip link set up vcan0`.
    #[test]
    fn vcan_round_trip() {
        let mut a = SocketCanBus::open("vcan0").unwrap();
        let mut b = SocketCanBus::open("vcan0").unwrap();
        let f = CanFrame::standard(0x123, &[1, 2, 3]).unwrap();
        a.send(&f, Instant::now() + Duration::from_millis(100))
            .unwrap();
        assert_eq!(b.recv(Instant::now() + Duration::from_secs(1)).unwrap(), f);
    }
}
