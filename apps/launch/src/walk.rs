//! `stride walk`: send a goal, follow the walk to its end, and judge it: the goal reached (by
//! the gait, and by the simulated world's true pose when there is one), the steps, the
//! smallest clearance and ZMP margin, collisions and falls, the joints' tracking error
//! (commanded rows against the drives' measured positions) and each app's CPU.

use std::collections::BTreeMap;

use stride_lcmtypes::stride::{
    JointCommandT, JointStateT, JointTrajectoryT, LaunchStatusT, PoseStampedT, SimReportT,
    StepCounterT, TrajectoryStatusT,
};

/// One joint's commanded positions in time (µs since the epoch, rad).
#[derive(Debug, Default, Clone)]
struct Rows {
    rows: Vec<(i64, f64)>,
    /// Set-points: each holds until the next (not rows to interpolate between).
    hold: bool,
}

/// Commanded rows of every joint, from the trajectories on the bus, and their comparison with
/// the measured positions.
#[derive(Debug, Default)]
pub struct Tracking {
    joints: BTreeMap<String, Rows>,
    /// Largest error, rad, and the joint.
    pub max: (f64, String),
    sum_sq: f64,
    /// Measurements compared.
    pub samples: u64,
}

impl Tracking {
    /// Takes a trajectory: its rows replace what was commanded from its start on; an appended
    /// chunk continues from the last row.
    pub fn trajectory(&mut self, m: &JointTrajectoryT, received_utime: i64) {
        for (j, name) in m.joint_names.iter().enumerate() {
            let rows = self.joints.entry(name.clone()).or_default();
            let start = if m.queue == JointTrajectoryT::QUEUE_APPEND {
                match rows.rows.last() {
                    Some(&(t, _)) => t,
                    None => continue,
                }
            } else if m.start_utime == 0 {
                received_utime
            } else {
                m.start_utime
            };
            let first = start + (m.time_from_start.first().copied().unwrap_or(0.0) * 1e6) as i64;
            rows.rows.retain(|&(t, _)| t < first);
            for (k, dt) in m.time_from_start.iter().enumerate() {
                if let Some(p) = m.positions.get(k).and_then(|r| r.get(j)) {
                    rows.rows.push((start + (dt * 1e6).round() as i64, *p));
                }
            }
        }
    }

    /// Takes a set-point command (a set-point bridge's, one a control period): each joint's
    /// set-point from the command's stamp on.
    pub fn set_point(&mut self, m: &JointCommandT) {
        for (name, p) in m.names.iter().zip(&m.setpoints) {
            let rows = self.joints.entry(name.clone()).or_default();
            rows.hold = true;
            rows.rows.retain(|&(t, _)| t < m.header.utime);
            rows.rows.push((m.header.utime, *p));
        }
    }

    /// Compares a measurement with what was commanded at its time (linear between rows; not
    /// compared outside the rows).
    pub fn measured(&mut self, m: &JointStateT) {
        for (name, p) in m.names.iter().zip(&m.positions) {
            let Some(rows) = self.joints.get(name) else {
                continue;
            };
            let t = m.header.utime;
            let i = rows.rows.partition_point(|&(rt, _)| rt <= t);
            let cmd = if rows.hold && i > 0 {
                rows.rows[i - 1].1
            } else if i == 0 || i >= rows.rows.len() {
                continue;
            } else {
                let ((t0, p0), (t1, p1)) = (rows.rows[i - 1], rows.rows[i]);
                let s = if t1 > t0 {
                    (t - t0) as f64 / (t1 - t0) as f64
                } else {
                    0.0
                };
                p0 + s * (p1 - p0)
            };
            let e = (p - cmd).abs();
            if !e.is_finite() {
                continue;
            }
            if e > self.max.0 {
                self.max = (e, name.clone());
            }
            self.sum_sq += e * e;
            self.samples += 1;
        }
    }

    /// The root mean square error, rad.
    pub fn rms(&self) -> f64 {
        if self.samples == 0 {
            f64::NAN
        } else {
            (self.sum_sq / self.samples as f64).sqrt()
        }
    }
}

/// What was seen of a walk.
#[derive(Debug, Default)]
pub struct Walk {
    /// The first and last step numbers of the gait now running.
    pub steps: Option<(i64, i64)>,
    /// Steps walked under gaits that ended before it (a restart starts the count afresh).
    pub steps_before: i64,
    /// Plans taken and refused by gaits that ended before the one now running.
    pub plans_before: (i64, i64),
    /// The gait said it reached the goal.
    pub reached: bool,
    /// The gait's last status.
    pub gait: Option<TrajectoryStatusT>,
    /// The simulated world's last report.
    pub report: Option<SimReportT>,
    /// The true pose, last.
    pub pose: Option<PoseStampedT>,
    /// The tracking of the joints.
    pub tracking: Tracking,
    /// CPU per app: sum of shares and samples.
    pub cpu: BTreeMap<String, (f64, u32)>,
    /// Why the gait stopped the walk, if it did.
    pub stopped: Option<String>,
    /// Why the gait ended the walk to the goal without reaching it (the planner cannot reach
    /// it), if it did.
    pub dropped: Option<String>,
    /// The gait's fault, from its heartbeat (FAULT, or a stalled loop), if it reported one.
    pub fault: Option<String>,
}

impl Walk {
    /// Takes a step counter. One that goes back is a new gait's (restarted): the steps of
    /// the one before stay counted.
    pub fn counter(&mut self, c: &StepCounterT) {
        self.steps = Some(match self.steps {
            None => (c.step_number, c.step_number),
            Some((a, b)) if c.step_number < b => {
                self.steps_before += b - a;
                (c.step_number, c.step_number)
            }
            Some((a, _)) => (a, c.step_number),
        });
    }

