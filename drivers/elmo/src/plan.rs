//! One axis's motion as the drive will play it, and the checks of it. Pure: times are µs on
//! the master's clock ("plan time"), positions rad, velocities rad/s; no bus.
//!
//! A plan is a run of knots: the last ones already sent to the drive (kept for context), then
//! those still to send. What the drive does between two knots depends on the table mode:
//! a cubic Hermite through both knots' positions and velocities (PVT), a cubic whose slopes
//! the drive takes from the neighbouring points (PT: zero at the motion's first point and
//! where no next point has arrived), or a line (interpolated position). Every check is of
//! that motion, exactly ([`Cubic::extremes`]): positions, speeds and accelerations between
//! knots, not only at them.

use std::collections::VecDeque;

use crate::curve::Cubic;

/// Where a knot comes from, to name it in a refusal.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Tag {
    /// Row `n` of the trajectory (or a point between row `n - 1` and row `n`).
    Row(usize),
    /// The state the trajectory starts from (what is queued, or where the joint stands).
    Join,
    /// The stop after a chunk that ended in motion.
    Stop,
}

/// A point of the motion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Knot {
    /// Plan time, µs.
    pub t: i64,
    /// Position, rad.
    pub p: f64,
    /// Velocity, rad/s (PVT: the row's velocity; otherwise the motion's, for information).
    pub v: f64,
    /// Where it comes from.
    pub tag: Tag,
    /// The first knot of a motion started from rest (PT gives it a zero slope).
    pub first: bool,
}

/// How the drive interpolates between knots.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Interp {
    /// PVT rows: cubic Hermite; rows at most 255 ms apart.
    Pvt,
    /// PT points every `period` µs: cubic, slopes from the neighbours.
    Pt {
        /// µs between points.
        period: i64,
    },
    /// Interpolated position every `period` µs: linear.
    Ip {
        /// µs between set-points.
        period: i64,
    },
}

/// The longest PVT row, µs (the row's time field is 8 bits of ms).
pub const PVT_MAX_ROW_US: i64 = 255_000;

/// A joint's limits as the checks use them.
pub use stride_limits::curve::Bounds;

/// What a check found beyond a limit.
#[derive(Debug, Clone, PartialEq)]
pub struct Violation {
    /// The knot at the segment's end.
    pub tag: Tag,
    /// What and by how much, in words.
    pub what: String,
}

impl Interp {
    /// The drive's curve of segment `i` (from `k[i]` to `k[i + 1]`). `k` must hold the
    /// knots the drive has around it: for PT one before and one after where they exist.
    pub fn curve(self, k: &[Knot], i: usize) -> Cubic {
        let (a, b) = (k[i], k[i + 1]);
        let h = (b.t - a.t) as f64 * 1e-6;
        match self {
            Interp::Pvt => Cubic::hermite(a.p, a.v, b.p, b.v, h),
            Interp::Ip { .. } => Cubic::line(a.p, b.p, h),
            Interp::Pt { period } => {
                let t2 = 2.0 * period as f64 * 1e-6;
                let s0 = if a.first || i == 0 {
                    0.0
                } else {
                    (b.p - k[i - 1].p) / t2
                };
                let s1 = match k.get(i + 2) {
                    Some(c) => (c.p - a.p) / t2,
                    None => 0.0,
                };
                Cubic::hermite(a.p, s0, b.p, s1, h)
            }
        }
    }

    /// Checks the motion of `k` from segment `from` on against `b`; `t0` is the plan time
    /// the figures are given from (the trajectory's start).
    pub fn check(self, k: &[Knot], from: usize, b: &Bounds, t0: i64) -> Result<(), Violation> {
        let secs = |t: i64| (t - t0) as f64 * 1e-6;
        for i in from..k.len().saturating_sub(1) {
            let c = self.curve(k, i);
            let e = c.extremes();
            // A line has no acceleration inside; between two lines it is the change of
            // speed over a period (the drive's position loop smooths the corner).
            let acc = match self {
                Interp::Ip { period } => {
                    let v = (k[i + 1].p - k[i].p) / ((k[i + 1].t - k[i].t) as f64 * 1e-6);
                    let before = if i == 0 || k[i].first {
                        0.0
                    } else {
                        (k[i].p - k[i - 1].p) / ((k[i].t - k[i - 1].t) as f64 * 1e-6)
                    };
                    let after_end = if i + 2 >= k.len() { v.abs() } else { 0.0 };
                    (
                        (v - before).abs().max(after_end) / (period as f64 * 1e-6),
                        0.0,
                    )
                }
                _ => e.a,
            };
            if let Some(what) = stride_limits::curve::beyond(&e, acc, b, secs(k[i].t)) {
                return Err(Violation {
                    tag: k[i + 1].tag,
                    what,
                });
            }
        }
        Ok(())
    }
}

