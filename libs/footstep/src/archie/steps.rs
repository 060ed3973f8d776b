//! Footsteps along a path of waypoints (seed 000, §2.7): the centre of mass advances along the
//! path, the feet alternate beside it.
//!
//! - [`faithful`]: the thesis's `footStepPoseComputation`, to the letter: 0.3 m steps with the
//!   remainder on the last one, turns on the spot in two or three steps whatever their size,
//!   a closing step after every segment, and (behind a flag) its first-foot bug.
//! - [`improved`]: the first foot where it is, heading changes wrapped, runs of segments that
//!   turn by at most `max_yaw` cut into equal lengths of path (no distance lost, none
//!   overlong, no short step at a bend), each step along the chord between its two points of
//!   the path; large heading changes on the spot in steps of at most `max_yaw`.

use crate::geom::{v2, wrap, Circle, V2};
use crate::plan::Foot;

/// Step geometry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepParams {
    /// Longest advance of the centre of mass per step, m (thesis: 0.3).
    pub max_step: f64,
    /// Lateral distance from the centre of mass to a foot, m (thesis: 0.1).
    pub half_stance: f64,
    /// Heading changes below this are ignored, rad (thesis: 0.01).
    pub turn_threshold: f64,
    /// The foot's centre lies this far ahead of its reference point, m (thesis: 0.0375).
    pub foot_offset: f64,
    /// Largest heading change between two footholds (improved), rad.
    pub max_yaw: f64,
}

impl Default for StepParams {
    fn default() -> Self {
        StepParams {
            max_step: 0.3,
            half_stance: 0.1,
            turn_threshold: 0.01,
            foot_offset: 0.0375,
            max_yaw: 20f64.to_radians(),
        }
    }
}

/// The footprint's size: 0.225 m long, 0.1 m wide.
pub const FOOT: (f64, f64) = (0.225, 0.1);

/// One walk parameter: COM advance, lateral offset, heading.
type Walk = (f64, f64, f64);

/// The feet of a walk-parameter sequence from `hip0`: odd indices are left feet when
/// `odd_left`, right feet otherwise.
fn feet(hip0: V2, s: &[Walk], odd_left: bool) -> Vec<Foot> {
    let mut hip = hip0;
    let mut out = Vec::new();
    for (jj, &(sx, sy, th)) in s.iter().enumerate().skip(1) {
        hip = hip + v2(th.cos(), th.sin()) * sx;
        let left = (jj % 2 == 1) == odd_left;
        let sign = if left { -1.0 } else { 1.0 }; // (-1)^jj for odd left feet
        out.push(Foot {
            z: 0.0,
            p: hip + v2(sign * th.sin() * sy, -sign * th.cos() * sy),
            yaw: th,
            left,
        });
    }
    out
}

/// The point of the path a foot of these steps stands beside (its hip): `half_stance` to the
/// foot's inner side, as [`feet`] placed it.
pub fn hip(foot: &Foot, half_stance: f64) -> V2 {
    let inward = if foot.left { -half_stance } else { half_stance };
    foot.p + v2(-foot.yaw.sin(), foot.yaw.cos()) * inward
}

/// The thesis's footsteps for `waypoints` with the headings `dirs` (the heading of the segment
/// ending at each waypoint). `first_foot_bug` keeps the thesis's `px = py + x` for the first
/// foot.
pub fn faithful(waypoints: &[V2], dirs: &[f64], p: &StepParams, first_foot_bug: bool) -> Vec<Foot> {
    let (mx, my) = (p.max_step, p.half_stance);
    let w0 = waypoints[0];
    let py = -my;
    let px = if first_foot_bug { py + w0.x } else { w0.x };
    let mut out = vec![Foot {
        z: 0.0,
        p: v2(px, py + w0.y),
        yaw: 0.0,
        left: false,
    }];
    let mut s: Vec<Walk> = vec![(0.0, 0.0, 0.0), (0.0, my, 0.0)];
    for ii in 0..waypoints.len().saturating_sub(1) {
        let d = waypoints[ii].dist(waypoints[ii + 1]);
        let num = (d / mx).round() as usize;
        let th = dirs[ii + 1];
        let head_diff = th - dirs[ii]; // not wrapped, as in the thesis
        let nb = s.len();
        if head_diff.abs() > p.turn_threshold {
            if (head_diff > 0.0 && nb.is_multiple_of(2))
                || (head_diff < 0.0 && !nb.is_multiple_of(2))
            {
                s.extend([(0.0, my, dirs[ii]), (0.0, my, th), (0.0, my, th)]);
            } else {
                s.extend([(0.0, my, th), (0.0, my, th)]);
            }
        }
        let rest = d / mx - num as f64;
        for g in 0..num {
            let sx = if g + 1 == num { mx + rest * mx } else { mx };
            s.push((sx, my, th));
        }
        s.push((0.0, my, th));
    }
    out.extend(feet(w0, &s, true));
    out
}

