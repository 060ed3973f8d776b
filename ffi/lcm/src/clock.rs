//! The time base of LCM's event logs (lcm-logger stamps each event with it) and of the
//! stride headers' `utime`: microseconds since the Unix epoch, by the system clock.

/// Microseconds since the Unix epoch (0 for a clock set before it).
pub fn now_utime() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as i64)
}