/// One axis's plan: knots sent (the last few, for context), knots to send, and where a
/// stream chunk's provisional stop begins.
#[derive(Debug, Clone)]
pub struct Plan {
    interp: Interp,
    sent: VecDeque<Knot>,
    pending: VecDeque<Knot>,
    /// A chunk that ended in motion: from this plan time on, the pending knots are its stop.
    tail: Option<i64>,
    /// The last knot sent was the motion's last row.
    ended: bool,
}

/// Plan time after a motion's last row from which the next motion may start (the drive has
/// ended the first one by then).
pub const RESTART_US: i64 = 10_000;

/// Knots sent that a plan keeps for context.
const CONTEXT: usize = 3;

impl Plan {
    /// An empty plan.
    pub fn new(interp: Interp) -> Plan {
        Plan {
            interp,
            sent: VecDeque::new(),
            pending: VecDeque::new(),
            tail: None,
            ended: false,
        }
    }

    /// The interpolation.
    pub fn interp(&self) -> Interp {
        self.interp
    }

    /// Forgets everything (the drive dropped its table).
    pub fn clear(&mut self) -> usize {
        let n = self.pending.len();
        self.sent.clear();
        self.pending.clear();
        self.tail = None;
        self.ended = false;
        n
    }

    /// The drive ended the motion: the sent knots are history, the next motion starts from
    /// rest.
    pub fn finish(&mut self) {
        self.sent.clear();
        self.ended = false;
    }

    /// True when nothing is left to send.
    pub fn is_empty(&self) -> bool {
        self.pending.is_empty()
    }

    /// Knots not yet sent.
    pub fn pending(&self) -> &VecDeque<Knot> {
        &self.pending
    }

    /// The last knot sent.
    pub fn last_sent(&self) -> Option<&Knot> {
        self.sent.back()
    }

    /// The plan time from which the plan may still change: the first knot not sent (its time
    /// is fixed once the row before it went out, its state is not), or `None` when nothing
    /// was sent and all may change.
    pub fn horizon(&self) -> Option<i64> {
        let last = self.sent.back()?;
        Some(match self.pending.front() {
            Some(k) => k.t,
            None if self.ended => last.t + RESTART_US,
            None => last.t + 1,
        })
    }

    /// The end of the plan: its last knot.
    pub fn end(&self) -> Option<&Knot> {
        self.pending.back().or(self.sent.back())
    }

    /// Where a stream chunk ended, if the plan ends in its provisional stop.
    pub fn tail(&self) -> Option<i64> {
        self.tail
    }

    /// The end a chunk appended now would follow: the start of the provisional stop, or the
    /// plan's end.
    pub fn chunk_end(&self) -> Option<i64> {
        self.tail.or(self.end().map(|k| k.t))
    }

    /// All knots, sent then pending.
    fn knots(&self) -> Vec<Knot> {
        self.sent
            .iter()
            .chain(self.pending.iter())
            .copied()
            .collect()
    }

    /// Position and velocity at plan time `t` as the drive plays the plan; past its end the
    /// end position at rest; `None` before its first knot.
    pub fn state_at(&self, t: i64) -> Option<(f64, f64)> {
        let k = self.knots();
        let first = k.first()?;
        if t < first.t {
            return None;
        }
        let last = k.last()?;
        if t >= last.t {
            return Some((last.p, if self.tail.is_some() { last.v } else { 0.0 }));
        }
        let i = k.partition_point(|x| x.t <= t) - 1;
        let c = self.interp.curve(&k, i);
        Some(c.at((t - k[i].t) as f64 * 1e-6))
    }

    /// The plan with the knots from plan time `s` on replaced by `new` (and `tail` the start
    /// of their provisional stop), checked from the first segment it changes; the number of
    /// knots it drops. Nothing changes when the check fails.
    pub fn splice(
        &mut self,
        s: i64,
        new: Vec<Knot>,
        tail: Option<i64>,
        bounds: &Bounds,
        t0: i64,
    ) -> Result<usize, Violation> {
        let keep = self.pending.iter().filter(|k| k.t < s).count();
        // After the motion's last row the drive starts anew: the new knots are checked from
        // rest, on their own.
        let context: Vec<Knot> = if self.ended {
            Vec::new()
        } else {
            self.sent.iter().copied().collect()
        };
        let mut k: Vec<Knot> = context;
        let changed = k.len() + keep;
        k.extend(self.pending.iter().take(keep).copied());
        k.extend(new.iter().copied());
        // PT: the two segments before a changed point change with it (slopes).
        let look_back = match self.interp {
            Interp::Pt { .. } => 2,
            Interp::Ip { .. } => 1,
            Interp::Pvt => 1,
        };
        self.interp
            .check(&k, changed.saturating_sub(look_back), bounds, t0)?;
        let dropped = self.pending.len() - keep;
        self.pending.truncate(keep);
        self.pending.extend(new);
        self.tail = tail;
        Ok(dropped)
    }