/// Improved footsteps along `waypoints`, starting with the feet side by side at `start_yaw`
/// (right foot first in the list, then the steps).
pub fn improved(waypoints: &[V2], start_yaw: f64, p: &StepParams) -> Vec<Foot> {
    improved_from(waypoints, start_yaw, p, None)
}

/// [`improved`], or, with `swing_left` given (the feet known, walking on), the stance foot
/// first in the list, then the steps from the swing foot's on: the walk goes on with the
/// foot that swings next instead of first setting it beside the other.
pub fn improved_from(
    waypoints: &[V2],
    start_yaw: f64,
    p: &StepParams,
    swing_left: Option<bool>,
) -> Vec<Foot> {
    let my = p.half_stance;
    let w0 = waypoints[0];
    let stance_left = swing_left == Some(false);
    let side = if stance_left { -1.0 } else { 1.0 };
    let mut out = vec![Foot {
        z: 0.0,
        p: w0 + v2(side * start_yaw.sin() * my, -side * start_yaw.cos() * my),
        yaw: start_yaw,
        left: stance_left,
    }];
    let (mut s, odd_left): (Vec<Walk>, bool) = match swing_left {
        None => (vec![(0.0, 0.0, start_yaw), (0.0, my, start_yaw)], true),
        Some(l) => (vec![(0.0, 0.0, start_yaw)], l),
    };
    let mut heading = start_yaw;
    // The foot that steps next: odd indices of s are left feet when `odd_left`.
    let left_next = |s: &Vec<Walk>| (s.len() % 2 == 1) == odd_left;
    let segs: Vec<(V2, V2)> = waypoints
        .windows(2)
        .filter(|w| w[0].dist(w[1]) >= 1e-9)
        .map(|w| (w[0], w[1]))
        .collect();
    let mut k = 0;
    while k < segs.len() {
        let th = (segs[k].1 - segs[k].0).angle();
        let turn = wrap(th - heading);
        if turn.abs() > p.max_yaw {
            // Stop (feet together), then turn on the spot, the foot on the turn's side leading,
            // in equal increments of at most max_yaw.
            if s.last().is_some_and(|w| w.0 != 0.0) {
                s.push((0.0, my, heading));
            }
            if (turn > 0.0) != left_next(&s) {
                s.push((0.0, my, heading));
            }
            let n = (turn.abs() / p.max_yaw).ceil() as usize;
            for i in 1..=n {
                let h = heading + turn * i as f64 / n as f64;
                s.extend([(0.0, my, h), (0.0, my, h)]);
            }
            heading = th;
        }
        // A run: the segments from here on that each turn by at most max_yaw from the last.
        let mut end = k + 1;
        while end < segs.len() {
            let (a, b) = (segs[end - 1], segs[end]);
            if wrap((b.1 - b.0).angle() - (a.1 - a.0).angle()).abs() > p.max_yaw {
                break;
            }
            end += 1;
        }
        let run: Vec<V2> = std::iter::once(segs[k].0)
            .chain(segs[k..end].iter().map(|s| s.1))
            .collect();
        let steps = run_steps(&run, heading, p).unwrap_or_else(|| {
            // Turning too fast for steps cut along it: each segment in its own steps.
            run.windows(2)
                .flat_map(|w| {
                    let (d, th) = ((w[1] - w[0]).norm(), (w[1] - w[0]).angle());
                    let n = (d / p.max_step).ceil().max(1.0) as usize;
                    std::iter::repeat_n((d / n as f64, th), n)
                })
                .collect()
        });
        for (d, th) in steps {
            s.push((d, my, th));
            heading = th;
        }
        k = end;
    }
    // Feet together at the end.
    s.push((0.0, my, heading));
    out.extend(feet(w0, &s, odd_left));
    out
}

