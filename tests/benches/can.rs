//! The CAN bus under a robot's load, and SLCAN against its line:
//!
//! - twelve Elmo axes streamed by stride-elmo's master on the modelled 1 Mbit/s bus (frames
//!   take their exact wire time, stuff bits counted): set-points at 200 Hz (PVT rows 5 ms
//!   apart, appended as a stream of 100 ms chunks, the way a walking controller sends them),
//!   joint states at 100 Hz (a SYNC every 10 ms, each drive's state PDO), the master's and the
//!   drives' heartbeats. Measured: bus load, the host's CPU per 10 ms cycle, each set-point's
//!   latency from the master's send to the drive, the lowest table depth a playing drive had,
//!   underflows and drive faults (named), over the whole run; twice: on a quiet machine, and
//!   loaded with two CPU-burning processes as a robot's computer is. The master runs at the
//!   real-time priority a robot's bridge runs at (SCHED_FIFO 20), the fake drives above it
//!   (they stand in for devices with processors of their own, which the host's load does not
//!   hold up);
//! - frames per second through an SLCAN dongle on a pseudo-terminal (the host's SlcanBus, the
//!   fake dongle, the modelled bus) against the bus's own limit for the same frames, host to
//!   bus and bus to host.
//!
//! `cargo bench -p stride-tests --bench can [-- --secs S]` (scripts/bench can).

use std::collections::{HashMap, VecDeque};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serialport::SerialPort;
use stride_canbus::{BusError, CanBus, CanFrame, MemBus, MemNode};
use stride_elmo::{Event, JointConfig, Master, MasterConfig, Motion, Start, Trajectory};
use stride_fakes::dongle::FakeDongle;
use stride_fakes::elmo::{ElmoConfig, FakeElmo, Levers};
use stride_tests::percentile as pct;

/// This thread's CPU time.
fn cpu() -> Duration {
    let mut t = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes the timespec it is given.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut t) };
    Duration::new(t.tv_sec as u64, t.tv_nsec as u32)
}

/// When each set-point frame (RPDO3) was handed to the bus, by identifier, oldest first.
type Sent = Arc<Mutex<HashMap<u32, VecDeque<(Instant, [u8; 8])>>>>;

/// The master's bus, noting when each set-point frame was handed to it.
struct Noting {
    inner: MemNode,
    sent: Sent,
}

impl CanBus for Noting {
    fn send(&mut self, f: &CanFrame, deadline: Instant) -> Result<(), BusError> {
        if !(0x401..=0x47f).contains(&f.raw_id()) {
            return self.inner.send(f, deadline);
        }
        // Noted before it goes: the drives' side may see it before this send returns.
        let mut d = [0u8; 8];
        d[..f.data().len()].copy_from_slice(f.data());
        self.sent
            .lock()
            .unwrap()
            .entry(f.raw_id())
            .or_default()
            .push_back((Instant::now(), d));
        let r = self.inner.send(f, deadline);
        if r.is_err() {
            let mut s = self.sent.lock().unwrap();
            if let Some(q) = s.get_mut(&f.raw_id()) {
                q.pop_back();
            }
        }
        r
    }
    fn recv(&mut self, deadline: Instant) -> Result<CanFrame, BusError> {
        self.inner.recv(deadline)
    }
    fn try_recv(&mut self) -> Result<Option<CanFrame>, BusError> {
        self.inner.try_recv()
    }
    fn now(&self) -> Instant {
        self.inner.now()
    }
    fn utime(&self) -> i64 {
        self.inner.utime()
    }
    fn wait_until(&mut self, t: Instant) {
        self.inner.wait_until(t)
    }
}

fn joint(i: u8) -> JointConfig {
    JointConfig {
        name: format!("axis{i}"),
        node: i,
        counts_per_rev: 4096.0,
        gear_ratio: 100.0,
        min_position: -1.0,
        max_position: 1.0,
        max_velocity: 3.0,
        max_acceleration: 30.0,
        tolerance: 0.02,
    }
}

