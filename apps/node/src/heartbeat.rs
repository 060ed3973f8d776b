//! The 1 Hz heartbeat thread.

use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use lcm::Publisher;
use stride_lcmtypes::stride::NodeStatusT;

use crate::stamp::Stamper;
use crate::{Health, LoopState, STALL_AFTER};

/// Beats on a change come at most this often (a detail that changes every tick does not
/// flood the bus).
const MIN_GAP: Duration = Duration::from_millis(50);

/// While a loop is stalled, how often the thread looks whether it came round again.
const STALL_POLL: Duration = Duration::from_millis(100);

pub(crate) struct Heartbeat {
    signal: Arc<(Mutex<Signal>, Condvar)>,
    thread: JoinHandle<()>,
}

/// What wakes the heartbeat thread early.
#[derive(Default)]
struct Signal {
    stopped: bool,
    /// The health changed: publish it now rather than at the next beat.
    changed: bool,
}

struct Beat {
    publisher: Publisher,
    channel: String,
    name: String,
    host: String,
    health: Arc<Mutex<Health>>,
    loop_state: Arc<LoopState>,
    started: Instant,
    stamper: Stamper,
}

/// The state and detail a heartbeat carries: the app's, unless its loop is stalled (the
/// overdue time given) or late (the words given).
pub(crate) fn merged(app: &Health, stalled: Option<Duration>, late: Option<&str>) -> Health {
    let join = |a: String, b: &str| {
        if b.is_empty() {
            a
        } else {
            format!("{a}; {b}")
        }
    };
    match (stalled, late) {
        (Some(d), _) => Health {
            state: NodeStatusT::STATE_STALLED,
            detail: join(
                format!(
                    "control loop stalled: no turn for {:.1} s past its time",
                    d.as_secs_f64()
                ),
                &app.detail,
            ),
        },
        (None, Some(n)) if app.state == NodeStatusT::STATE_RUNNING => Health {
            state: NodeStatusT::STATE_DEGRADED,
            detail: n.to_owned(),
        },
        (None, Some(n)) if app.state == NodeStatusT::STATE_DEGRADED => Health {
            state: NodeStatusT::STATE_DEGRADED,
            detail: join(app.detail.clone(), n),
        },
        _ => app.clone(),
    }
}

impl Beat {
    /// True when the loop is stalled at `now`.
    fn stalled(&self, now: Instant) -> Option<Duration> {
        self.loop_state
            .overdue(self.started, now)
            .filter(|d| *d > STALL_AFTER)
    }

    fn publish(&mut self) {
        let app = self
            .health
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .clone();
        let health = merged(
            &app,
            self.stalled(Instant::now()),
            self.loop_state.note().as_deref(),
        );
        let s = self.publisher.stats();
        let msg = NodeStatusT {
            header: self.stamper.stamp(),
            node: self.name.clone(),
            host: self.host.clone(),
            pid: std::process::id() as i32,
            state: health.state,
            detail: health.detail,
            uptime_us: self.started.elapsed().as_micros() as i64,
            messages_published: s.published as i64,
            messages_received: s.received as i64,
            decode_errors: s.decode_errors as i64,
            handler_panics: s.handler_panics as i64,
            messages_lost: s.lost as i64,
        };
        if let Err(e) = self.publisher.publish(&self.channel, &msg) {
            tracing::warn!(error = %e, "could not publish the heartbeat");
        }
    }
}

fn hostname() -> String {
    let mut buf = [0u8; 256];
    // SAFETY: the buffer is valid for its length; gethostname NUL-terminates on success.
    let rc = unsafe { libc::gethostname(buf.as_mut_ptr().cast(), buf.len()) };
    if rc != 0 {
        return String::new();
    }
    let end = buf.iter().position(|&b| b == 0).unwrap_or(buf.len());
    String::from_utf8_lossy(&buf[..end]).into_owned()
}

