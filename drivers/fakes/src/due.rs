//! A fake Arduino Due joint-controller board (`c/fake_due.c`): the board side of the stride
//! Arduino link built on the firmware's own C codec (`drivers/arduino-link/c`), with six
//! simulated brushless joints, their currents and over-current trip, the board's watchdog that
//! brakes the motors when commands stop, and an MPU-6050 whose raw samples follow a tilt.
//! Reached only through its serial line (a pty in tests).

use std::ffi::c_void;
use std::ptr::NonNull;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use stride_serial::Transport;

/// Settings of the board.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DueConfig {
    /// Joints driven (at most 8).
    pub joints: u8,
    /// The watchdog: commands or heartbeats must come this often, ms.
    pub watchdog_ms: u16,
    /// Largest duty accepted, 1/10000.
    pub max_duty: u16,
    /// Over-current trip, mA.
    pub current_limit_ma: u16,
    /// STATE period, ms.
    pub state_period_ms: u16,
    /// IMU period, ms.
    pub imu_period_ms: u16,
}

impl Default for DueConfig {
    fn default() -> Self {
        DueConfig {
            joints: 6,
            watchdog_ms: 100,
            max_duty: 9000,
            current_limit_ma: 8000,
            state_period_ms: 10,
            imu_period_ms: 10,
        }
    }
}

extern "C" {
    fn fake_due_new(cfg: *const DueConfig, t_us: u64) -> *mut c_void;
    fn fake_due_free(d: *mut c_void);
    fn fake_due_receive(d: *mut c_void, bytes: *const u8, n: usize, t_us: u64);
    fn fake_due_poll(d: *mut c_void, t_us: u64, out: *mut u8, cap: usize) -> usize;
    fn fake_due_set_extra_current(d: *mut c_void, joint: i32, ma: f64);
    fn fake_due_set_tilt(d: *mut c_void, roll: f64, pitch: f64);
    fn fake_due_duty(d: *const c_void, joint: i32) -> i32;
    fn fake_due_braked(d: *const c_void, joint: i32) -> i32;
    fn fake_due_position(d: *const c_void, joint: i32) -> f64;
}

/// Levers a test pulls on the board.
#[derive(Debug, Clone, Default)]
pub struct DueLevers(Arc<Mutex<LeverState>>);

#[derive(Debug, Clone, Copy, Default)]
struct LeverState {
    extra_ma: [f64; 8],
    tilt: (f64, f64),
}

impl DueLevers {
    /// A joint draws `ma` more (a jammed joint).
    pub fn extra_current(&self, joint: usize, ma: f64) {
        self.0.lock().unwrap().extra_ma[joint.min(7)] = ma;
    }

    /// The board is tilted by `roll` and `pitch`, rad.
    pub fn tilt(&self, roll: f64, pitch: f64) {
        self.0.lock().unwrap().tilt = (roll, pitch);
    }
}

/// The fake board.
pub struct FakeDue {
    ptr: NonNull<c_void>,
    t0: Instant,
    cfg: DueConfig,
}

// SAFETY: the board's state is only touched through `&mut self` (or `&self` for reads), from
// one thread at a time.
unsafe impl Send for FakeDue {}

impl std::fmt::Debug for FakeDue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FakeDue").field("cfg", &self.cfg).finish()
    }
}

impl Drop for FakeDue {
    fn drop(&mut self) {
        // SAFETY: ptr came from fake_due_new and is freed once.
        unsafe { fake_due_free(self.ptr.as_ptr()) }
    }
}

impl FakeDue {
    /// A board powered up now.
    pub fn new(cfg: DueConfig) -> FakeDue {
        // SAFETY: cfg is a valid #[repr(C)] struct for the call's duration.
        let ptr = unsafe { fake_due_new(&cfg, 0) };
        FakeDue {
            ptr: NonNull::new(ptr).expect("allocating the fake board"),
            t0: Instant::now(),
            cfg,
        }
    }

    fn t_us(&self, now: Instant) -> u64 {
        now.saturating_duration_since(self.t0).as_micros() as u64
    }

    /// Bytes from the host.
    pub fn receive(&mut self, bytes: &[u8], now: Instant) {
        let t = self.t_us(now);
        // SAFETY: bytes is valid for its length.
        unsafe { fake_due_receive(self.ptr.as_ptr(), bytes.as_ptr(), bytes.len(), t) }
    }

    /// Advances to `now`; what the board sends.
    pub fn poll(&mut self, now: Instant) -> Vec<u8> {
        let t = self.t_us(now);
        let mut out = vec![0u8; 4096];
        // SAFETY: out is valid for its length; the board writes at most that many bytes.
        let n = unsafe { fake_due_poll(self.ptr.as_ptr(), t, out.as_mut_ptr(), out.len()) };
        out.truncate(n);
        out
    }

    fn apply(&mut self, l: &LeverState) {
        for (j, ma) in l.extra_ma.iter().enumerate() {
            // SAFETY: plain calls on a live board.
            unsafe { fake_due_set_extra_current(self.ptr.as_ptr(), j as i32, *ma) }
        }
        // SAFETY: as above.
        unsafe { fake_due_set_tilt(self.ptr.as_ptr(), l.tilt.0, l.tilt.1) }
    }

    /// A joint's applied duty, 1/10000.
    pub fn duty(&self, joint: usize) -> i32 {
        // SAFETY: a read on a live board; joint is bounded by the board.
        unsafe {
            fake_due_duty(
                self.ptr.as_ptr(),
                joint.min(self.cfg.joints as usize - 1) as i32,
            )
        }
    }

    /// Whether a joint's brake is on.
    pub fn braked(&self, joint: usize) -> bool {
        // SAFETY: as in duty.
        unsafe {
            fake_due_braked(
                self.ptr.as_ptr(),
                joint.min(self.cfg.joints as usize - 1) as i32,
            ) != 0
        }
    }

    /// A joint's position, rad.
    pub fn position(&self, joint: usize) -> f64 {
        // SAFETY: as in duty.
        unsafe {
            fake_due_position(
                self.ptr.as_ptr(),
                joint.min(self.cfg.joints as usize - 1) as i32,
            )
        }
    }

    /// Runs the board on its own thread on `line` (wrap it in `stride_serial::Paced` for the
    /// line's timing) until `stop` is set.
    pub fn spawn(
        mut self,
        mut line: impl Transport + 'static,
        levers: DueLevers,
        stop: Arc<AtomicBool>,
    ) -> JoinHandle<FakeDue> {
        std::thread::spawn(move || {
            let mut buf = [0u8; 512];
            while !stop.load(Ordering::Relaxed) {
                let n = line
                    .read_until(&mut buf, Instant::now() + Duration::from_millis(1))
                    .unwrap_or(0);
                let now = Instant::now();
                if n > 0 {
                    self.receive(&buf[..n], now);
                }
                let l = *levers.0.lock().unwrap();
                self.apply(&l);
                let out = self.poll(now);
                if !out.is_empty() && line.write_all(&out).is_err() {
                    std::thread::sleep(Duration::from_millis(1));
                }
            }
            self
        })
    }
}
