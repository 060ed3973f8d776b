//! The logic of `stride-elmo-bridge`: configuration, message conversion and the stream
//! watchdog. The CANopen work is `stride-elmo`'s.

use std::time::{Duration, Instant};

use stride_elmo::{JointConfig, JointState, Trajectory};
use stride_lcmtypes::stride::{HeaderT, JointStateT, JointTrajectoryT};

/// The bridge's TOML configuration.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BridgeConfig {
    /// `sim` (fake drives in this process), `slcan:PATH` (a USB2CAN dongle) or `lcm:NAME`
    /// (a CAN bus behind a stride-usb2can gateway).
    pub bus: String,
    /// CAN bit rate.
    pub bitrate: u32,
    /// Channel of incoming `stride.joint_trajectory_t`.
    pub trajectory_channel: String,
    /// Channel of outgoing `stride.joint_state_t`.
    pub state_channel: String,
    /// Joint state rate (and SYNC rate), Hz.
    pub state_rate_hz: f64,
    /// Quick stop when the last trajectory ended in motion and no next one came for this long
    /// (0: never).
    pub stream_timeout_ms: u64,
    /// `pvt` (Elmo PVT tables, cubic), `pt` (Elmo PT tables: positions every `pt_period_ms`,
    /// cubic) or `ip` (CiA 402 interpolated position, linear, fixed period `ip_period_ms`).
    pub motion: String,
    /// The fixed set-point period in `ip` mode, ms.
    pub ip_period_ms: u8,
    /// The point period in `pt` mode, ms (a whole number of the drives' position-loop samples).
    pub pt_period_ms: u8,
    /// After a bus failure (bus-off, a dongle unplugged), the first attempt to bring the
    /// drives up again waits this long; each failed attempt doubles it, up to 10 s.
    pub recovery_delay_ms: u64,
    /// The joints.
    pub joint: Vec<JointConfig>,
}

impl Default for BridgeConfig {
    fn default() -> Self {
        BridgeConfig {
            bus: "sim".into(),
            bitrate: 1_000_000,
            trajectory_channel: "JOINT_TRAJECTORY".into(),
            state_channel: "JOINT_STATE".into(),
            state_rate_hz: 100.0,
            stream_timeout_ms: 500,
            motion: "pvt".into(),
            ip_period_ms: 10,
            pt_period_ms: 10,
            recovery_delay_ms: 500,
            joint: Vec::new(),
        }
    }
}

impl BridgeConfig {
    /// Checks what serde cannot: at least one joint, sane rates.
    pub fn check(&self) -> Result<(), String> {
        if self.joint.is_empty() {
            return Err("the configuration lists no [[joint]]".into());
        }
        self.motion()?;
        if !(1.0..=1000.0).contains(&self.state_rate_hz) {
            return Err(format!(
                "state_rate_hz {} outside 1..=1000",
                self.state_rate_hz
            ));
        }
        for j in &self.joint {
            if !(j.min_position < j.max_position
                && j.max_velocity > 0.0
                && j.max_acceleration > 0.0)
            {
                return Err(format!(
                    "joint {}: limits must be ordered and positive",
                    j.name
                ));
            }
            if !(j.counts_per_rev > 0.0 && j.gear_ratio != 0.0) {
                return Err(format!(
                    "joint {}: counts_per_rev and gear_ratio must be set",
                    j.name
                ));
            }
            if !(j.tolerance > 0.0 && j.tolerance < j.max_position - j.min_position) {
                return Err(format!(
                    "joint {}: tolerance {} rad must be positive and less than the joint's range",
                    j.name, j.tolerance
                ));
            }
        }
        Ok(())
    }
}

impl BridgeConfig {
    /// The motion mode the configuration asks for.
    pub fn motion(&self) -> Result<stride_elmo::Motion, String> {
        match self.motion.as_str() {
            "pvt" => Ok(stride_elmo::Motion::Pvt),
            "ip" if self.ip_period_ms > 0 => Ok(stride_elmo::Motion::InterpolatedPosition {
                period_ms: self.ip_period_ms,
            }),
            "pt" if self.pt_period_ms > 0 => Ok(stride_elmo::Motion::Pt {
                period_ms: self.pt_period_ms,
            }),
            other => Err(format!(
                "motion {other:?}: use \"pvt\", \"pt\" (with pt_period_ms 1..=255) or \"ip\" \
                 (with ip_period_ms 1..=255)"
            )),
        }
    }
}

/// A `stride.joint_trajectory_t` as the master's trajectory (velocities only in PVT mode).
pub fn trajectory_from_msg(m: &JointTrajectoryT) -> Trajectory {
    Trajectory {
        joints: m.joint_names.clone(),
        times: m.time_from_start.clone(),
        positions: m.positions.clone(),
        velocities: if m.mode == JointTrajectoryT::MODE_PVT {
            m.velocities.clone()
        } else {
            Vec::new()
        },
    }
}

/// The joint states as a `stride.joint_state_t` (velocity, current and temperature NaN: the
/// state PDO carries position and statusword only; fault bit of the statusword per joint).
pub fn state_msg(states: &[(&str, JointState)], header: HeaderT) -> JointStateT {
    let n = states.len();
    JointStateT {
        header,
        num_joints: n as i32,
        names: states.iter().map(|(name, _)| name.to_string()).collect(),
        positions: states.iter().map(|(_, s)| s.position).collect(),
        velocities: vec![f64::NAN; n],
        currents: vec![f64::NAN; n],
        temperatures: vec![f32::NAN; n],
        faults: states
            .iter()
            .map(|(_, s)| ((s.statusword >> 3) & 1) as i32)
            .collect(),
    }
}