/// Steps (advance, heading) along the polyline `run` from heading `heading`: equal lengths of
/// path, as few as max_step allows, each taken along the chord between its ends, so the hips
/// lie on the path and a short segment (the rest of one the walk is on, a tangent point just
/// ahead) does not make a short step of its own. More steps where the chords would turn by
/// more than max_yaw; None where even steps a centimetre long would.
fn run_steps(run: &[V2], heading: f64, p: &StepParams) -> Option<Vec<(f64, f64)>> {
    let lengths: Vec<f64> = run.windows(2).map(|w| w[0].dist(w[1])).collect();
    let total: f64 = lengths.iter().sum();
    let at = |s: f64| {
        let mut s = s;
        for (k, &l) in lengths.iter().enumerate() {
            if s <= l || k + 1 == lengths.len() {
                return run[k] + (run[k + 1] - run[k]) * (s / l).min(1.0);
            }
            s -= l;
        }
        run[run.len() - 1]
    };
    let fewest = (total / p.max_step).ceil().max(1.0) as usize;
    let most = (total / 0.01).ceil().max(1.0) as usize;
    let mut n = fewest;
    while n <= most {
        let mut steps = Vec::with_capacity(n);
        let (mut from, mut h) = (run[0], heading);
        let mut fits = true;
        for j in 1..=n {
            let to = if j == n {
                run[run.len() - 1]
            } else {
                at(total * j as f64 / n as f64)
            };
            let th = (to - from).angle();
            if wrap(th - h).abs() > p.max_yaw + 1e-9 {
                fits = false;
                break;
            }
            steps.push(((to - from).norm(), th));
            (from, h) = (to, th);
        }
        if fits {
            return Some(steps);
        }
        n = (n + 1).max(n * 5 / 4);
    }
    None
}

/// True when the footprint of `f` (the [`FOOT`] box around its centre) overlaps circle `c`.
pub fn footprint_hits(f: &Foot, offset: f64, c: &Circle) -> bool {
    let dir = v2(f.yaw.cos(), f.yaw.sin());
    let centre = f.p + dir * offset;
    let rel = c.c - centre;
    let (lx, ly) = (rel.dot(dir), rel.cross(dir).abs());
    let dx = (lx.abs() - FOOT.0 / 2.0).max(0.0);
    let dy = (ly - FOOT.1 / 2.0).max(0.0);
    dx.hypot(dy) < c.r
}

#[cfg(test)]
mod tests {
    use super::*;

    fn near(f: &Foot, x: f64, y: f64, yaw_deg: f64) -> bool {
        (f.p.x - x).abs() < 1e-4
            && (f.p.y - y).abs() < 1e-4
            && (f.yaw.to_degrees() - yaw_deg).abs() < 1e-6
    }

