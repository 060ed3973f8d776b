//! The joints' rows in time as a gait plays them (walker time, s: positions and velocities per
//! group of joints), and the stream of them to the trajectory bridges: which rows went out,
//! where a new pattern joins what was sent. Pure bookkeeping: the app publishes.

use crate::archie::JointPlan;
use crate::hexapod::HexRow;
use stride_limits::moves::{min_jerk, min_jerk_time};

/// Rows of joints in time (walker time, s): positions and velocities per group, in group
/// order.
#[derive(Debug, Clone, PartialEq)]
pub struct Rows {
    /// When each row plays, walker time.
    pub times: Vec<f64>,
    /// Per group: a row of its joints per time.
    pub pos: Vec<Vec<Vec<f64>>>,
    /// Per group: the velocities of its joints per time.
    pub vel: Vec<Vec<Vec<f64>>>,
    /// Archie's: the pattern's start (walker time) and the stabiliser's hip correction.
    of: Option<(f64, [f64; 2])>,
}

impl Rows {
    /// The rows of an Archie joint plan starting at `start` (walker time), the stabiliser's
    /// hip correction `stab` (roll, pitch) added.
    pub fn of_plan(start: f64, plan: &JointPlan, stab: [f64; 2]) -> Rows {
        let mut r = Rows {
            times: Vec::with_capacity(plan.times.len()),
            pos: vec![Vec::new(), Vec::new()],
            vel: vec![Vec::new(), Vec::new()],
            of: Some((start, stab)),
        };
        r.extend(plan);
        r
    }

    /// Takes the rows of `plan` (those it was made of, and more) not taken yet.
    pub fn extend(&mut self, plan: &JointPlan) {
        let Some((start, stab)) = self.of else {
            return;
        };
        for i in self.times.len()..plan.times.len() {
            self.times.push(start + plan.times[i]);
            for (g, rows) in [&plan.left, &plan.right].into_iter().enumerate() {
                let mut q = rows.positions[i].to_vec();
                q[1] += stab[0];
                q[2] += stab[1];
                self.pos[g].push(q);
                self.vel[g].push(rows.velocities[i].to_vec());
            }
        }
    }

    /// The hexapod's rows (servo degrees as radians) from `start`.
    pub fn hexapod(start: f64, rows: &[HexRow]) -> Rows {
        Rows {
            times: rows.iter().map(|r| start + r.t).collect(),
            pos: vec![rows
                .iter()
                .map(|r| {
                    r.servo_deg
                        .iter()
                        .flatten()
                        .map(|d| d.to_radians())
                        .collect()
                })
                .collect()],
            vel: vec![rows
                .iter()
                .map(|r| r.speed.iter().flatten().copied().collect())
                .collect()],
            of: None,
        }
    }

    /// One row holding `q` (a row per group) at `t`.
    pub fn hold(t: f64, q: &[Vec<f64>]) -> Rows {
        Rows {
            times: vec![t],
            pos: q.iter().map(|g| vec![g.clone()]).collect(),
            vel: q.iter().map(|g| vec![vec![0.0; g.len()]]).collect(),
            of: None,
        }
    }

    /// A minimum-jerk move of every group from `from` to `to` (a row of each group's joints)
    /// starting at `start`: one time for all groups, the longest any needs so that no joint
    /// passes `speed` at its peak (at least `min_time`), rows every `dt`.
    pub fn move_to(
        start: f64,
        from: &[Vec<f64>],
        to: &[Vec<f64>],
        speed: f64,
        min_time: f64,
        dt: f64,
    ) -> Rows {
        let secs = from
            .iter()
            .zip(to)
            .map(|(a, b)| min_jerk_time(a, b, speed, min_time, dt))
            .fold(min_time, f64::max);
        let mut rows = Rows {
            times: Vec::new(),
            pos: Vec::new(),
            vel: Vec::new(),
            of: None,
        };
        for (a, b) in from.iter().zip(to) {
            let m = min_jerk(a, b, secs, dt);
            rows.times = m.times.iter().map(|x| start + x).collect();
            rows.pos.push(m.positions);
            rows.vel.push(m.velocities);
        }
        rows
    }

    /// The last row's time.
    pub fn end(&self) -> f64 {
        self.times.last().copied().unwrap_or(0.0)
    }

