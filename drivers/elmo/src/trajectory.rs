//! Trajectories as the master takes them: their shape and rows checked, and turned into the
//! knots of one axis's plan (PVT rows as they are, split where longer than a row can be; PT
//! and interpolated-position points sampled on the mode's period). Pure.

use crate::curve::Cubic;
use crate::error::MasterError;
use crate::plan::{Interp, Knot, Tag, PVT_MAX_ROW_US};

/// When a trajectory starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Start {
    /// As soon as the drives can: what is queued is replaced from the first moment it may
    /// still change (the end of what the drives were already sent).
    #[default]
    Now,
    /// At this time on the master's system clock (µs since the Unix epoch, UTC): what is
    /// queued from then on is replaced. Refused when it has passed, when the drives were
    /// already sent the motion up to later, or beyond the queue's bound.
    At(i64),
    /// After everything queued: the trajectory continues the chunk queued last (a stream).
    Append,
}

/// A trajectory in joint space: rows of positions (and velocities) at times.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Trajectory {
    /// Joint names, one per column, each once.
    pub joints: Vec<String>,
    /// Seconds from the start to each row (strictly increasing, the first 0 or later).
    pub times: Vec<f64>,
    /// Positions, rad: `positions[row][joint]`.
    pub positions: Vec<Vec<f64>>,
    /// Velocities, rad/s (PVT), same shape; empty for PT rows, whose velocities are the
    /// central differences of their positions, zero at the first and last row.
    pub velocities: Vec<Vec<f64>>,
    /// When it starts.
    pub start: Start,
}

impl Trajectory {
    /// The velocity of row `r` of column `c`: given, or (PT rows) derived.
    pub fn velocity(&self, r: usize, c: usize) -> f64 {
        if let Some(v) = self.velocities.get(r) {
            return v[c];
        }
        if r == 0 || r + 1 == self.positions.len() {
            return 0.0;
        }
        (self.positions[r + 1][c] - self.positions[r - 1][c])
            / (self.times[r + 1] - self.times[r - 1])
    }

    /// The row times in µs from the start.
    pub fn micros(&self) -> Vec<i64> {
        self.times
            .iter()
            .map(|t| (t * 1e6).round() as i64)
            .collect()
    }

    /// True when column `c` ends at rest (to rounding: below 1 nrad/s).
    pub fn ends_at_rest(&self, c: usize) -> bool {
        self.velocity(self.times.len() - 1, c).abs() < 1e-9
    }
}

fn bad(why: String) -> MasterError {
    MasterError::BadTrajectory(why)
}

/// The latest a row may be from its trajectory's start, s: far past any queue's bound, and
/// far inside the µs arithmetic's range.
pub const MAX_TIME_S: f64 = 1e6;

/// Checks what can be checked of a trajectory alone: joints known (by `find`) and named once,
/// one time and one row of the right width per row, times finite and strictly increasing
/// from 0 or later (up to [`MAX_TIME_S`]), PVT rows on whole milliseconds (`pvt`), every value finite and within
/// its joint's position and velocity limits (`limits`). Returns each column's joint.
pub fn check_shape<'a>(
    t: &Trajectory,
    find: impl FnMut(&str) -> Option<usize>,
    limits: impl Fn(usize) -> (&'a str, stride_limits::Limits),
    pvt: bool,
) -> Result<Vec<usize>, MasterError> {
    let cols = stride_limits::columns(&t.joints, find).map_err(|e| bad(e.to_string()))?;
    if cols.is_empty() {
        return Err(bad("no joints".into()));
    }
    if t.times.is_empty() || t.times.len() != t.positions.len() {
        return Err(bad(format!(
            "{} times for {} rows: one time per row, at least one row",
            t.times.len(),
            t.positions.len()
        )));
    }
    if !t.velocities.is_empty() && t.velocities.len() != t.positions.len() {
        return Err(bad("velocities and positions differ in rows".into()));
    }
    for (r, &time) in t.times.iter().enumerate() {
        if !time.is_finite() || time < 0.0 {
            return Err(bad(format!(
                "row {r}: time {time} s is not a time from the start"
            )));
        }
        if time > MAX_TIME_S {
            return Err(bad(format!(
                "row {r}: time {time} s from the start is past any queue (at most {MAX_TIME_S} s)"
            )));
        }
        if r > 0 && time <= t.times[r - 1] {
            return Err(bad(format!(
                "row {r}: time {time} s does not come after row {}'s {} s",
                r - 1,
                t.times[r - 1]
            )));
        }
        if pvt && ((time * 1e3) - (time * 1e3).round()).abs() > 1e-6 {
            return Err(bad(format!(
                "row {r}: {:.4} ms from the start; PVT rows lie on whole milliseconds",
                time * 1e3
            )));
        }
        if t.positions[r].len() != cols.len()
            || t.velocities.get(r).is_some_and(|v| v.len() != cols.len())
        {
            return Err(bad(format!("row {r} has the wrong number of joints")));
        }
    }
    for r in 0..t.times.len() {
        for (c, &j) in cols.iter().enumerate() {
            let (name, l) = limits(j);
            let row = |e: stride_limits::Reject| MasterError::Limit {
                row: r,
                joint: name.to_owned(),
                what: match e {
                    stride_limits::Reject::Limit { what, .. } => what,
                    e => e.to_string(),
                },
            };
            l.position(name, t.positions[r][c]).map_err(row)?;
            l.velocity(name, t.velocity(r, c)).map_err(row)?;
        }
    }
    Ok(cols)
}

