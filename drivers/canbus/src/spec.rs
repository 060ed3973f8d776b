//! Where a bus is, as configuration and command lines name it.

use std::fmt;
use std::str::FromStr;

use crate::{BusError, CanBus};

/// A CAN bus by name: `sim` (fake devices in the process), `slcan:/dev/ttyACM0` (a USB2CAN
/// dongle speaking SLCAN), `lcm:NAME` (a bus behind a stride-usb2can gateway on the LCM
/// network) or `socketcan:can0` (a kernel interface, with the feature `socketcan`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum BusSpec {
    /// Fake devices on an in-memory bus in this process.
    Sim,
    /// An SLCAN dongle on this serial device.
    Slcan(String),
    /// A bus carried over LCM under this name.
    Lcm(String),
    /// A kernel CAN interface.
    SocketCan(String),
}

/// The forms a [`BusSpec`] takes, for error messages.
pub const BUS_FORMS: &str = "\"sim\", \"slcan:/dev/ttyACM0\", \"lcm:NAME\" or \"socketcan:can0\"";

impl FromStr for BusSpec {
    type Err = String;

    fn from_str(s: &str) -> Result<BusSpec, String> {
        let nonempty = |kind: &str, rest: &str| {
            if rest.is_empty() {
                Err(format!("bus {s:?}: {kind} needs a name after the colon"))
            } else {
                Ok(rest.to_owned())
            }
        };
        if s == "sim" {
            Ok(BusSpec::Sim)
        } else if let Some(p) = s.strip_prefix("slcan:") {
            nonempty("slcan", p).map(BusSpec::Slcan)
        } else if let Some(n) = s.strip_prefix("lcm:") {
            nonempty("lcm", n).map(BusSpec::Lcm)
        } else if let Some(i) = s.strip_prefix("socketcan:") {
            nonempty("socketcan", i).map(BusSpec::SocketCan)
        } else {
            Err(format!("unknown bus {s:?}: use {BUS_FORMS}"))
        }
    }
}

impl fmt::Display for BusSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BusSpec::Sim => f.write_str("sim"),
            BusSpec::Slcan(p) => write!(f, "slcan:{p}"),
            BusSpec::Lcm(n) => write!(f, "lcm:{n}"),
            BusSpec::SocketCan(i) => write!(f, "socketcan:{i}"),
        }
    }
}

impl<'de> serde::Deserialize<'de> for BusSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<BusSpec, D::Error> {
        let s = String::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

impl BusSpec {
    /// Opens the device a spec names at `bitrate`: an SLCAN dongle or a kernel interface. The
    /// simulated and LCM-carried buses are made by their owners (the fakes, stride-can-lcm).
    pub fn open_device(&self, bitrate: u32) -> Result<Box<dyn CanBus + Send>, BusError> {
        match self {
            BusSpec::Slcan(path) => Ok(Box::new(crate::slcan::open_path(path, bitrate)?)),
            #[cfg(feature = "socketcan")]
            BusSpec::SocketCan(iface) => {
                Ok(Box::new(crate::socketcan::SocketCanBus::open(iface)?))
            }
            #[cfg(not(feature = "socketcan"))]
            BusSpec::SocketCan(iface) => Err(BusError::Device(format!(
                "socketcan:{iface}: this build has no SocketCAN backend (build with --features socketcan)"
            ))),
            other => Err(BusError::Device(format!("{other} is not a device"))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_form_parses_and_prints_back() {
        for s in ["sim", "slcan:/dev/ttyACM0", "lcm:left", "socketcan:can0"] {
            assert_eq!(s.parse::<BusSpec>().unwrap().to_string(), s);
        }
    }

    #[test]
    fn an_unknown_bus_names_every_form() {
        let e = "bogus:xyz".parse::<BusSpec>().unwrap_err();
        assert!(e.contains("lcm:NAME") && e.contains("socketcan"), "{e}");
        assert!("lcm:".parse::<BusSpec>().is_err());
    }

    #[cfg(not(feature = "socketcan"))]
    #[test]
    fn socketcan_without_the_feature_says_so() {
        let e = BusSpec::SocketCan("can0".into()).open_device(1_000_000);
        assert!(format!("{}", e.err().unwrap()).contains("--features socketcan"));
    }
}
