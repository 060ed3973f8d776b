//! The 1 Hz heartbeat thread.

use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use lcm::Publisher;
use stride_lcmtypes::stride::NodeStatusT;

use crate::stamp::Stamper;
use crate::Health;

pub(crate) struct Heartbeat {
    stop: Arc<(Mutex<bool>, Condvar)>,
    thread: JoinHandle<()>,
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
        let stop = Arc::new((Mutex::new(false), Condvar::new()));
        let stop2 = stop.clone();
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
                let (lock, cv) = &*stop2;
                let mut next = Instant::now();
                loop {
                    beat.publish();
                    next += period;
                    let mut stopped = lock.lock().unwrap_or_else(|p| p.into_inner());
                    while !*stopped {
                        let now = Instant::now();
                        if now >= next {
                            break;
                        }
                        stopped = cv
                            .wait_timeout(stopped, next - now)
                            .unwrap_or_else(|p| p.into_inner())
                            .0;
                    }
                    if *stopped {
                        drop(stopped);
                        beat.publish(); // the final STOPPING status
                        return;
                    }
                }
            })?;
        Ok(Heartbeat { stop, thread })
    }

    pub(crate) fn stop(self) {
        let (lock, cv) = &*self.stop;
        *lock.lock().unwrap_or_else(|p| p.into_inner()) = true;
        cv.notify_all();
        let _ = self.thread.join();
    }
}
