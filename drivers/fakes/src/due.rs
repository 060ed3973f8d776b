//! A fake Arduino Due joint-controller board that runs the firmware itself: the sketch
//! `firmware/due/stride_link_due` (its link handling on the C codec, its watchdog, over-current
//! trip, duty limit, state and IMU periods), compiled for the host against the Arduino stubs in
//! `firmware/host-stubs`, its `setup()` once and its `loop()` again and again on a simulated
//! clock. Behind the stub pins is a plant (`c/due_plant.c`): six brushless joints that turn
//! under the PWM, direction and brake pins the sketch drives, current sensors on its analog
//! inputs, and an MPU-6050 register model on its I2C bus whose raw samples follow a tilt.
//! Reached only through its serial line (a pty in tests), so what the tests exercise is what
//! ships to the board.
//!
//! Each board loads its own copy of the compiled sketch (a shared library built by `build.rs`,
//! loaded from memory), so boards in one process do not share the sketch's statics, and each
//! new board starts from a fresh power-up.

use std::ffi::{c_void, CStr, CString};
use std::io::Write;
use std::os::fd::{FromRawFd, OwnedFd};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use stride_serial::Transport;

/// The compiled board: the sketch, the Arduino stubs and the plant.
static BOARD: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/due_board.so"));

/// The longest the board's clock moves in one go. A longer pause of the thread that runs it
/// (a busy machine) pauses the board, rather than let its watchdog see a host gone quiet while
/// the host's bytes were waiting to be read.
const MAX_GAP: Duration = Duration::from_millis(20);

/// The plant behind the board's pins: how the joints and their current sensors respond. What
/// the board does (its joints, watchdog, duty limit, current trip, periods) is the firmware's.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DueConfig {
    /// A joint's speed at full duty, rad/s.
    pub speed_at_full_duty: f64,
    /// A driven joint's current at zero duty, mA.
    pub idle_current_ma: f64,
    /// A driven joint's current per unit of duty, mA.
    pub current_per_duty_ma: f64,
}

impl Default for DueConfig {
    fn default() -> Self {
        DueConfig {
            speed_at_full_duty: 5.0,
            idle_current_ma: 300.0,
            current_per_duty_ma: 6000.0,
        }
    }
}

/// Levers a test pulls on the board.
#[derive(Debug, Clone, Default)]
pub struct DueLevers(Arc<Mutex<LeverState>>);

#[derive(Debug, Clone, Copy, Default)]
struct LeverState {
    extra_ma: [f64; 8],
    tilt: (f64, f64),
    /// What the running board's pins showed at its last turn: PWM changes per joint.
    pwm_changes: [u64; 8],
    /// Its joints' true positions at its last turn, rad (the plant's).
    positions: [f64; 8],
    /// Frame delimiters (zeros) the running board has written to its line: two a frame.
    delimiters_sent: u64,
    /// Asked: the board stops (its clock, its loop, its line) until released.
    hold: bool,
    /// The board has stopped, everything it wrote before on the line.
    held: bool,
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

    /// [`FakeDue::pwm_changes`] of the board running with these levers, as of its last turn.
    pub fn pwm_changes(&self, joint: usize) -> u64 {
        self.0.lock().unwrap().pwm_changes[joint.min(7)]
    }

    /// The true position of joint `joint` of the board running with these levers, rad, as of
    /// its last turn (what an instrument on the joint would measure: the simulated world's
    /// input).
    pub fn position(&self, joint: usize) -> f64 {
        self.0.lock().unwrap().positions[joint.min(7)]
    }

    /// The frames the running board has written to its line (its frame delimiters counted:
    /// each frame comes between two zeros, and holds none).
    pub fn frames_sent(&self) -> u64 {
        self.0.lock().unwrap().delimiters_sent / 2
    }

    /// Stops the running board (`true`: its clock, its loop and its line stand still) or lets
    /// it go on; returns once it has done so, all it wrote before on the line. A benchmark
    /// holds the board to count what crossed.
    pub fn hold(&self, on: bool) {
        self.0.lock().unwrap().hold = on;
        let t0 = Instant::now();
        while self.0.lock().unwrap().held != on && t0.elapsed() < Duration::from_secs(5) {
            std::thread::sleep(Duration::from_millis(1));
        }
    }
}