/// Decides when a trajectory stream has stopped.
#[derive(Debug, Clone)]
pub struct Watchdog {
    timeout: Option<Duration>,
    last: Option<Instant>,
    tripped: bool,
}

impl Watchdog {
    /// A watchdog with `timeout_ms` (0: disabled).
    pub fn new(timeout_ms: u64) -> Watchdog {
        Watchdog {
            timeout: (timeout_ms > 0).then(|| Duration::from_millis(timeout_ms)),
            last: None,
            tripped: false,
        }
    }

    /// A trajectory message arrived.
    pub fn feed(&mut self, now: Instant) {
        self.last = Some(now);
        self.tripped = false;
    }

    /// True once (until fed again) when motion is under way (`idle` false) and the stream
    /// has been silent for longer than the timeout.
    pub fn expired(&mut self, now: Instant, idle: bool) -> bool {
        let (Some(t), Some(last)) = (self.timeout, self.last) else {
            return false;
        };
        if idle || self.tripped || now.saturating_duration_since(last) <= t {
            return false;
        }
        self.tripped = true;
        true
    }
}

/// When to try bringing the drives up again after the bus failed: after a delay that doubles
/// with every failed attempt (up to 10 s), so a dongle plugged back in or a bus that recovers
/// from bus-off is picked up without flooding it.
#[derive(Debug, Clone)]
pub struct Recovery {
    first: Duration,
    delay: Duration,
    next: Option<Instant>,
}

impl Recovery {
    /// Longest wait between attempts.
    pub const MAX_DELAY: Duration = Duration::from_secs(10);

    /// A policy whose first retry comes `first_ms` after a failure.
    pub fn new(first_ms: u64) -> Recovery {
        let first = Duration::from_millis(first_ms.max(1));
        Recovery {
            first,
            delay: first,
            next: None,
        }
    }

    /// The bus failed (or an attempt to recover did): the next attempt is due after the
    /// current delay, which then doubles.
    pub fn failed(&mut self, now: Instant) {
        self.next = Some(now + self.delay);
        self.delay = (self.delay * 2).min(Self::MAX_DELAY);
    }

    /// True while the drives are to be considered down.
    pub fn pending(&self) -> bool {
        self.next.is_some()
    }

    /// True when an attempt is due now.
    pub fn due(&self, now: Instant) -> bool {
        self.next.is_some_and(|t| now >= t)
    }

    /// The drives are up again: back to the first delay.
    pub fn succeeded(&mut self) {
        self.next = None;
        self.delay = self.first;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shipped_config_parses_and_checks() {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../config/robots/archie-left-leg.toml"
        ))
        .unwrap();
        let cfg: BridgeConfig = toml::from_str(&text).unwrap();
        cfg.check().unwrap();
        assert_eq!(cfg.joint.len(), 6);
        assert_eq!(cfg.joint[3].name, "left_knee");
        let mut bad = cfg.clone();
        bad.joint[0].max_position = -1.0;
        assert!(bad.check().is_err());
        assert!(BridgeConfig::default().check().is_err());
    }

    #[test]
    fn watchdog_trips_once_when_the_stream_stops_mid_motion() {
        let t0 = Instant::now();
        let mut w = Watchdog::new(100);
        assert!(!w.expired(t0 + Duration::from_secs(5), false)); // never fed
        w.feed(t0);
        assert!(!w.expired(t0 + Duration::from_millis(50), false));
        assert!(!w.expired(t0 + Duration::from_millis(200), true)); // idle: nothing to stop
        assert!(w.expired(t0 + Duration::from_millis(200), false));
        assert!(!w.expired(t0 + Duration::from_millis(300), false)); // once
        w.feed(t0 + Duration::from_millis(300));
        assert!(!w.expired(t0 + Duration::from_millis(350), false));
        assert!(!Watchdog::new(0).expired(t0 + Duration::from_secs(9), false));
    }

    #[test]
    fn recovery_backs_off_and_resets() {
        let t0 = Instant::now();
        let ms = Duration::from_millis;
        let mut r = Recovery::new(100);
        assert!(!r.pending() && !r.due(t0));
        r.failed(t0);
        assert!(r.pending() && !r.due(t0 + ms(99)) && r.due(t0 + ms(100)));
        // Each failed attempt doubles the wait, up to the ceiling.
        r.failed(t0 + ms(100));
        assert!(!r.due(t0 + ms(299)) && r.due(t0 + ms(300)));
        for _ in 0..10 {
            r.failed(t0);
        }
        assert!(!r.due(t0 + ms(9999)) && r.due(t0 + Recovery::MAX_DELAY));
        r.succeeded();
        assert!(!r.pending());
        r.failed(t0);
        assert!(r.due(t0 + ms(100)));
    }

    #[test]
    fn conversions() {
        let m = JointTrajectoryT {
            mode: JointTrajectoryT::MODE_PT,
            num_joints: 1,
            joint_names: vec!["a".into()],
            num_rows: 2,
            time_from_start: vec![0.0, 0.01],
            positions: vec![vec![0.0], vec![0.1]],
            velocities: vec![vec![0.0], vec![0.0]],
            ..Default::default()
        };
        assert!(trajectory_from_msg(&m).velocities.is_empty());
        let s = state_msg(
            &[(
                "a",
                JointState {
                    position: 0.5,
                    statusword: 0x0218,
                    updated: None,
                },
            )],
            HeaderT::default(),
        );
        assert_eq!((s.positions[0], s.faults[0]), (0.5, 1));
    }
}