    #[test]
    #[allow(clippy::approx_constant)] // the golden vectors as printed, to four places
    fn thesis_golden_vectors() {
        let p = StepParams::default();
        let f = faithful(&[v2(0.0, 0.0), v2(1.0, 0.0)], &[0.0, 0.0], &p, true);
        let want = [
            (-0.1, -0.1),
            (0.0, 0.1),
            (0.3, -0.1),
            (0.6, 0.1),
            (1.0, -0.1),
            (1.0, 0.1),
        ];
        assert_eq!(f.len(), want.len());
        for (k, (x, y)) in want.iter().enumerate() {
            assert!(near(&f[k], *x, *y, 0.0), "#{k}: {:?}", f[k]);
        }
        assert!(f[1].left && !f[2].left);
        let q = std::f64::consts::FRAC_PI_4;
        let f = faithful(&[v2(0.0, 0.0), v2(1.0, 1.0)], &[0.0, q], &p, true);
        let want = [
            (-0.1, -0.1, 0.0),
            (0.0, 0.1, 0.0),
            (0.0, -0.1, 0.0),
            (-0.0707, 0.0707, 45.0),
            (0.0707, -0.0707, 45.0),
            (0.1414, 0.2828, 45.0),
            (0.4950, 0.3536, 45.0),
            (0.5657, 0.7071, 45.0),
            (0.9192, 0.7778, 45.0),
            (0.9293, 1.0707, 45.0),
            (1.0707, 0.9293, 45.0),
        ];
        assert_eq!(f.len(), want.len());
        for (k, (x, y, a)) in want.iter().enumerate() {
            assert!(near(&f[k], *x, *y, *a), "#{k}: {:?}", f[k]);
        }
        // Without the bug the first foot is beside the start.
        let f = faithful(&[v2(0.0, 0.0), v2(1.0, 0.0)], &[0.0, 0.0], &p, false);
        assert!(near(&f[0], 0.0, -0.1, 0.0));
    }

    #[test]
    fn improved_steps_alternate_keep_their_yaw_limit_and_cover_the_path() {
        let p = StepParams::default();
        let path = [v2(0.0, 0.0), v2(1.0, 0.05), v2(1.2, 1.5), v2(-0.5, 1.6)];
        let f = improved(&path, 0.0, &p);
        // Alternating sides, the last two side by side and parallel.
        for w in f.windows(2) {
            assert_ne!(w[0].left, w[1].left);
            assert!(wrap(w[1].yaw - w[0].yaw).abs() <= p.max_yaw + 1e-9, "{w:?}");
        }
        let (a, b) = (f[f.len() - 2], f[f.len() - 1]);
        assert!((a.yaw - b.yaw).abs() < 1e-12);
        assert!((a.p.dist(b.p) - 2.0 * p.half_stance).abs() < 1e-9);
        // The feet end beside the goal.
        let mid = (a.p + b.p) * 0.5;
        assert!(mid.dist(path[3]) < 1e-9, "{mid:?}");
        // Every foot beside a point of the path.
        for x in &f {
            let h = hip(x, p.half_stance);
            let off = path
                .windows(2)
                .map(|w| crate::geom::point_segment_distance(h, w[0], w[1]))
                .fold(f64::INFINITY, f64::min);
            assert!(off < 1e-9, "{x:?}: {off} m off the path");
        }
        // No step longer than max_step.
        let hips: Vec<V2> = f.iter().map(|x| x.p).collect();
        for k in 2..hips.len() {
            assert!(hips[k].dist(hips[k - 2]) <= 2.0 * p.max_step + 1e-9);
        }
    }

    #[test]
    fn a_walk_replanned_goes_on_with_the_swing_foot_instead_of_stepping_in_place() {
        // Replanned at every step, a plan whose first step set the swing foot beside the
        // other (or stepped the other foot first) would have the robot step in place for
        // ever: with the feet known, the list is the stance foot, then the swing foot's step
        // forward, alternating from there, whichever foot swings.
        let p = StepParams::default();
        let path = [v2(0.0, 0.0), v2(1.0, 0.0)];
        for swing_left in [true, false] {
            let f = improved_from(&path, 0.0, &p, Some(swing_left));
            assert_eq!(f[0].left, !swing_left, "the stance foot first");
            assert_eq!(f[1].left, swing_left, "then the swing foot");
            assert!(f[1].p.x > 0.2, "its step goes forward: {:?}", f[1]);
            for w in f.windows(2) {
                assert_ne!(w[0].left, w[1].left);
            }
            let (a, b) = (f[f.len() - 2], f[f.len() - 1]);
            assert!(((a.p + b.p) * 0.5).dist(path[1]) < 1e-9);
        }
        // Without the feet: both feet listed where they stand, the right foot first.
        let f = improved_from(&path, 0.0, &p, None);
        assert_eq!(f, improved(&path, 0.0, &p));
        assert!(!f[0].left && f[1].left && f[1].p.x.abs() < 1e-12);
    }
}