    /// Positions and velocities of group `g` at walker time `t` (between rows, linear; held
    /// past the ends).
    pub fn at(&self, g: usize, t: f64) -> (Vec<f64>, Vec<f64>) {
        let i = self.times.partition_point(|&x| x <= t);
        if i == 0 {
            return (self.pos[g][0].clone(), vec![0.0; self.pos[g][0].len()]);
        }
        if i >= self.times.len() {
            let l = self.times.len() - 1;
            return (self.pos[g][l].clone(), vec![0.0; self.pos[g][l].len()]);
        }
        let (a, b) = (i - 1, i);
        let s = (t - self.times[a]) / (self.times[b] - self.times[a]);
        let mix = |x: &[f64], y: &[f64]| x.iter().zip(y).map(|(p, q)| p + s * (q - p)).collect();
        (
            mix(&self.pos[g][a], &self.pos[g][b]),
            mix(&self.vel[g][a], &self.vel[g][b]),
        )
    }
}

/// The rows being played and how far they went to the trajectory bridges.
#[derive(Debug, Clone, PartialEq)]
pub struct Stream {
    /// The rows.
    pub rows: Rows,
    /// The last row sent (None: nothing of these rows yet: the next chunk replaces).
    sent: Option<usize>,
    /// A pattern just taken: its first chunk goes out at once, not when the lookahead
    /// reaches it (the drives' bridges have the change as early as they can).
    fresh: bool,
    /// Nothing goes to the trajectory bridges (they stand still already).
    quiet: bool,
}

impl Stream {
    /// Standing on `rows`, quiet.
    pub fn quiet(rows: Rows) -> Stream {
        Stream {
            rows,
            sent: None,
            fresh: false,
            quiet: true,
        }
    }

    /// True while nothing goes to the trajectory bridges.
    pub fn is_quiet(&self) -> bool {
        self.quiet
    }

    /// Sends nothing more (the rows stay, for set-points and tracking).
    pub fn silence(&mut self) {
        self.quiet = true;
    }

    /// Holds `rows`, quiet (a stand after a halt, the pose reached).
    pub fn hold(&mut self, rows: Rows) {
        *self = Stream::quiet(rows);
    }

    /// Plays `rows` from their start, replacing what was sent (a move into the pose).
    pub fn play(&mut self, rows: Rows) {
        self.rows = rows;
        self.sent = None;
        self.quiet = false;
    }

    /// Plays a new pattern's `rows` at walker time `t`. Rows that start where the stream
    /// sent so far ends are appended there; rows that start ahead (a plan taken, a stand: the
    /// walker switches beyond what was sent) replace from their start; rows that start in the
    /// past keep what was sent (a plan refused with nothing to change): the stream goes on
    /// from the last row sent, or, quiet, stays quiet. False when such rows do not continue
    /// what was sent (they are not streamed: the stream falls quiet).
    pub fn adopt(&mut self, rows: Rows, t: f64) -> bool {
        let stream_end = self.end_sent(t);
        let mut joined = true;
        self.fresh = true;
        if stream_end.is_some_and(|e| (rows.times[0] - e).abs() < 1e-6) {
            self.sent = Some(0);
        } else if rows.times[0] > t {
            self.sent = None;
            self.quiet = false;
        } else {
            let last_sent = self.sent.map(|i| self.rows.times[i]);
            self.sent = last_sent.and_then(|ts| {
                let i = rows
                    .times
                    .partition_point(|&x| x <= ts + 1e-9)
                    .checked_sub(1)?;
                ((rows.times[i] - ts).abs() < 1e-6).then_some(i)
            });
            if self.sent.is_none() && !self.quiet {
                joined = false;
                self.quiet = true;
            }
        }
        self.rows = rows;
        joined
    }

    /// The time of the last row sent to the trajectory bridges, while a stream runs at `t`
    /// (not once its last row has passed: a pattern then starts from now, not back there).
    pub fn end_sent(&self, t: f64) -> Option<f64> {
        if self.quiet {
            return None;
        }
        self.sent.map(|i| self.rows.times[i]).filter(|&e| e >= t)
    }