/// 100 ms from `t0` s of each axis's motion, rows 5 ms apart: a 0.3 rad sine at 0.5 Hz (its
/// phase by axis) whose amplitude grows smoothly from 0 over the first second, so that every
/// axis starts at rest where it stands.
fn chunk(axes: u8, t0: f64, first: bool) -> Trajectory {
    let rows = 21;
    let w = std::f64::consts::TAU * 0.5;
    let ramp = |t: f64| {
        if t < 1.0 {
            t * t * (3.0 - 2.0 * t)
        } else {
            1.0
        }
    };
    let dramp = |t: f64| if t < 1.0 { 6.0 * t * (1.0 - t) } else { 0.0 };
    let phase = |a: u8| a as f64 * 0.5;
    let p = |a: u8, t: f64| 0.3 * ramp(t) * ((w * t + phase(a)).sin() - phase(a).sin());
    let v = |a: u8, t: f64| {
        0.3 * dramp(t) * ((w * t + phase(a)).sin() - phase(a).sin())
            + 0.3 * ramp(t) * w * (w * t + phase(a)).cos()
    };
    let at = |k: usize| t0 + k as f64 * 0.005;
    Trajectory {
        joints: (1..=axes).map(|i| format!("axis{i}")).collect(),
        times: (0..rows).map(|k| k as f64 * 0.005).collect(),
        positions: (0..rows)
            .map(|k| (1..=axes).map(|a| p(a, at(k))).collect())
            .collect(),
        velocities: (0..rows)
            .map(|k| (1..=axes).map(|a| v(a, at(k))).collect())
            .collect(),
        start: if first { Start::Now } else { Start::Append },
    }
}

struct Axes {
    /// The fault events, by kind, with their counts.
    fault_kinds: Vec<(String, usize)>,
    load: f64,
    frames_per_s: f64,
    cpu_mean_us: f64,
    cpu_p99_us: f64,
    cpu_max_us: f64,
    latency_p50_us: f64,
    latency_max_us: f64,
    rows: u64,
    min_depth: u64,
    underflows: u64,
    stream_stops: u64,
    refused: u64,
    faults: usize,
    secs: f64,
}

/// A fault event's kind, without the joint: what faulted the drives.
fn fault_kind(e: &Event) -> String {
    match e {
        Event::Emergency { text, emcy, .. } => format!("emergency {:#06x} {text}", emcy.code),
        Event::HeartbeatLost { .. } => "heartbeat lost".into(),
        Event::Rebooted { .. } => "rebooted".into(),
        Event::InterpreterError { command, code, .. } => {
            format!("interpreter error {code} on {command}")
        }
        Event::Underflow { .. } => "underflow".into(),
        other => format!("{other:?}"),
    }
}

/// Back to the normal scheduling (this thread).
fn normal_priority() {
    let param = libc::sched_param { sched_priority: 0 };
    // SAFETY: sched_setscheduler(2) on the calling thread with a valid parameter block.
    unsafe { libc::sched_setscheduler(0, libc::SCHED_OTHER, &param) };
}

/// The real-time priorities of the fake drives (and the sniffer, an instrument) and of the
/// master, as on a robot: devices are not held up by the host's load, the bridge runs at 20.
const DEVICE_PRIORITY: u8 = 30;
const MASTER_PRIORITY: u8 = 20;