    /// The next knot to send if it is due by plan time `until` (and the drive is not to end
    /// the motion first), with µs to the knot after it (PVT puts it in the row; the last row
    /// of a motion gets the shortest time). It stays pending until [`Plan::sent_front`].
    pub fn next(&self, until: i64) -> Option<(Knot, i64)> {
        let k = *self.pending.front()?;
        if k.t > until || self.ended {
            // Not due, or the drive must end the motion first (see [`Plan::finish`]).
            return None;
        }
        let dt = match self.pending.get(1) {
            // A new motion after this one starts from rest with its own start.
            Some(n) if n.first => 1000,
            Some(n) => n.t - k.t,
            // The end at rest: a plan in its stop always ends at rest, so no motion ends
            // unknown.
            None => 1000,
        };
        Some((k, dt))
    }

    /// The knot [`Plan::next`] gave went out.
    pub fn sent_front(&mut self) {
        let Some(k) = self.pending.pop_front() else {
            return;
        };
        if k.first {
            self.sent.clear();
        }
        self.ended = self.pending.front().is_none_or(|n| n.first);
        self.sent.push_back(k);
        while self.sent.len() > CONTEXT {
            self.sent.pop_front();
        }
        if self.tail.is_some_and(|t| k.t >= t) {
            // The stop is under way: a chunk can no longer follow the one that ended.
            self.tail = None;
        }
    }

    /// True once the plan's last knot went out as the motion's last row: the drive ends
    /// the motion there, and what follows starts a new one.
    pub fn ended(&self) -> bool {
        self.ended
    }
}

