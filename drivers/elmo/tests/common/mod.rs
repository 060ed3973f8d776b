//! A rig of fake drives on an in-memory bus on modelled time and a master, for the master's
//! tests.

#![allow(dead_code)]

use std::time::{Duration, Instant};

use stride_canbus::{Attached, MemBus, MemNode};
use stride_elmo::{JointConfig, Master, MasterConfig, Motion, Start, Trajectory};
use stride_fakes::elmo::{ElmoConfig, FakeElmo, Levers, Probe};

pub fn joint(i: u8) -> JointConfig {
    JointConfig {
        name: format!("j{i}"),
        node: i,
        counts_per_rev: 4096.0,
        gear_ratio: 100.0,
        min_position: -1.5,
        max_position: 1.5,
        max_velocity: 3.0,
        max_acceleration: 60.0,
        tolerance: 0.01,
    }
}

pub struct Rig {
    /// The bus, on modelled time: the drives step on it as the master waits or the test
    /// advances it, whatever else the machine runs.
    pub bus: MemBus,
    pub drives: Vec<Attached<FakeElmo>>,
    pub levers: Vec<Levers>,
    pub m: Master<MemNode>,
}

/// `n` fake drives on a modelled bus, each configured by `drive`.
pub fn drives(
    bus: &MemBus,
    n: u8,
    levers: &[Levers],
    drive: impl Fn(u8) -> ElmoConfig,
) -> Vec<Attached<FakeElmo>> {
    (0..n)
        .map(|i| {
            let l = levers.get(i as usize).cloned().unwrap_or_default();
            bus.attach(FakeElmo::new(drive(i + 1), l), Duration::from_millis(1))
        })
        .collect()
}

impl Rig {
    /// `n` fake drives and a master in `motion` mode, brought up, with states coming.
    pub fn new(n: u8, motion: Motion) -> Rig {
        Rig::with(
            n,
            MasterConfig {
                motion,
                ..Default::default()
            },
        )
    }

    pub fn with(n: u8, cfg: MasterConfig) -> Rig {
        Rig::on_bus(n, cfg, 1_000_000)
    }

    /// [`Rig::with`] on a bus of `bits_per_second`.
    pub fn on_bus(n: u8, cfg: MasterConfig, bits_per_second: u32) -> Rig {
        Rig::try_new(n, cfg, bits_per_second, |_| {}).unwrap()
    }

    /// [`Rig::on_bus`] with the levers pulled by `pull` before the master brings the drives
    /// up; the bring-up's error, if it fails.
    pub fn try_new(
        n: u8,
        cfg: MasterConfig,
        bits_per_second: u32,
        pull: impl FnOnce(&[Levers]),
    ) -> Result<Rig, stride_elmo::MasterError> {
        let bus = MemBus::modelled(bits_per_second);
        let levers: Vec<Levers> = (0..n).map(|_| Levers::default()).collect();
        pull(&levers);
        let drives = drives(&bus, n, &levers, ElmoConfig::new);
        let mut m = Master::new(bus.node(), (1..=n).map(joint).collect(), cfg).unwrap();
        m.bring_up()?;
        let mut rig = Rig {
            bus,
            drives,
            levers,
            m,
        };
        rig.run(Duration::from_millis(50));
        Ok(rig)
    }

    /// The bus's (modelled) time.
    pub fn now(&self) -> Instant {
        self.bus.now()
    }

    /// Lets `d` pass with the master held up (the drives go on).
    pub fn wait(&mut self, d: Duration) {
        self.bus.advance_to(self.now() + d);
    }

    /// Pumps for `d`, at every wake the master asks for (at least every millisecond).
    pub fn run(&mut self, d: Duration) {
        let end = self.now() + d;
        while self.now() < end {
            let now = self.now();
            self.m.pump(now).unwrap();
            // A master with work left at once comes round again as a busy loop's next turn.
            let wake = self
                .m
                .next_wake()
                .min(now + Duration::from_millis(1))
                .min(end)
                .max(now + Duration::from_micros(50));
            self.bus.advance_to(wake);
        }
    }

    /// Pumps until the master is idle (at most 10 s), then lets the motors settle.
    pub fn play(&mut self) {
        let deadline = self.now() + Duration::from_secs(10);
        while !self.m.idle() && self.now() < deadline {
            self.run(Duration::from_millis(5));
        }
        assert!(self.m.idle(), "trajectory not finished");
        self.run(Duration::from_millis(100));
    }