/// The functions the board library exports (`c/due_board.cpp`).
struct Api {
    power_up: unsafe extern "C" fn(*const DueConfig) -> i32,
    advance: unsafe extern "C" fn(u64),
    turn: unsafe extern "C" fn(),
    receive: unsafe extern "C" fn(*const u8, usize),
    take: unsafe extern "C" fn(*mut u8, usize) -> usize,
    joints: unsafe extern "C" fn() -> i32,
    set_extra_current: unsafe extern "C" fn(i32, f64),
    set_tilt: unsafe extern "C" fn(f64, f64),
    duty: unsafe extern "C" fn(i32) -> i32,
    braked: unsafe extern "C" fn(i32) -> i32,
    position: unsafe extern "C" fn(i32) -> f64,
    pwm_changes: unsafe extern "C" fn(i32) -> u64,
}

/// The last error of the dynamic loader.
fn dl_error() -> String {
    // SAFETY: dlerror returns null or a valid C string owned by the loader.
    let e = unsafe { libc::dlerror() };
    if e.is_null() {
        "unknown error".into()
    } else {
        // SAFETY: as above.
        unsafe { CStr::from_ptr(e) }.to_string_lossy().into_owned()
    }
}

/// Loads a fresh copy of the board library from memory: its handle, and the memory file it was
/// loaded from (open while the library is).
fn load() -> (*mut c_void, OwnedFd) {
    let name = CString::new("stride-due-board").unwrap();
    // SAFETY: name is a valid C string.
    let fd = unsafe { libc::memfd_create(name.as_ptr(), libc::MFD_CLOEXEC) };
    assert!(
        fd >= 0,
        "memfd_create for the fake board: {}",
        std::io::Error::last_os_error()
    );
    // SAFETY: fd is a new descriptor that nothing else owns.
    let fd = unsafe { OwnedFd::from_raw_fd(fd) };
    let mut file = std::fs::File::from(fd.try_clone().expect("duplicating the board's memfd"));
    file.write_all(BOARD).expect("writing the fake board");
    drop(file);
    // A distinct file per board, so the loader maps a new copy rather than reuse one.
    let path = CString::new(format!(
        "/proc/self/fd/{}",
        std::os::fd::AsRawFd::as_raw_fd(&fd)
    ))
    .unwrap();
    // SAFETY: path is a valid C string; the library has no constructors beyond zeroing statics.
    let handle = unsafe { libc::dlopen(path.as_ptr(), libc::RTLD_NOW | libc::RTLD_LOCAL) };
    assert!(!handle.is_null(), "loading the fake board: {}", dl_error());
    (handle, fd)
}

/// A function of the board library.
///
/// # Safety
///
/// `handle` is a live library handle and `F` is the function pointer type of `name`.
unsafe fn symbol<F: Copy>(handle: *mut c_void, name: &str) -> F {
    let c = CString::new(name).unwrap();
    // SAFETY: handle is live (the caller's promise), c a valid C string.
    let p = unsafe { libc::dlsym(handle, c.as_ptr()) };
    assert!(!p.is_null(), "the fake board has no {name}: {}", dl_error());
    assert_eq!(std::mem::size_of::<F>(), std::mem::size_of::<*mut c_void>());
    // SAFETY: p is the address of name, whose type is F (the caller's promise).
    unsafe { std::mem::transmute_copy::<*mut c_void, F>(&p) }
}

/// The fake board.
pub struct FakeDue {
    handle: *mut c_void,
    _file: OwnedFd,
    api: Api,
    cfg: DueConfig,
    joints: usize,
    /// Where the board's clock was last brought to, in the host's time.
    last: Instant,
}

// SAFETY: the board's library state is only touched through `&mut self` (or `&self` for
// reads), from one thread at a time; nothing in it is tied to the thread that loaded it.
unsafe impl Send for FakeDue {}

impl std::fmt::Debug for FakeDue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FakeDue").field("cfg", &self.cfg).finish()
    }
}

impl Drop for FakeDue {
    fn drop(&mut self) {
        // SAFETY: handle came from dlopen and is closed once; no function of it is used after.
        unsafe { libc::dlclose(self.handle) };
    }
}

