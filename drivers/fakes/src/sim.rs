//! A guard over fake devices running on their own threads.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;

/// Fake devices running in this process (an app's `sim` bus or line): dropping the guard
/// stops them and waits for their threads.
#[derive(Debug)]
pub struct Sim<T> {
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<T>>,
}

impl<T> Default for Sim<T> {
    fn default() -> Self {
        Sim::new()
    }
}

impl<T> Sim<T> {
    /// A guard with nothing running yet.
    pub fn new() -> Sim<T> {
        Sim {
            stop: Arc::new(AtomicBool::new(false)),
            threads: Vec::new(),
        }
    }

    /// The flag to hand each device's `spawn`.
    pub fn flag(&self) -> Arc<AtomicBool> {
        self.stop.clone()
    }

    /// Keeps a device's thread, to stop and join it with the rest.
    pub fn add(&mut self, thread: JoinHandle<T>) {
        self.threads.push(thread);
    }

    /// Stops the devices and returns what their threads returned.
    pub fn finish(mut self) -> Vec<T> {
        self.stop.store(true, Ordering::Relaxed);
        self.threads
            .drain(..)
            .filter_map(|t| t.join().ok())
            .collect()
    }
}

impl<T> Drop for Sim<T> {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}