fn twelve_axes(secs: f64, realtime: bool) -> Axes {
    let n = 12u8;
    let bus = MemBus::new(1_000_000);
    let stop = Arc::new(AtomicBool::new(false));
    // Threads take the priority of the thread that starts them.
    if realtime {
        let _ = stride_node::realtime::request(DEVICE_PRIORITY);
    }
    let drives: Vec<_> = (1..=n)
        .map(|i| {
            let mut c = ElmoConfig::new(i);
            c.following_error_window = 1_000_000;
            FakeElmo::new(c, Levers::default()).spawn(bus.node(), stop.clone())
        })
        .collect();
    // The drives' side of the wire: when each set-point reached them.
    let sent: Sent = Arc::default();
    let latencies: Arc<Mutex<Vec<f64>>> = Arc::default();
    let sniffer = {
        let mut node = bus.node();
        let (sent, lat, stop) = (sent.clone(), latencies.clone(), stop.clone());
        std::thread::spawn(move || {
            while !stop.load(Ordering::Relaxed) {
                let Ok(f) = node.recv(Instant::now() + Duration::from_millis(5)) else {
                    continue;
                };
                if !(0x401..=0x47f).contains(&f.raw_id()) {
                    continue;
                }
                let now = Instant::now();
                let mut d = [0u8; 8];
                d[..f.data().len()].copy_from_slice(f.data());
                let mut s = sent.lock().unwrap();
                // The frame's own send: the oldest noted with its bytes.
                if let Some(q) = s.get_mut(&f.raw_id()) {
                    if let Some(i) = q.iter().position(|(_, b)| *b == d) {
                        let (t, _) = q.drain(..=i).next_back().expect("found");
                        lat.lock().unwrap().push((now - t).as_secs_f64() * 1e6);
                    }
                }
            }
        })
    };
    let cfg = MasterConfig {
        motion: Motion::Pvt,
        sync_period: Duration::from_millis(10),
        ..Default::default()
    };
    let link = Noting {
        inner: bus.node(),
        sent: sent.clone(),
    };
    if realtime {
        let _ = stride_node::realtime::request(MASTER_PRIORITY);
    }
    let mut m = Master::new(link, (1..=n).map(joint).collect(), cfg).unwrap();
    m.bring_up().unwrap();
    let t_start = Instant::now();
    let busy0 = bus.stats();
    let mut cycle_cpu = Vec::new();
    let (mut cpu_acc, mut next_cycle) =
        (Duration::ZERO, Instant::now() + Duration::from_millis(10));
    let mut min_depth = u64::MAX;
    let mut faults = 0;
    let mut kinds: HashMap<String, usize> = HashMap::new();
    let mut t_stream = 0.0;
    // Each chunk goes out 200 ms before the queue ends, as a controller keeps ahead of its
    // bridge (the rows go to the drives 100 ms ahead).
    let mut next_chunk = Instant::now();
    let end = t_start + Duration::from_secs_f64(secs);
    while Instant::now() < end {
        let now = Instant::now();
        if now >= next_chunk {
            let c0 = cpu();
            let first = t_stream == 0.0;
            if m.load(&chunk(n, t_stream, first), now).is_ok() {
                t_stream += 0.1;
            }
            cpu_acc += cpu() - c0;
            next_chunk = m.status().queued_until.unwrap_or(now) - Duration::from_millis(200);
        }
        let c0 = cpu();
        m.pump(now).unwrap();
        cpu_acc += cpu() - c0;
        for e in m.take_events().into_iter().filter(|e| e.is_fault()) {
            faults += 1;
            *kinds.entry(fault_kind(&e)).or_default() += 1;
        }
        for (playing, depth) in m.table_depths() {
            if playing && now > t_start + Duration::from_millis(300) {
                min_depth = min_depth.min(depth);
            }
        }
        if now >= next_cycle {
            cycle_cpu.push(cpu_acc.as_secs_f64() * 1e6);
            cpu_acc = Duration::ZERO;
            next_cycle += Duration::from_millis(10);
        }
        let wake = m.next_wake().min(next_chunk).min(next_cycle);
        if let Some(w) = wake.checked_duration_since(Instant::now()) {
            std::thread::sleep(w.min(Duration::from_millis(2)));
        }
    }
    let elapsed = t_start.elapsed().as_secs_f64();
    let stats = bus.stats();
    let busy = (stats.busy - busy0.busy).as_secs_f64();
    let frames = stats.frames - busy0.frames;
    let c = m.status().counters;
    m.shutdown();
    stop.store(true, Ordering::Relaxed);
    for d in drives {
        let _ = d.join();
    }
    let _ = sniffer.join();
    let mut lat = latencies.lock().unwrap().clone();
    let rows = lat.len() as u64;
    let mean = cycle_cpu.iter().sum::<f64>() / cycle_cpu.len().max(1) as f64;
    normal_priority();
    let mut fault_kinds: Vec<(String, usize)> = kinds.into_iter().collect();
    fault_kinds.sort();
    Axes {
        fault_kinds,
        load: busy / elapsed,
        frames_per_s: frames as f64 / elapsed,
        cpu_mean_us: mean,
        cpu_p99_us: pct(&mut cycle_cpu.clone(), 99.0),
        cpu_max_us: cycle_cpu.iter().copied().fold(0.0, f64::max),
        latency_p50_us: pct(&mut lat, 50.0),
        latency_max_us: lat.iter().copied().fold(0.0, f64::max),
        rows,
        min_depth: if min_depth == u64::MAX { 0 } else { min_depth },
        underflows: c.underflows,
        stream_stops: c.stream_stops,
        refused: c.refused,
        faults,
        secs: elapsed,
    }
}