impl Heartbeat {
    pub(crate) fn spawn(
        publisher: Publisher,
        channel: String,
        name: String,
        health: Arc<Mutex<Health>>,
        loop_state: Arc<LoopState>,
        started: Instant,
        period: Duration,
    ) -> std::io::Result<Heartbeat> {
        let signal = Arc::new((Mutex::new(Signal::default()), Condvar::new()));
        let signal2 = signal.clone();
        let mut beat = Beat {
            publisher,
            channel,
            name,
            host: hostname(),
            health,
            loop_state,
            started,
            stamper: Stamper::new(""),
        };
        let thread = std::thread::Builder::new()
            .name("heartbeat".into())
            .spawn(move || {
                let (lock, cv) = &*signal2;
                let mut next = Instant::now();
                loop {
                    beat.publish();
                    let sent = Instant::now();
                    let was_stalled = beat.stalled(sent).is_some();
                    let mut sig = lock.lock().unwrap_or_else(|p| p.into_inner());
                    loop {
                        let now = Instant::now();
                        if sig.stopped || now >= next {
                            break;
                        }
                        // A change goes out at once, but a gap after the last beat.
                        let room = sent + MIN_GAP;
                        if sig.changed && now >= room {
                            break;
                        }
                        // A loop that stalls or comes round again is told at once.
                        if beat.stalled(now).is_some() != was_stalled {
                            break;
                        }
                        let mut wake = next;
                        if sig.changed {
                            wake = wake.min(room);
                        }
                        if was_stalled {
                            wake = wake.min(now + STALL_POLL);
                        } else if let Some(d) = beat.loop_state.deadline(beat.started) {
                            wake = wake.min(
                                (d + STALL_AFTER + Duration::from_millis(1))
                                    .max(now + Duration::from_millis(1)),
                            );
                        }
                        sig = cv
                            .wait_timeout(sig, wake.saturating_duration_since(now))
                            .unwrap_or_else(|p| p.into_inner())
                            .0;
                    }
                    if sig.stopped {
                        drop(sig);
                        beat.publish(); // the final STOPPING status
                        return;
                    }
                    sig.changed = false;
                    let now = Instant::now();
                    if now >= next {
                        next += period;
                        if next <= now {
                            next = now + period;
                        }
                    }
                }
            })?;
        Ok(Heartbeat { signal, thread })
    }

    /// Publishes the health now (it changed).
    pub(crate) fn poke(&self) {
        let (lock, cv) = &*self.signal;
        lock.lock().unwrap_or_else(|p| p.into_inner()).changed = true;
        cv.notify_all();
    }

    pub(crate) fn stop(self) {
        let (lock, cv) = &*self.signal;
        lock.lock().unwrap_or_else(|p| p.into_inner()).stopped = true;
        cv.notify_all();
        let _ = self.thread.join();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn h(state: i8, detail: &str) -> Health {
        Health {
            state,
            detail: detail.into(),
        }
    }

    #[test]
    fn a_late_or_stalled_loop_shows_in_the_heartbeat() {
        let running = h(NodeStatusT::STATE_RUNNING, "");
        assert_eq!(merged(&running, None, None), running);
        let late = merged(&running, None, Some("control loop late: 3 of 100"));
        assert_eq!(late.state, NodeStatusT::STATE_DEGRADED);
        assert_eq!(late.detail, "control loop late: 3 of 100");
        let degraded = merged(
            &h(NodeStatusT::STATE_DEGRADED, "stream ran dry"),
            None,
            Some("late"),
        );
        assert_eq!(degraded.detail, "stream ran dry; late");
        // A fault stays a fault; a stall is told over anything.
        let fault = h(NodeStatusT::STATE_FAULT, "no joint states");
        assert_eq!(merged(&fault, None, Some("late")), fault);
        let stalled = merged(&fault, Some(Duration::from_millis(1200)), None);
        assert_eq!(stalled.state, NodeStatusT::STATE_STALLED);
        assert!(
            stalled.detail.contains("no turn for 1.2 s") && stalled.detail.contains("no joint"),
            "{}",
            stalled.detail
        );
    }
}