    /// Pumps for `d`, recording every joint's position at each state.
    pub fn record(&mut self, d: Duration) -> Vec<(Instant, Vec<f64>)> {
        let end = self.now() + d;
        let mut out: Vec<(Instant, Vec<f64>)> = Vec::new();
        while self.now() < end {
            self.run(Duration::from_millis(1));
            let s = self.m.states();
            let t = s[0].1.updated.unwrap();
            if out.last().is_none_or(|(u, _)| *u != t) {
                out.push((t, s.iter().map(|(_, s)| s.position).collect()));
            }
        }
        out
    }

    pub fn positions(&self) -> Vec<f64> {
        self.m.states().iter().map(|(_, s)| s.position).collect()
    }

    /// What each fake drive shows, as an instrument would.
    pub fn probes(&self) -> Vec<Probe> {
        probes(&self.drives)
    }

    /// The drives as they are left.
    pub fn finish(self) -> Vec<Probe> {
        self.probes()
    }
}

/// What each of `drives` shows.
pub fn probes(drives: &[Attached<FakeElmo>]) -> Vec<Probe> {
    drives.iter().map(|d| d.lock().unwrap().probe()).collect()
}

/// The SYNC period of the master's default configuration.
pub const SYNC: f64 = 0.01;

/// Joint `j`'s mean speed over a stretch of a recorded trace. The states answer SYNCs, so
/// their spacing is a whole number of periods whatever their delivery's jitter: the time
/// is counted in periods, not read off the arrival times.
pub fn mean_speed(w: &[(Instant, Vec<f64>)], j: usize) -> f64 {
    let (a, b) = (&w[0], &w[w.len() - 1]);
    let periods = ((b.0 - a.0).as_secs_f64() / SYNC).round().max(1.0);
    (b.1[j] - a.1[j]) / (periods * SYNC)
}

/// One period of a shape over `rows` rows 10 ms apart: joint `j` moves by
/// `amplitude · (j + 1) / joints · p(ω, t)` at velocity `amplitude · (j + 1) / joints · v(ω, t)`.
pub fn periodic(
    joints: usize,
    amplitude: f64,
    rows: usize,
    p: fn(f64, f64) -> f64,
    v: fn(f64, f64) -> f64,
) -> Trajectory {
    let dt = 0.01;
    let w = std::f64::consts::TAU / (dt * (rows - 1) as f64);
    let table = |f: fn(f64, f64) -> f64| -> Vec<Vec<f64>> {
        (0..rows)
            .map(|r| {
                (0..joints)
                    .map(|j| amplitude * (j + 1) as f64 / joints as f64 * f(w, r as f64 * dt))
                    .collect()
            })
            .collect()
    };
    Trajectory {
        joints: (1..=joints).map(|i| format!("j{i}")).collect(),
        times: (0..rows).map(|r| r as f64 * dt).collect(),
        positions: table(p),
        velocities: table(v),
        start: Start::Now,
    }
}

/// A sine period of 0.3 rad (scaled per joint): it ends in motion.
pub fn sine(joints: usize, rows: usize) -> Trajectory {
    periodic(
        joints,
        0.3,
        rows,
        |w, t| (w * t).sin(),
        |w, t| w * (w * t).cos(),
    )
}

/// A move out and back of `amplitude` rad (a cosine bump), at rest at both ends.
pub fn bump(joints: usize, amplitude: f64, rows: usize) -> Trajectory {
    periodic(
        joints,
        amplitude,
        rows,
        |w, t| (1.0 - (w * t).cos()) / 2.0,
        |w, t| w * (w * t).sin() / 2.0,
    )
}

/// A minimum-jerk move of the named joints from `from` to `to` in `secs`, rows 10 ms apart.
pub fn minjerk(names: &[&str], from: &[f64], to: &[f64], secs: f64) -> Trajectory {
    let m = stride_limits::moves::min_jerk(from, to, secs, 0.01);
    Trajectory {
        joints: names.iter().map(|s| s.to_string()).collect(),
        positions: m.positions,
        velocities: m.velocities,
        times: m.times,
        start: Start::Now,
    }
}

/// One joint's trajectory from rows of (time, position, velocity).
pub fn rows(name: &str, rows: &[(f64, f64, f64)]) -> Trajectory {
    Trajectory {
        joints: vec![name.into()],
        times: rows.iter().map(|r| r.0).collect(),
        positions: rows.iter().map(|r| vec![r.1]).collect(),
        velocities: rows.iter().map(|r| vec![r.2]).collect(),
        start: Start::Now,
    }
}
