//! Headers for outgoing messages.

use std::time::{SystemTime, UNIX_EPOCH};

use stride_lcmtypes::stride::HeaderT;

/// Microseconds since the Unix epoch.
pub fn now_utime() -> i64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_micros() as i64)
        .unwrap_or(0)
}

/// Makes the headers of one publisher's messages on one channel: the current time and a
/// sequence number counting up from 0, so receivers can count what they lose.
#[derive(Debug, Clone, Default)]
pub struct Stamper {
    next: i64,
    frame: String,
}

impl Stamper {
    /// A stamper for data in `frame` ("" when none applies).
    pub fn new(frame: impl Into<String>) -> Self {
        Stamper {
            next: 0,
            frame: frame.into(),
        }
    }

    /// The next header.
    pub fn stamp(&mut self) -> HeaderT {
        let h = HeaderT {
            utime: now_utime(),
            sequence: self.next,
            frame: self.frame.clone(),
        };
        self.next += 1;
        h
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sequence_counts_up() {
        let mut s = Stamper::new("world");
        let a = s.stamp();
        let b = s.stamp();
        assert_eq!((a.sequence, b.sequence), (0, 1));
        assert_eq!(a.frame, "world");
        assert!(b.utime >= a.utime && a.utime > 0);
    }
}
