//! The logic of `stride-usb2can`: candump-style lines and gateway statistics.

use stride_canbus::CanFrame;

/// A frame as `candump -L` prints it: `(seconds.micros) iface ID#DATA` (`R` for remote
/// frames, 8 hex digits for extended identifiers).
pub fn candump_line(utime_us: i64, iface: &str, f: &CanFrame) -> String {
    let id = if f.is_extended() {
        format!("{:08X}", f.raw_id())
    } else {
        format!("{:03X}", f.raw_id())
    };
    let data = if f.is_remote() {
        "R".to_owned()
    } else {
        f.data().iter().map(|b| format!("{b:02X}")).collect()
    };
    format!(
        "({}.{:06}) {iface} {id}#{data}",
        utime_us.div_euclid(1_000_000),
        utime_us.rem_euclid(1_000_000)
    )
}

/// Counters of the gateway.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GatewayStats {
    /// Frames from the wire to LCM.
    pub from_wire: u64,
    /// Frames from LCM to the wire.
    pub to_wire: u64,
    /// Frames that could not be sent (queue full, refused).
    pub send_errors: u64,
    /// Times the interface reported bus-off.
    pub bus_off: u64,
}

impl GatewayStats {
    /// A one-line summary with rates over `secs`.
    pub fn summary(&self, previous: &GatewayStats, secs: f64) -> String {
        let rate = |a: u64, b: u64| (a - b) as f64 / secs.max(1e-9);
        format!(
            "{:.0} frames/s from the wire, {:.0} frames/s to the wire, {} send errors, {} bus-off",
            rate(self.from_wire, previous.from_wire),
            rate(self.to_wire, previous.to_wire),
            self.send_errors,
            self.bus_off
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn candump_format() {
        let f = CanFrame::standard(0x601, &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0]).unwrap();
        assert_eq!(
            candump_line(1_000_000, "can0", &f),
            "(1.000000) can0 601#4041600000000000"
        );
        let e = CanFrame::extended(0x1234, &[1]).unwrap();
        assert_eq!(
            candump_line(1_500_000, "slcan0", &e),
            "(1.500000) slcan0 00001234#01"
        );
        let r = CanFrame::remote(CanFrame::standard(0x705, &[]).unwrap().id(), 1).unwrap();
        assert!(candump_line(0, "x", &r).ends_with("705#R"));
        let s = GatewayStats {
            from_wire: 100,
            ..Default::default()
        };
        assert!(s
            .summary(&GatewayStats::default(), 2.0)
            .starts_with("50 frames/s"));
    }
}