/// The knots of column `c` played from plan time `s`: the trajectory's rows, with a first
/// knot at `s` in the state `join` when the first row comes later than the start; every
/// segment the Hermite cubic of its rows.
fn row_knots(t: &Trajectory, c: usize, s: i64, join: (f64, f64)) -> Vec<Knot> {
    let us = t.micros();
    let mut k = Vec::with_capacity(t.times.len() + 1);
    if us[0] > 0 {
        k.push(Knot {
            t: s,
            p: join.0,
            v: join.1,
            tag: Tag::Join,
            first: false,
        });
    }
    for (r, &dt) in us.iter().enumerate() {
        k.push(Knot {
            t: s + dt,
            p: t.positions[r][c],
            v: t.velocity(r, c),
            tag: Tag::Row(r),
            first: false,
        });
    }
    k
}

/// The knots of column `c` from plan time `s` as the drive will be sent them in `interp`:
/// PVT rows as they are (a segment longer than a row can be split on its own cubic); PT and
/// interpolated-position points sampled every period from `s` along the rows' cubics, the
/// last at the trajectory's end (a trajectory that ends at rest holds its last position to
/// the next period; one that ends in motion must end on a period).
pub fn knots(
    t: &Trajectory,
    c: usize,
    s: i64,
    join: (f64, f64),
    interp: Interp,
) -> Result<Vec<Knot>, MasterError> {
    let rows = row_knots(t, c, s, join);
    match interp {
        Interp::Pvt => {
            let mut out = vec![rows[0]];
            for w in rows.windows(2) {
                let (a, b) = (w[0], w[1]);
                let n = (b.t - a.t + PVT_MAX_ROW_US - 1) / PVT_MAX_ROW_US;
                if n > 1 {
                    let h = (b.t - a.t) as f64 * 1e-6;
                    let cubic = Cubic::hermite(a.p, a.v, b.p, b.v, h);
                    // Equal pieces on whole milliseconds.
                    let ms = (b.t - a.t) / 1000;
                    let step = (ms + n - 1) / n * 1000;
                    let mut at = a.t + step;
                    while at < b.t {
                        let (p, v) = cubic.at((at - a.t) as f64 * 1e-6);
                        out.push(Knot {
                            t: at,
                            p,
                            v,
                            tag: b.tag,
                            first: false,
                        });
                        at += step;
                    }
                }
                out.push(b);
            }
            Ok(out)
        }
        Interp::Pt { period } | Interp::Ip { period } => {
            let end = rows.last().expect("at least one row").t;
            let span = end - s;
            let at_rest = t.ends_at_rest(c);
            if span % period != 0 && !at_rest {
                return Err(bad(format!(
                    "it ends in motion {:.1} ms from its start, not on a {} ms period of the \
                     drives' table: a chunk of a stream spans whole periods",
                    span as f64 / 1000.0,
                    period / 1000
                )));
            }
            let n = (span + period - 1) / period;
            let mut out = Vec::with_capacity(n as usize + 1);
            let mut seg = 0;
            for i in 0..=n {
                let at = s + i * period;
                if at >= end {
                    let last = rows[rows.len() - 1];
                    out.push(Knot { t: at, ..last });
                    continue;
                }
                while rows[seg + 1].t <= at {
                    seg += 1;
                }
                let (a, b) = (rows[seg], rows[seg + 1]);
                let (p, v) = if at == a.t {
                    (a.p, a.v)
                } else {
                    Cubic::hermite(a.p, a.v, b.p, b.v, (b.t - a.t) as f64 * 1e-6)
                        .at((at - a.t) as f64 * 1e-6)
                };
                out.push(Knot {
                    t: at,
                    p,
                    v,
                    tag: if at == a.t { a.tag } else { b.tag },
                    first: false,
                });
            }
            Ok(out)
        }
    }
}

