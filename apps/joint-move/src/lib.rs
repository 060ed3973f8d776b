//! Smooth joint moves: a minimum-jerk profile sampled as a PVT trajectory, and the
//! `stride-joint-move` client that sends one and waits for the joints to arrive ([`Mover`]).

mod app;

pub use app::{parse_moves, Cli, Mover};

use stride_lcmtypes::stride::{HeaderT, JointTrajectoryT};

/// A minimum-jerk move of each joint from `from` to `to` in `secs`, sampled every `dt`.
pub fn min_jerk(
    names: &[String],
    from: &[f64],
    to: &[f64],
    secs: f64,
    dt: f64,
    header: HeaderT,
) -> JointTrajectoryT {
    let m = stride_limits::moves::min_jerk(from, to, secs, dt);
    JointTrajectoryT {
        header,
        start_utime: 0,
        mode: JointTrajectoryT::MODE_PVT,
        queue: JointTrajectoryT::QUEUE_REPLACE,
        num_joints: names.len() as i32,
        joint_names: names.to_vec(),
        num_rows: m.times.len() as i32,
        positions: m.positions,
        velocities: m.velocities,
        time_from_start: m.times,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn starts_and_ends_at_rest() {
        let t = min_jerk(&["k".into()], &[0.0], &[1.0], 1.0, 0.01, HeaderT::default());
        assert_eq!(t.num_rows, 101);
        assert_eq!(t.positions[0][0], 0.0);
        assert!((t.positions[100][0] - 1.0).abs() < 1e-12);
        assert!(t.velocities[0][0].abs() < 1e-12 && t.velocities[100][0].abs() < 1e-12);
        // Peak velocity of a minimum-jerk move: 1.875 x distance / time.
        let peak = t.velocities.iter().map(|v| v[0]).fold(0.0, f64::max);
        assert!((peak - 1.875).abs() < 1e-3);
    }
}
