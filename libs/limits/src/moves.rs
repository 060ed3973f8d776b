//! The minimum-jerk move (the quintic 10x³ − 15x⁴ + 6x⁵): at rest at both ends, smooth in
//! acceleration, its peak speed 1.875 · distance / time. The one profile the tools, the gait's
//! pose moves and the tests send to drives.

/// Peak speed of a minimum-jerk move over its mean speed.
pub const MIN_JERK_PEAK: f64 = 1.875;

/// A sampled move: row times (s from its start) and each row's joint positions and velocities.
#[derive(Debug, Clone, PartialEq)]
pub struct Rows {
    /// Row times, 0 first.
    pub times: Vec<f64>,
    /// Positions, one row per time, one value per joint.
    pub positions: Vec<Vec<f64>>,
    /// Velocities (rad/s or m/s), as `positions`.
    pub velocities: Vec<Vec<f64>>,
}

/// The fraction of the way, and its rate (per s), at time `t` of a move lasting `secs`.
pub fn min_jerk_at(t: f64, secs: f64) -> (f64, f64) {
    let x = (t / secs).clamp(0.0, 1.0);
    let s = x * x * x * (10.0 + x * (-15.0 + 6.0 * x));
    let ds = x * x * (30.0 + x * (-60.0 + 30.0 * x)) / secs;
    (s, ds)
}

/// A minimum-jerk move of each joint from `from` to `to` in `secs`, sampled every `dt` from 0
/// through `secs` rounded to a whole number of rows (at least one step).
pub fn min_jerk(from: &[f64], to: &[f64], secs: f64, dt: f64) -> Rows {
    let n = (secs / dt).round().max(1.0) as usize;
    let mut rows = Rows {
        times: Vec::with_capacity(n + 1),
        positions: Vec::with_capacity(n + 1),
        velocities: Vec::with_capacity(n + 1),
    };
    for k in 0..=n {
        let t = k as f64 * dt;
        let (s, ds) = min_jerk_at(t, secs);
        rows.times.push(t);
        rows.positions
            .push(from.iter().zip(to).map(|(a, b)| a + (b - a) * s).collect());
        rows.velocities
            .push(from.iter().zip(to).map(|(a, b)| (b - a) * ds).collect());
    }
    rows
}

/// The time of a minimum-jerk move from `from` to `to` that takes at least `min_time` s and
/// moves no joint faster than `speed` at its peak, rounded up to a whole number of `dt`.
pub fn min_jerk_time(from: &[f64], to: &[f64], speed: f64, min_time: f64, dt: f64) -> f64 {
    let far = from
        .iter()
        .zip(to)
        .map(|(a, b)| (b - a).abs())
        .fold(0.0, f64::max);
    ((MIN_JERK_PEAK * far / speed).max(min_time) / dt).ceil() * dt
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_min_jerk_move_rests_at_both_ends_and_peaks_at_its_known_speed() {
        let r = min_jerk(&[0.0, 1.0], &[1.0, 1.0], 1.0, 0.01);
        assert_eq!(r.times.len(), 101);
        assert_eq!(r.positions[0], [0.0, 1.0]);
        assert!((r.positions[100][0] - 1.0).abs() < 1e-12);
        assert_eq!(r.velocities[0], [0.0, 0.0]);
        assert!(r.velocities[100][0].abs() < 1e-12);
        let peak = r.velocities.iter().map(|v| v[0]).fold(0.0, f64::max);
        assert!((peak - MIN_JERK_PEAK).abs() < 1e-9, "{peak}");
        assert!(r.velocities.iter().all(|v| v[1] == 0.0));
        // Its velocity is its position's slope.
        for k in 1..100 {
            let slope = (r.positions[k + 1][0] - r.positions[k - 1][0]) / 0.02;
            assert!((slope - r.velocities[k][0]).abs() < 1e-3);
        }
    }

    #[test]
    fn a_min_jerk_time_keeps_the_peak_within_the_speed() {
        let t = min_jerk_time(&[0.0, 1.0], &[0.5, 1.0], 0.3, 1.0, 0.01);
        assert!((t - 3.13).abs() < 1e-9, "{t}");
        let r = min_jerk(&[0.0], &[0.5], t, 0.01);
        let peak = r.velocities.iter().map(|v| v[0]).fold(0.0, f64::max);
        assert!(peak <= 0.3, "{peak}");
        assert!((min_jerk_time(&[0.0], &[0.01], 1.0, 1.0, 0.01) - 1.0).abs() < 1e-12);
    }
}
