//! Repeated log lines, thinned: the first of a run, then at most one a period with how many
//! were left out, so a client that keeps sending what is refused does not flood the log.

use std::time::{Duration, Instant};

/// A line an app's library asks its executable to log.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Note {
    /// An error.
    Error(String),
    /// Worth a warning.
    Warn(String),
    /// For the record.
    Info(String),
}

/// Which lines of a run of repeats to write.
#[derive(Debug, Clone)]
pub struct Throttle {
    every: Duration,
    last: Option<(String, Instant)>,
    held: u64,
}

impl Throttle {
    /// Repeats of one line written at most once every `every`.
    pub fn new(every: Duration) -> Throttle {
        Throttle {
            every,
            last: None,
            held: 0,
        }
    }

    /// Logs `notes` at their levels through `tracing`, repeats thinned.
    pub fn log(&mut self, notes: impl IntoIterator<Item = Note>) {
        for n in notes {
            let (level, text) = match n {
                Note::Error(m) => (tracing::Level::ERROR, m),
                Note::Warn(m) => (tracing::Level::WARN, m),
                Note::Info(m) => (tracing::Level::INFO, m),
            };
            let Some(line) = self.pass(&text, Instant::now()) else {
                continue;
            };
            match level {
                tracing::Level::ERROR => tracing::error!("{line}"),
                tracing::Level::WARN => tracing::warn!("{line}"),
                _ => tracing::info!("{line}"),
            }
        }
    }

    /// The line to write for `text` at `now`, if any: a new text at once (after a word on
    /// the repeats of the one before), a repeat once a period with its count.
    pub fn pass(&mut self, text: &str, now: Instant) -> Option<String> {
        match &self.last {
            Some((t, at)) if t == text => {
                if now.saturating_duration_since(*at) < self.every {
                    self.held += 1;
                    return None;
                }
                let n = std::mem::take(&mut self.held);
                self.last = Some((text.to_owned(), now));
                Some(if n > 0 {
                    format!("{text} (and {n} more like it)")
                } else {
                    text.to_owned()
                })
            }
            _ => {
                let n = std::mem::take(&mut self.held);
                self.last = Some((text.to_owned(), now));
                Some(if n > 0 {
                    format!("{text} (after {n} more of the line before)")
                } else {
                    text.to_owned()
                })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repeats_are_thinned_and_counted() {
        let t0 = Instant::now();
        let ms = Duration::from_millis;
        let mut t = Throttle::new(ms(1000));
        assert_eq!(t.pass("a", t0).as_deref(), Some("a"));
        for i in 1..50 {
            assert_eq!(t.pass("a", t0 + ms(i * 10)), None);
        }
        assert_eq!(
            t.pass("a", t0 + ms(1000)).as_deref(),
            Some("a (and 49 more like it)")
        );
        assert_eq!(t.pass("a", t0 + ms(1001)), None);
        assert_eq!(
            t.pass("b", t0 + ms(1002)).as_deref(),
            Some("b (after 1 more of the line before)")
        );
    }
}