    /// Takes the gait's status. Counts that go back are a new gait's (restarted): the plans
    /// of the one before stay counted.
    pub fn gait_status(&mut self, m: TrajectoryStatusT) {
        if let Some(g) = &self.gait {
            if m.accepted < g.accepted || m.refused < g.refused {
                self.plans_before.0 += g.accepted;
                self.plans_before.1 += g.refused;
            }
        }
        self.gait = Some(m);
    }

    /// The steps walked, over every gait that ran.
    pub fn steps_walked(&self) -> i64 {
        self.steps_before + self.steps.map_or(0, |(a, b)| b - a)
    }

    /// Takes a deputy's report.
    pub fn launch(&mut self, s: &LaunchStatusT) {
        for a in &s.apps {
            if a.pid > 0 {
                let e = self.cpu.entry(a.name.clone()).or_default();
                e.0 += a.cpu;
                e.1 += 1;
            }
        }
    }

    /// The summary's lines and whether the walk passes: the goal reached within `tolerance`
    /// (by the true pose when known), no collision and no fall.
    pub fn summary(&self, goal: [f64; 2], tolerance: f64, secs: f64) -> (Vec<String>, bool) {
        let mut lines = Vec::new();
        let mut ok = self.reached;
        let steps = self.steps_walked();
        lines.push(format!(
            "goal ({:.3}, {:.3}): {} after {secs:.1} s, {steps} steps",
            goal[0],
            goal[1],
            if self.reached {
                "reached"
            } else {
                "NOT reached"
            },
        ));
        if let Some(why) = &self.dropped {
            ok = false;
            lines.push(format!("the walk ended: {why}"));
        }
        if let Some(why) = &self.stopped {
            ok = false;
            lines.push(format!("the gait stopped the walk: {why}"));
        }
        if let Some(why) = &self.fault {
            ok = false;
            lines.push(format!("the gait reports a fault: {why}"));
        }
        // Where the robot stands: the centre of its feet (the simulated world's truth).
        let at = match (&self.report, &self.pose) {
            (Some(r), _) => Some((
                (r.feet[0][0] + r.feet[1][0]) / 2.0,
                (r.feet[0][1] + r.feet[1][1]) / 2.0,
                "the feet's true centre",
            )),
            (None, Some(p)) => Some((p.pose.position[0], p.pose.position[1], "the true pelvis")),
            _ => None,
        };
        if let Some((x, y, what)) = at {
            let d = (x - goal[0]).hypot(y - goal[1]);
            let within = d <= tolerance;
            ok &= within;
            lines.push(format!(
                "{what} ({x:.3}, {y:.3}): {d:.3} m from the goal ({} the {tolerance} m tolerance)",
                if within { "within" } else { "OUTSIDE" }
            ));
        }
        if let Some(r) = &self.report {
            ok &= r.collisions == 0 && r.falls == 0;
            lines.push(format!(
                "smallest clearance of a foot or shank from an obstacle {:.3} m; collisions {}; falls {}; smallest ZMP margin {:.3} m; joints at a limit {}; touch-downs {}",
                r.min_clearance, r.collisions, r.falls, r.min_zmp_margin, r.limits, r.touchdowns
            ));
        }
        let t = &self.tracking;
        lines.push(format!(
            "tracking error (commanded rows against the drives' positions): max {:.4} rad ({}), rms {:.4} rad over {} samples",
            t.max.0,
            if t.max.1.is_empty() { "-" } else { &t.max.1 },
            t.rms(),
            t.samples
        ));
        if !self.cpu.is_empty() {
            let per: Vec<String> = self
                .cpu
                .iter()
                .map(|(n, (sum, k))| format!("{n} {:.1} %", 100.0 * sum / (*k).max(1) as f64))
                .collect();
            lines.push(format!(
                "CPU per app (mean over the walk): {}",
                per.join(", ")
            ));
        }
        if let Some(g) = &self.gait {
            lines.push(format!(
                "plans taken by the gait {}, refused {}{}",
                g.accepted + self.plans_before.0,
                g.refused + self.plans_before.1,
                if g.refused > 0 {
                    format!(" (last: {})", g.last_refusal)
                } else {
                    String::new()
                }
            ));
        }
        (lines, ok)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn counter(n: i64) -> StepCounterT {
        StepCounterT {
            step_number: n,
            ..Default::default()
        }
    }

    /// D9 of the reliability findings: after a gait restart the summary said "0 steps, plans
    /// taken 0" (the new gait's counters) where 12 touch-downs happened.
    #[test]
    fn a_walks_summary_counts_its_steps_and_plans_over_a_restarted_gait() {
        let mut w = Walk::default();
        for n in 3..=15 {
            w.counter(&counter(n));
        }
        let status = |accepted, refused| TrajectoryStatusT {
            accepted,
            refused,
            ..Default::default()
        };
        w.gait_status(status(2, 0));
        w.gait_status(status(12, 1));
        // The gait restarted: its counters begin again.
        for n in 0..=5 {
            w.counter(&counter(n));
        }
        w.gait_status(status(0, 0));
        w.gait_status(status(4, 0));
        assert_eq!(w.steps_walked(), 12 + 5);
        let (lines, _) = w.summary([1.0, 0.0], 0.2, 10.0);
        assert!(lines[0].ends_with("17 steps"), "{lines:?}");
        assert!(
            lines
                .iter()
                .any(|l| l.starts_with("plans taken by the gait 16, refused 1")),
            "{lines:?}"
        );
    }
}