impl FakeDue {
    /// A board powered up now: the firmware's `setup()` has run.
    pub fn new(cfg: DueConfig) -> FakeDue {
        let (handle, file) = load();
        // SAFETY: handle is live; each name is the function of that type in c/due_board.cpp.
        let api = unsafe {
            Api {
                power_up: symbol(handle, "due_board_power_up"),
                advance: symbol(handle, "due_board_advance"),
                turn: symbol(handle, "due_board_loop"),
                receive: symbol(handle, "due_board_receive"),
                take: symbol(handle, "due_board_take"),
                joints: symbol(handle, "due_board_joints"),
                set_extra_current: symbol(handle, "due_board_set_extra_current"),
                set_tilt: symbol(handle, "due_board_set_tilt"),
                duty: symbol(handle, "due_board_duty"),
                braked: symbol(handle, "due_board_braked"),
                position: symbol(handle, "due_board_position"),
                pwm_changes: symbol(handle, "due_board_pwm_changes"),
            }
        };
        // SAFETY: cfg is a valid #[repr(C)] struct for the call's duration.
        let fresh = unsafe { (api.power_up)(&cfg) } == 0;
        assert!(
            fresh,
            "the loader handed out a fake board that was used before"
        );
        // SAFETY: a plain call on a live board.
        let joints = unsafe { (api.joints)() } as usize;
        FakeDue {
            handle,
            _file: file,
            api,
            cfg,
            joints,
            last: Instant::now(),
        }
    }

    /// Brings the board's clock and the plant to `now` (at most `MAX_GAP` at once).
    fn advance(&mut self, now: Instant) {
        let dt = now.saturating_duration_since(self.last).min(MAX_GAP);
        self.last = self.last.max(now);
        // SAFETY: a plain call on a live board.
        unsafe { (self.api.advance)(dt.as_micros() as u64) }
    }

    /// Bytes from the host, arrived at `now` (the firmware reads them at its next turn, in
    /// `poll`).
    pub fn receive(&mut self, bytes: &[u8], now: Instant) {
        self.advance(now);
        // SAFETY: bytes is valid for its length.
        unsafe { (self.api.receive)(bytes.as_ptr(), bytes.len()) }
    }

    /// Advances to `now` and gives the firmware a turn of its `loop()`; what the board sends.
    pub fn poll(&mut self, now: Instant) -> Vec<u8> {
        self.advance(now);
        // SAFETY: a plain call on a live board.
        unsafe { (self.api.turn)() }
        let mut out = vec![0u8; 4096];
        let mut n = 0;
        loop {
            // SAFETY: out is valid from n for the rest of its length.
            let k = unsafe { (self.api.take)(out[n..].as_mut_ptr(), out.len() - n) };
            n += k;
            if n < out.len() {
                break;
            }
            out.resize(out.len() * 2, 0);
        }
        out.truncate(n);
        out
    }

    fn apply(&mut self, l: &LeverState) {
        for (j, ma) in l.extra_ma.iter().enumerate().take(self.joints) {
            // SAFETY: plain calls on a live board.
            unsafe { (self.api.set_extra_current)(j as i32, *ma) }
        }
        // SAFETY: as above.
        unsafe { (self.api.set_tilt)(l.tilt.0, l.tilt.1) }
    }

    fn index(&self, joint: usize) -> i32 {
        joint.min(self.joints - 1) as i32
    }

    /// A joint's applied duty as its driver sees it (PWM and direction pins), 1/10000; 0 when
    /// braked.
    pub fn duty(&self, joint: usize) -> i32 {
        // SAFETY: a read on a live board; the board bounds the joint.
        unsafe { (self.api.duty)(self.index(joint)) }
    }

    /// Whether a joint's brake pin is on.
    pub fn braked(&self, joint: usize) -> bool {
        // SAFETY: as in duty.
        unsafe { (self.api.braked)(self.index(joint)) != 0 }
    }

    /// A joint's position in the plant, rad.
    pub fn position(&self, joint: usize) -> f64 {
        // SAFETY: as in duty.
        unsafe { (self.api.position)(self.index(joint)) }
    }

