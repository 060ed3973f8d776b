//! A group of joints as the gait sees it: its names, the channels its rows and set-points go
//! to, its joints' measured states and its bridge's status.

use std::collections::BTreeMap;
use std::sync::mpsc::Receiver;

use stride_lcmtypes::stride::{JointStateT, TrajectoryStatusT};
use stride_node::Stamper;

use crate::{BridgeStop, BridgeWatch};

/// A group of joints: its names, where they go, what was measured.
pub(crate) struct Group {
    pub(crate) name: String,
    pub(crate) joints: Vec<String>,
    pub(crate) trajectory: Option<String>,
    pub(crate) command: Option<String>,
    pub(crate) states: Option<(lcm::Subscription, Receiver<JointStateT>)>,
    /// The last measured position of each joint, and when (walker time, from the state's own
    /// stamp: a state that waited in a queue is compared with the pattern of its time).
    pub(crate) measured: BTreeMap<String, (f64, f64)>,
    /// Each joint's last measured speed (rad/s; NaN: unknown).
    pub(crate) speeds: BTreeMap<String, f64>,
    /// The headers of the trajectories and of the set-points: a sequence per channel.
    pub(crate) trajectory_stamper: Stamper,
    pub(crate) command_stamper: Stamper,
    /// The trajectory bridge's status, and what it last said.
    pub(crate) bridge: Option<(lcm::Subscription, Receiver<TrajectoryStatusT>)>,
    pub(crate) bridge_watch: BridgeWatch,
}

impl Group {
    /// Why the group's bridge stopped its drives, if its status turned to stopped since the
    /// last call.
    pub(crate) fn bridge_stopped(&mut self) -> Option<BridgeStop> {
        let (_, rx) = self.bridge.as_ref()?;
        let mut why = None;
        for m in rx.try_iter() {
            why = self.bridge_watch.on_status(&self.name, &m).or(why);
        }
        why
    }

    /// Takes the joints' states; `now` is walker time, `utime0` its start on the system
    /// clock (a state's stamp is its time; a stamp of none, or ahead of now, counts as now).
    pub(crate) fn take_states(&mut self, now: f64, utime0: i64) {
        if let Some((_, rx)) = &self.states {
            while let Ok(s) = rx.try_recv() {
                let stamped = (s.header.utime - utime0) as f64 * 1e-6;
                let at = if s.header.utime > 0 && stamped <= now {
                    stamped
                } else {
                    now
                };
                for (i, (n, p)) in s.names.iter().zip(&s.positions).enumerate() {
                    // The group's own joints only (a message of other names sizes nothing).
                    if p.is_finite() && self.joints.contains(n) {
                        // The speed: the bridge's, else the change since the last position.
                        let v = match (s.velocities.get(i), self.measured.get(n)) {
                            (Some(v), _) if v.is_finite() => *v,
                            (_, Some((q, t))) if at > *t => (p - q) / (at - t),
                            _ => f64::NAN,
                        };
                        self.speeds.insert(n.clone(), v);
                        self.measured.insert(n.clone(), (*p, at));
                    }
                }
            }
        }
    }

    /// The largest distance of the fresh measurements (at most MEASURED_AGE old at `now`)
    /// from where `want` has the group's joints at each measurement's time, and the joint.
    pub(crate) fn off(
        &self,
        want: impl Fn(f64) -> Option<Vec<f64>>,
        now: f64,
    ) -> Option<(f64, String)> {
        self.states.as_ref()?;
        self.joints
            .iter()
            .enumerate()
            .filter_map(|(i, n)| {
                let (p, at) = self.measured.get(n)?;
                if now - at >= MEASURED_AGE {
                    return None;
                }
                let q = want(*at)?;
                Some(((p - q.get(i)?).abs(), n.clone()))
            })
            .max_by(|a, b| a.0.total_cmp(&b.0))
    }

    /// Every joint measured, recently.
    pub(crate) fn all_measured(&self, now: f64) -> bool {
        self.states.is_none()
            || self.joints.iter().all(|n| {
                self.measured
                    .get(n)
                    .is_some_and(|(_, at)| now - at < MEASURED_AGE)
            })
    }

    pub(crate) fn position(&self, joint: &str) -> Option<f64> {
        self.measured.get(joint).map(|m| m.0)
    }

    /// Every joint at rest (a motion starts from rest: rows sent while the joints still
    /// decelerate from a stop are refused); a joint whose speed is unknown counts as still.
    pub(crate) fn still(&self) -> bool {
        self.states.is_none()
            || self.joints.iter().all(|n| {
                self.speeds
                    .get(n)
                    .is_none_or(|v| v.is_nan() || v.abs() < STILL_SPEED)
            })
    }
}

/// Slower than this, rad/s, a joint is at rest.
const STILL_SPEED: f64 = 0.01;

/// A joint's measurement older than this, s, tells nothing of where it is.
const MEASURED_AGE: f64 = 0.5;