/// The knots of a stop from `(p, v)` at plan time `t` at acceleration `a` (at most), on a grid
/// of `grid` µs from `origin`: the motion `p + v τ - sign(v) a' τ² / 2` to rest, with `a'` the
/// acceleration that ends it on the grid (never above `a`).
pub fn stop(t: i64, p: f64, v: f64, a: f64, interp: Interp, grid: i64) -> Vec<Knot> {
    if v == 0.0 {
        return Vec::new();
    }
    let secs = v.abs() / a;
    let steps = ((secs * 1e6) / grid as f64 - 1e-9).ceil().max(1.0) as i64;
    let dur = steps * grid;
    let d = dur as f64 * 1e-6;
    let a = v.abs() / d;
    let at = |tau: f64| {
        (
            p + v * tau - v.signum() * a * tau * tau / 2.0,
            v - v.signum() * a * tau,
        )
    };
    let step = match interp {
        Interp::Pvt => PVT_MAX_ROW_US.min(dur) / grid * grid,
        Interp::Pt { period } | Interp::Ip { period } => period,
    };
    let step = step.max(grid);
    let mut out = Vec::new();
    let mut tau = step;
    while tau < dur {
        let (pp, vv) = at(tau as f64 * 1e-6);
        out.push(Knot {
            t: t + tau,
            p: pp,
            v: vv,
            tag: Tag::Stop,
            first: false,
        });
        tau += step;
    }
    let (pe, _) = at(d);
    out.push(Knot {
        t: t + dur,
        p: pe,
        v: 0.0,
        tag: Tag::Stop,
        first: false,
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const B: Bounds = Bounds {
        min: -1.0,
        max: 1.0,
        v: 3.0,
        a: 30.0,
    };

    fn knot(t_ms: i64, p: f64, v: f64, tag: Tag) -> Knot {
        Knot {
            t: t_ms * 1000,
            p,
            v,
            tag,
            first: false,
        }
    }

    #[test]
    fn the_motion_between_rows_is_what_is_checked() {
        // Rows 0 and 0.5 rad 1 ms apart at rest: each row is inside every limit, the cubic
        // between them is not.
        let k = [
            knot(0, 0.0, 0.0, Tag::Row(0)),
            knot(1, 0.5, 0.0, Tag::Row(1)),
        ];
        let e = Interp::Pvt.check(&k, 0, &B, 0).unwrap_err();
        assert_eq!(e.tag, Tag::Row(1));
        assert!(e.what.starts_with("velocity 750.000 rad/s"), "{}", e.what);
        // The same rows 0.5 s apart are fine.
        let k = [
            knot(0, 0.0, 0.0, Tag::Row(0)),
            knot(500, 0.5, 0.0, Tag::Row(1)),
        ];
        Interp::Pvt.check(&k, 0, &B, 0).unwrap();
    }

    #[test]
    fn pt_points_are_checked_with_the_slopes_the_drive_gives_them() {
        // Two points 0.45 rad apart 10 ms apart from rest: the drive's cubic starts and ends
        // with zero slope, so it peaks at 1.5 x 45 = 67.5 rad/s.
        let pt = Interp::Pt { period: 10_000 };
        let mut k = vec![
            knot(0, 0.0, 0.0, Tag::Row(0)),
            knot(10, 0.45, 0.0, Tag::Row(1)),
        ];
        k[0].first = true;
        let e = pt.check(&k, 0, &B, 0).unwrap_err();
        assert!(e.what.starts_with("velocity 67.500"), "{}", e.what);
        // A slow ramp of points is fine, and its slopes come from the neighbours.
        let k: Vec<Knot> = (0..20)
            .map(|i| knot(10 * i, 0.01 * i as f64, 0.0, Tag::Row(i as usize)))
            .collect();
        // From rest to 1 rad/s in the first 10 ms is 400 rad/s²; between, a steady speed.
        assert!(pt
            .check(&k, 0, &B, 0)
            .unwrap_err()
            .what
            .starts_with("acceleration 400.0"));
        for i in 1..18 {
            let e = pt.curve(&k, i).extremes();
            assert!(e.a.0 < 1e-9 && (e.v.0 - 1.0).abs() < 1e-9, "{i}: {e:?}");
        }
        let c = pt.curve(&k, 5);
        assert!((c.at(0.0).1 - 1.0).abs() < 1e-9);
    }

    #[test]
    fn interpolated_position_speed_changes_count_as_acceleration() {
        let ip = Interp::Ip { period: 10_000 };
        // From rest to 1 rad/s in one period: 100 rad/s², beyond 30.
        let k = [
            knot(0, 0.0, 0.0, Tag::Row(0)),
            knot(10, 0.01, 0.0, Tag::Row(1)),
        ];
        assert!(ip
            .check(&k, 0, &B, 0)
            .unwrap_err()
            .what
            .starts_with("acceleration 100.0"));
    }

    #[test]
    fn a_stop_decelerates_at_the_limit_and_ends_at_rest() {
        // 2 rad/s at 30 rad/s²: 66.7 ms, ends on the 1 ms grid at 67 ms, 0.067 rad further.
        let s = stop(0, 0.0, 2.0, 30.0, Interp::Pvt, 1000);
        let end = *s.last().unwrap();
        assert_eq!((end.t, end.v), (67_000, 0.0));
        assert!((end.p - 2.0 * 0.067 / 2.0).abs() < 1e-12);
        let mut k = vec![
            knot(-10, -0.02, 2.0, Tag::Row(0)),
            knot(0, 0.0, 2.0, Tag::Row(1)),
        ];
        k.extend(s);
        Interp::Pvt.check(&k, 1, &B, 0).unwrap();
        // The same stop as PT points, one every 10 ms, checked as the drive plays them.
        let pt = Interp::Pt { period: 10_000 };
        let s = stop(0, 0.0, 1.0, 30.0, pt, 10_000);
        assert_eq!(s.last().unwrap().t, 40_000);
        assert!(s.windows(2).all(|w| w[1].t - w[0].t == 10_000));
    }

    #[test]
    fn splicing_replaces_from_its_time_and_keeps_what_was_sent() {
        let mut plan = Plan::new(Interp::Pvt);
        let rows: Vec<Knot> = (0..=10)
            .map(|i| knot(10 * i, 0.0, 0.0, Tag::Row(i as usize)))
            .collect();
        plan.splice(0, rows, None, &B, 0).unwrap();
        assert_eq!(plan.horizon(), None);
        // Send the first three rows: the plan may change from the fourth's time on.
        for _ in 0..3 {
            plan.next(i64::MAX).unwrap();
            plan.sent_front();
        }
        assert_eq!(plan.horizon(), Some(30_000));
        // A new motion from 50 ms drops rows 5..10; the join at 50 ms is checked.
        let new = vec![
            knot(50, 0.0, 0.0, Tag::Row(0)),
            knot(250, 0.2, 0.0, Tag::Row(1)),
        ];
        assert_eq!(plan.splice(50_000, new, None, &B, 50_000), Ok(6));
        assert_eq!(plan.end().unwrap().p, 0.2);
        // A jump at the join is refused, and nothing changes.
        let bad = vec![knot(60, 0.9, 0.0, Tag::Row(0))];
        let before = plan.pending().len();
        assert!(plan.splice(60_000, bad, None, &B, 60_000).is_err());
        assert_eq!(plan.pending().len(), before);
        assert!((plan.state_at(150_000).unwrap().0 - 0.1).abs() < 1e-12);
    }
}