/// Knots that hold `p` at rest after plan time `from` and before `to` (the next knot's), as
/// far apart as a row may be.
pub fn hold(p: f64, from: i64, to: i64, interp: Interp) -> Vec<Knot> {
    let step = match interp {
        Interp::Pvt => PVT_MAX_ROW_US,
        Interp::Pt { period } | Interp::Ip { period } => period,
    };
    let mut out = Vec::new();
    let mut at = from + step;
    while at < to {
        out.push(Knot {
            t: at,
            p,
            v: 0.0,
            tag: Tag::Join,
            first: false,
        });
        at += step;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn one(times: &[f64], p: &[f64], v: &[f64]) -> Trajectory {
        Trajectory {
            joints: vec!["j".into()],
            times: times.to_vec(),
            positions: p.iter().map(|x| vec![*x]).collect(),
            velocities: v.iter().map(|x| vec![*x]).collect(),
            start: Start::Now,
        }
    }

    fn limits(_: usize) -> (&'static str, stride_limits::Limits) {
        (
            "j",
            stride_limits::Limits {
                min_position: -1.0,
                max_position: 1.0,
                max_velocity: 3.0,
            },
        )
    }

    fn find(n: &str) -> Option<usize> {
        (n == "j" || n == "k").then_some(usize::from(n == "k"))
    }

    #[test]
    fn shapes_that_cannot_be_played_are_refused() {
        let ok = one(&[0.0, 0.01], &[0.0, 0.01], &[0.0, 0.0]);
        assert_eq!(check_shape(&ok, find, limits, true).unwrap(), [0]);
        let mut twice = ok.clone();
        twice.joints = vec!["j".into(), "j".into()];
        twice.positions = vec![vec![0.0, 2.2], vec![0.0, 2.2]];
        twice.velocities.clear();
        let e = check_shape(&twice, find, limits, true).unwrap_err();
        assert!(e.to_string().contains("named twice"), "{e}");
        let back = one(&[0.0, 0.01, 0.005], &[0.0; 3], &[0.0; 3]);
        assert!(check_shape(&back, find, limits, true).is_err());
        let off_grid = one(&[0.0, 0.0125], &[0.0; 2], &[0.0; 2]);
        assert!(check_shape(&off_grid, find, limits, true)
            .unwrap_err()
            .to_string()
            .contains("whole milliseconds"));
        assert!(check_shape(&off_grid, find, limits, false).is_ok());
        let nan = one(&[0.0, f64::NAN], &[0.0; 2], &[0.0; 2]);
        assert!(check_shape(&nan, find, limits, true).is_err());
        let far = one(&[0.0, 0.01], &[0.0, 1.5], &[0.0, 0.0]);
        assert!(matches!(
            check_shape(&far, find, limits, true),
            Err(MasterError::Limit { row: 1, .. })
        ));
    }

    #[test]
    fn pvt_rows_longer_than_255_ms_are_split_on_their_own_cubic() {
        let t = one(&[0.0, 0.6], &[0.0, 0.6], &[0.0, 0.0]);
        let k = knots(&t, 0, 0, (0.0, 0.0), Interp::Pvt).unwrap();
        assert_eq!(
            k.iter().map(|k| k.t).collect::<Vec<_>>(),
            [0, 200_000, 400_000, 600_000]
        );
        let c = Cubic::hermite(0.0, 0.0, 0.6, 0.0, 0.6);
        assert_eq!((k[1].p, k[1].v), c.at(0.2));
    }

    #[test]
    fn pt_points_sample_the_rows_on_the_period() {
        let t = one(&[0.0, 0.05], &[0.0, 0.05], &[1.0, 1.0]);
        let k = knots(&t, 0, 1_000_000, (0.0, 0.0), Interp::Pt { period: 10_000 }).unwrap();
        assert_eq!(k.len(), 6);
        assert!(k
            .iter()
            .enumerate()
            .all(|(i, k)| (k.p - 0.01 * i as f64).abs() < 1e-12));
        // Ending in motion off the period is refused; at rest it holds to the period.
        let odd = one(&[0.0, 0.045], &[0.0, 0.045], &[1.0, 1.0]);
        assert!(knots(&odd, 0, 0, (0.0, 0.0), Interp::Pt { period: 10_000 }).is_err());
        let rest = one(&[0.0, 0.045], &[0.0, 0.045], &[0.0, 0.0]);
        let k = knots(&rest, 0, 0, (0.0, 0.0), Interp::Pt { period: 10_000 }).unwrap();
        assert_eq!((k.last().unwrap().t, k.last().unwrap().p), (50_000, 0.045));
        // A first row after the start joins from the given state.
        let late = one(&[0.02], &[0.1], &[0.0]);
        let k = knots(&late, 0, 0, (0.3, 0.0), Interp::Pvt).unwrap();
        assert_eq!((k[0].tag, k[0].p, k[1].t), (Tag::Join, 0.3, 20_000));
    }
}
