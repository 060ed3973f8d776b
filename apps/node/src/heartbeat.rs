//! The 1 Hz heartbeat thread.

use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use lcm::Publisher;
use stride_lcmtypes::stride::NodeStatusT;

use crate::stamp::Stamper;
use crate::Health;

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
    started: Instant,
    stamper: Stamper,
}

impl Beat {
    fn publish(&mut self) {
        let health = self
            .health
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .clone();
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
                    let mut sig = lock.lock().unwrap_or_else(|p| p.into_inner());
                    loop {
                        let now = Instant::now();
                        if sig.stopped || sig.changed || now >= next {
                            break;
                        }
                        sig = cv
                            .wait_timeout(sig, next - now)
                            .unwrap_or_else(|p| p.into_inner())
                            .0;
                    }
                    if sig.stopped {
                        drop(sig);
                        beat.publish(); // the final STOPPING status
                        return;
                    }
                    if std::mem::take(&mut sig.changed) {
                        continue; // an extra beat now; the regular ones keep their time
                    }
                    next += period;
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