struct Slcan {
    to_bus: f64,
    to_host: f64,
    limit: f64,
    frames: usize,
}

/// Frames per second through an SLCAN dongle on a pty, each way, against the bus's limit.
fn slcan(frames: usize) -> Slcan {
    let bus = MemBus::new(1_000_000);
    let (host_end, mut dongle_end) = serialport::TTYPort::pair().unwrap();
    dongle_end.set_timeout(Duration::from_millis(2)).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let dongle = FakeDongle::new(dongle_end, bus.node()).spawn(stop.clone());
    let mut host = stride_canbus::slcan::SlcanBus::open(
        host_end,
        stride_slcan::BitRate::M1,
        Duration::from_secs(1),
    )
    .unwrap();
    let f = CanFrame::standard(0x321, &[0x55, 0xaa, 0x55, 0xaa, 0x55, 0xaa, 0x55, 0xaa]).unwrap();
    let limit = 1e6 / f.wire_bits() as f64;
    // The limit against the textbook, without our code: a standard frame of 8 bytes is 111
    // bits with its interframe space, and stuffing adds at most 24.
    assert!(
        (1e6 / 135.0..=1e6 / 111.0).contains(&limit),
        "the frame's length is off: {limit:.0} frames/s"
    );
    // Host to bus: a node counts what arrives.
    let mut sink = bus.node();
    let count = std::thread::spawn(move || {
        let mut got = 0;
        let mut first = None;
        let mut last = Instant::now();
        while got < frames {
            if sink.recv(Instant::now() + Duration::from_secs(2)).is_ok() {
                first.get_or_insert_with(Instant::now);
                last = Instant::now();
                got += 1;
            } else {
                break;
            }
        }
        (got, first.map(|t| last - t))
    });
    let mut sent = 0;
    while sent < frames {
        match host.send(&f, Instant::now() + Duration::from_secs(1)) {
            Ok(()) => sent += 1,
            // The dongle's queue is full (BEL): the bus is the limit; try again.
            Err(BusError::TxQueueFull) => {}
            Err(e) => panic!("{e}"),
        }
    }
    let (got, span) = count.join().unwrap();
    assert_eq!(got, frames);
    let to_bus = (frames - 1) as f64 / span.unwrap().as_secs_f64();
    // Bus to host: a node sends as fast as the bus takes them.
    let mut source = bus.node();
    let feeder = std::thread::spawn(move || {
        let mut n = 0;
        while n < frames {
            match source.send(&f, Instant::now()) {
                Ok(()) => n += 1,
                Err(_) => std::thread::sleep(Duration::from_micros(100)),
            }
        }
    });
    let mut got = 0;
    let mut first = None;
    let mut last = Instant::now();
    while got < frames {
        if let Ok(r) = host.recv(Instant::now() + Duration::from_secs(2)) {
            if r.raw_id() == 0x321 {
                first.get_or_insert_with(Instant::now);
                last = Instant::now();
                got += 1;
            }
        } else {
            break;
        }
    }
    feeder.join().unwrap();
    stop.store(true, Ordering::Relaxed);
    let _ = dongle.join();
    assert_eq!(got, frames, "frames lost from bus to host");
    Slcan {
        to_bus,
        to_host: (frames - 1) as f64 / (last - first.unwrap()).as_secs_f64(),
        limit,
        frames,
    }
}

/// Two CPU-burning processes (a shell's busy loop each), stopped when dropped.
struct Burners(Vec<std::process::Child>);

impl Burners {
    fn start(n: usize) -> Burners {
        Burners(
            (0..n)
                .map(|_| {
                    std::process::Command::new("sh")
                        .args(["-c", "while :; do :; done"])
                        .spawn()
                        .expect("sh")
                })
                .collect(),
        )
    }
}