    /// How many times the firmware changed a joint's PWM output: with commands whose duty
    /// differs from the last, the number of commands the board received and acted on.
    pub fn pwm_changes(&self, joint: usize) -> u64 {
        // SAFETY: as in duty.
        unsafe { (self.api.pwm_changes)(self.index(joint)) }
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
                {
                    let mut l = levers.0.lock().unwrap();
                    l.held = l.hold;
                    if l.hold {
                        drop(l);
                        std::thread::sleep(Duration::from_millis(1));
                        // The time held does not pass for the board.
                        self.last = Instant::now();
                        continue;
                    }
                }
                let n = line
                    .read_until(&mut buf, Instant::now() + Duration::from_millis(1))
                    .unwrap_or(0);
                let now = Instant::now();
                let l = *levers.0.lock().unwrap();
                self.apply(&l);
                if n > 0 {
                    self.receive(&buf[..n], now);
                }
                let out = self.poll(now);
                {
                    let mut l = levers.0.lock().unwrap();
                    for j in 0..self.joints.min(8) {
                        l.pwm_changes[j] = self.pwm_changes(j);
                        l.positions[j] = self.position(j);
                    }
                    l.delimiters_sent += out.iter().filter(|&&b| b == 0).count() as u64;
                }
                if !out.is_empty() && line.write_all(&out).is_err() {
                    std::thread::sleep(Duration::from_millis(1));
                }
            }
            self
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use stride_link::{fault, nack, Decoder, JointCommand, Message, Mode};

    /// A board driven by hand on a simulated timeline (no line, no thread).
    struct Bench {
        board: FakeDue,
        t: Instant,
        seq: u8,
        dec: Decoder,
    }

    impl Bench {
        fn new() -> Bench {
            let board = FakeDue::new(DueConfig::default());
            Bench {
                t: board.last,
                board,
                seq: 0,
                dec: Decoder::new(),
            }
        }

        /// Sends `m`; its sequence number.
        fn send(&mut self, m: &Message) -> u8 {
            let seq = self.seq;
            self.seq = self.seq.wrapping_add(1);
            let bytes = m.frame(seq).encode().unwrap();
            self.board.receive(&bytes, self.t);
            seq
        }

        /// Runs the board for `ms` in 1 ms steps; what it sent.
        fn run(&mut self, ms: u64) -> Vec<Message> {
            let mut out = Vec::new();
            for _ in 0..ms.max(1) {
                self.t += Duration::from_millis(1);
                let bytes = self.board.poll(self.t);
                for f in self.dec.push(&bytes).into_iter().flatten() {
                    out.push(Message::parse(&f).unwrap());
                }
            }
            out
        }

        fn hello(&mut self) -> Vec<Message> {
            self.send(&Message::Hello {
                major: 1,
                minor: 0,
                nonce: 7,
            });
            self.run(2)
        }
    }

    fn duty(joint: u8, value: i16) -> Message {
        Message::Command(vec![JointCommand {
            joint,
            mode: Mode::Duty,
            value,
        }])
    }

    #[test]
    fn the_board_is_the_firmware() {
        let mut b = Bench::new();
        let msgs = b.hello();
        let Some(Message::HelloAck(info)) = msgs.first() else {
            panic!("{msgs:?}");
        };
        assert_eq!(
            (
                info.joints,
                info.watchdog_ms,
                info.max_duty,
                info.current_limit_ma
            ),
            (6, 100, 9000, 8000)
        );
        assert_eq!(info.firmware, "stride-due 1.0");
        // The duty reaches the driver's pins: PWM at 12 bits, direction for the sign.
        b.send(&duty(2, -3000));
        b.run(5);
        assert!((b.board.duty(2) + 3000).abs() <= 3, "{}", b.board.duty(2));
        assert!(!b.board.braked(2) && b.board.braked(1));
        // Heartbeats for 0.5 s (the joint turns at 1.5 rad/s), then nothing: the watchdog fires
        // 100 ms after the last one.
        for _ in 0..10 {
            b.send(&Message::Heartbeat(0));
            b.run(50);
        }
        assert!(b.board.position(2) < -0.5, "{}", b.board.position(2));
        b.send(&Message::Heartbeat(0));
        let quiet = b.run(100);
        assert!(
            !quiet.iter().any(|m| matches!(m, Message::Fault { .. })),
            "{quiet:?}"
        );
        let late = b.run(3);
        assert!(
            late.contains(&Message::Fault {
                joint: 0xff,
                bits: fault::WATCHDOG,
                detail: 100
            }),
            "{late:?}"
        );
        assert!(b.board.braked(2) && b.board.duty(2) == 0);
        // A state every 10 ms, an IMU sample every 10 ms whose gravity follows the tilt.
        b.board.apply(&LeverState {
            tilt: (0.0, 0.5),
            ..Default::default()
        });
        let msgs = b.run(100);
        let states = msgs
            .iter()
            .filter(|m| matches!(m, Message::State { .. }))
            .count();
        let imu: Vec<_> = msgs
            .iter()
            .filter_map(|m| match m {
                Message::Imu { accel, .. } => Some(*accel),
                _ => None,
            })
            .collect();
        assert!((9..=11).contains(&states), "{states}");
        assert!((9..=11).contains(&imu.len()), "{}", imu.len());
        let x = imu.last().unwrap()[0] as f64 / 16384.0;
        assert!((x + 0.5f64.sin()).abs() < 0.01, "{x}");
    }