    /// The next chunk to send at `t`, of at most `n` + 1 rows: its first and last row and
    /// whether it appends to what was sent; counted as sent. None when nothing is due (the
    /// last row sent is `lookahead` ahead of `t`, the rows are all sent, or quiet).
    pub fn next_chunk(&mut self, t: f64, lookahead: f64, n: usize) -> Option<(usize, usize, bool)> {
        if self.quiet || self.rows.times.len() < 2 {
            self.fresh = false;
            return None;
        }
        let last = self.rows.times.len() - 1;
        let (i0, append) = match self.sent {
            Some(i) if i >= last => {
                self.fresh = false;
                return None;
            }
            Some(i) if self.rows.times[i] >= t + lookahead && !self.fresh => return None,
            Some(i) => (i, true),
            None => (0, false),
        };
        let i1 = (i0 + n.max(1)).min(last);
        self.sent = Some(i1);
        self.fresh = false;
        Some((i0, i1, append))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rows(from: f64, n: usize) -> Rows {
        let times: Vec<f64> = (0..n).map(|k| from + k as f64 * 0.01).collect();
        let q: Vec<Vec<f64>> = times.iter().map(|&t| vec![t]).collect();
        Rows {
            pos: vec![q.clone()],
            vel: vec![vec![vec![1.0]; n]],
            times,
            of: None,
        }
    }

    #[test]
    fn a_stream_sends_its_chunks_ahead_and_a_new_pattern_joins_at_the_last_row_sent() {
        let mut s = Stream::quiet(rows(0.0, 100));
        assert_eq!(s.next_chunk(0.0, 0.15, 10), None);
        s.play(rows(0.0, 100));
        assert_eq!(s.next_chunk(0.0, 0.15, 10), Some((0, 10, false)));
        assert_eq!(s.next_chunk(0.0, 0.15, 10), Some((10, 20, true)));
        // 0.2 s sent, 0.15 s ahead: nothing due until t passes 0.05.
        assert_eq!(s.next_chunk(0.0, 0.15, 10), None);
        assert_eq!(s.next_chunk(0.06, 0.15, 10), Some((20, 30, true)));
        assert!((s.end_sent(0.06).unwrap() - 0.3).abs() < 1e-9);
        // A pattern from the last row sent is appended there, its first chunk at once.
        assert!(s.adopt(rows(0.3, 50), 0.07));
        assert_eq!(s.next_chunk(0.07, 0.15, 10), Some((0, 10, true)));
        // One from ahead replaces from its start.
        assert!(s.adopt(rows(0.5, 50), 0.08));
        assert_eq!(s.next_chunk(0.08, 0.15, 10), Some((0, 10, false)));
        // One from the past that does not meet a row sent is not streamed.
        assert!(!s.adopt(rows(0.0051, 50), 0.2));
        assert!(s.is_quiet() && s.next_chunk(0.2, 0.15, 10).is_none());
    }

    #[test]
    fn a_move_into_the_pose_takes_one_time_for_every_group() {
        // The left leg 1 rad from its pose, the right 0.01 rad: both move for the left's
        // time (each group's own time gave rows the length of the last group's move, the
        // other's positions cut short or read past their end).
        let from = [vec![0.0, 1.0], vec![0.0, 0.01]];
        let to = [vec![0.0, 0.0], vec![0.0, 0.0]];
        let r = Rows::move_to(2.0, &from, &to, 0.5, 1.0, 0.01);
        let n = r.times.len();
        assert!((r.end() - 2.0 - 3.75).abs() < 1e-9, "{}", r.end());
        for g in 0..2 {
            assert_eq!((r.pos[g].len(), r.vel[g].len()), (n, n));
            assert!(r.pos[g][n - 1].iter().all(|q| q.abs() < 1e-12));
        }
        let peak = r.vel[0].iter().map(|v| v[1].abs()).fold(0.0, f64::max);
        assert!(peak <= 0.5 + 1e-9, "{peak}");
    }

    #[test]
    fn rows_interpolate_between_and_hold_past_their_ends() {
        let r = rows(1.0, 3);
        assert_eq!(r.at(0, 1.005), (vec![1.005], vec![1.0]));
        assert_eq!(r.at(0, 0.0), (vec![1.0], vec![0.0]));
        assert_eq!(r.at(0, 9.0), (vec![1.02], vec![0.0]));
        assert_eq!(r.end(), 1.02);
    }
}