impl Drop for Burners {
    fn drop(&mut self) {
        for c in &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |name: &str, default: f64| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .and_then(|v| v.parse().ok())
            .unwrap_or(default)
    };
    let secs = arg("--secs", 600.0);
    // --normal-priority: everything at the normal priority (to see what the load does then).
    let realtime = !args.iter().any(|a| a == "--normal-priority");
    let rt = if realtime {
        stride_node::realtime::request(DEVICE_PRIORITY)
    } else {
        Err("everything at the normal priority (--normal-priority)".into())
    };
    normal_priority();
    eprintln!("twelve axes for {secs} s on a quiet machine ...");
    let quiet = twelve_axes(secs, realtime);
    eprintln!("twelve axes for {secs} s beside two CPU-burning processes ...");
    let loaded = {
        let _burn = Burners::start(2);
        twelve_axes(secs, realtime)
    };
    eprintln!("SLCAN through a pty ...");
    let s = slcan(20_000);
    let verdict = |ok: bool| if ok { "pass" } else { "FAIL" };
    let both = |f: &dyn Fn(&Axes) -> String| format!("{} | {}", f(&quiet), f(&loaded));
    match &rt {
        Ok(()) => println!(
            "Scheduling: the fake drives at SCHED_FIFO {DEVICE_PRIORITY}, the master at \
             SCHED_FIFO {MASTER_PRIORITY}."
        ),
        Err(why) => println!("Scheduling: {why}."),
    }
    println!();
    println!("| figure | quiet | loaded (2 CPU burners) | bar | verdict |");
    println!("|---|---|---|---|---|");
    println!(
        "| bus load, 12 axes (PVT rows at 200 Hz, states at 100 Hz) | {} | < 50 % | {} |",
        both(&|a| format!("{:.1} % ({:.0} frames/s)", a.load * 100.0, a.frames_per_s)),
        verdict(quiet.load < 0.5 && loaded.load < 0.5)
    );
    let clean = |a: &Axes| a.underflows == 0 && a.stream_stops == 0 && a.faults == 0;
    println!(
        "| buffer underflows over {:.0} s | {} | 0 | {} |",
        quiet.secs,
        both(&|a| format!(
            "{} (streams stopped {}, trajectories refused {})",
            a.underflows, a.stream_stops, a.refused
        )),
        verdict(
            quiet.underflows == 0
                && loaded.underflows == 0
                && quiet.stream_stops == 0
                && loaded.stream_stops == 0
        )
    );
    let kinds = |a: &Axes| {
        if a.fault_kinds.is_empty() {
            "0".to_string()
        } else {
            let k: Vec<String> = a
                .fault_kinds
                .iter()
                .map(|(k, n)| format!("{n} {k}"))
                .collect();
            format!("{} ({})", a.faults, k.join(", "))
        }
    };
    println!(
        "| drive faults over {:.0} s | {} | 0 | {} |",
        quiet.secs,
        both(&kinds),
        verdict(clean(&quiet) && clean(&loaded))
    );
    println!(
        "| lowest table depth of a playing drive | {} | ≥ 1 | {} |",
        both(&|a| format!(
            "{} rows ({:.0} ms of motion)",
            a.min_depth,
            a.min_depth as f64 * 5.0
        )),
        verdict(quiet.min_depth >= 1 && loaded.min_depth >= 1)
    );
    println!(
        "| set-point latency, master to drive (p50 / worst) | {} | | |",
        both(&|a| format!(
            "{:.0} µs / {:.0} µs of {} rows",
            a.latency_p50_us, a.latency_max_us, a.rows
        ))
    );
    println!(
        "| host CPU per 10 ms cycle (mean / p99) | {} | p99 < 2 ms | {} |",
        both(&|a| format!("{:.0} µs / {:.0} µs", a.cpu_mean_us, a.cpu_p99_us)),
        verdict(quiet.cpu_p99_us < 2000.0 && loaded.cpu_p99_us < 2000.0)
    );
    println!(
        "| host CPU per 10 ms cycle, worst | {} | < 10 ms | {} |",
        both(&|a| format!("{:.0} µs", a.cpu_max_us)),
        verdict(quiet.cpu_max_us < 10_000.0 && loaded.cpu_max_us < 10_000.0)
    );
    for (way, rate) in [("host to bus", s.to_bus), ("bus to host", s.to_host)] {
        println!(
            "| SLCAN {way} ({} 8-byte frames) | {rate:.0} frames/s = {:.3} of the bus's {:.0} | | ≥ 0.9 | {} |",
            s.frames,
            rate / s.limit,
            s.limit,
            verdict(rate / s.limit >= 0.9)
        );
    }
}