    #[test]
    fn a_jammed_joint_trips_at_the_firmwares_limit() {
        let mut b = Bench::new();
        b.hello();
        b.send(&duty(4, 5000)); // 300 + 3000 mA
        let mut msgs = b.run(20);
        for _ in 0..5 {
            b.send(&Message::Heartbeat(0));
            msgs.extend(b.run(20));
        }
        assert!(!msgs.iter().any(|m| matches!(m, Message::Fault { .. })));
        // 3.3 A + 4.5 A: still under the 8 A trip.
        b.board.apply(&LeverState {
            extra_ma: [0.0, 0.0, 0.0, 0.0, 4500.0, 0.0, 0.0, 0.0],
            ..Default::default()
        });
        b.send(&Message::Heartbeat(0));
        let msgs = b.run(20);
        assert!(
            !msgs.iter().any(|m| matches!(m, Message::Fault { .. })),
            "{msgs:?}"
        );
        assert!(!b.board.braked(4));
        // 3.3 A + 5 A: tripped and braked, until told to coast.
        b.board.apply(&LeverState {
            extra_ma: [0.0, 0.0, 0.0, 0.0, 5000.0, 0.0, 0.0, 0.0],
            ..Default::default()
        });
        b.send(&Message::Heartbeat(0));
        let msgs = b.run(20);
        assert!(
            msgs.iter().any(|m| matches!(
                m,
                Message::Fault {
                    joint: 4,
                    bits: fault::OVER_CURRENT,
                    ..
                }
            )),
            "{msgs:?}"
        );
        assert!(b.board.braked(4) && b.board.duty(4) == 0);
        // Told to drive again, it stays braked (no duty reaches it, so it does not trip again).
        b.send(&duty(4, 5000));
        let msgs = b.run(20);
        assert!(b.board.braked(4), "a tripped joint stays braked");
        assert!(
            !msgs.iter().any(|m| matches!(m, Message::Fault { .. })),
            "{msgs:?}"
        );
        // Told to coast, it is released and its fault cleared: 0.3 A + 5 A undriven does not
        // trip.
        b.send(&Message::Command(vec![JointCommand {
            joint: 4,
            mode: Mode::Coast,
            value: 0,
        }]));
        let msgs = b.run(20);
        assert!(!b.board.braked(4));
        assert!(
            !msgs.iter().any(|m| matches!(m, Message::Fault { .. })),
            "{msgs:?}"
        );
        let Some(Message::State { joints, .. }) = msgs
            .iter()
            .rev()
            .find(|m| matches!(m, Message::State { .. }))
        else {
            panic!("no state: {msgs:?}");
        };
        assert_eq!(joints[4].flags, 0, "{:?}", joints[4]);
        // Beyond the duty limit: refused.
        let seq = b.send(&duty(0, 9001));
        let msgs = b.run(5);
        assert!(
            msgs.contains(&Message::Nack {
                seq,
                reason: nack::RANGE
            }),
            "{msgs:?}"
        );
    }

    #[test]
    fn boards_in_one_process_are_separate_and_each_starts_afresh() {
        let mut a = Bench::new();
        a.hello();
        a.send(&duty(0, 2000));
        a.run(5);
        // A second board while the first runs: no session, nothing driven.
        let mut b = Bench::new();
        let seq = b.send(&duty(0, 2000));
        let msgs = b.run(5);
        assert!(
            msgs.contains(&Message::Nack {
                seq,
                reason: nack::NO_HANDSHAKE
            }),
            "{msgs:?}"
        );
        assert_eq!(b.board.duty(0), 0);
        assert_eq!(a.board.duty(0), 2000);
        // Boards made after others were dropped are fresh too.
        drop(a);
        for _ in 0..3 {
            let mut c = Bench::new();
            let seq = c.send(&duty(0, 2000));
            let msgs = c.run(5);
            assert!(
                msgs.contains(&Message::Nack {
                    seq,
                    reason: nack::NO_HANDSHAKE
                }),
                "{msgs:?}"
            );
        }
    }
}
