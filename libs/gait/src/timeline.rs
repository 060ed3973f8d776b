//! When each foot moves: a walk's footsteps laid out in time, and the ZMP reference that goes
//! with them.
//!
//! Each step is a double support, in which the ZMP reference moves in a straight line from
//! the last support foot's sole centre (or, at the start, from where it stands) to the
//! support foot of the step, then a single support, in which the other foot swings to its
//! footstep and the reference stays on the support foot. After the last step a final double
//! support brings the reference to the midpoint of the feet, where it stays.
//!
//! Step times follow LOLA's rule (its section 5.3): T = clamp(Δl / |v|, T_min, T_max) with Δl
//! the swing foot's travel, unless the plan gives a step its own duration.

use serde::Deserialize;

use crate::support::P2;
use crate::swing::{Place, SwingConfig, SwingPath};
use crate::GaitError;

/// A foot: left or right.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Side {
    /// The left foot.
    Left,
    /// The right foot.
    Right,
}

impl Side {
    /// 0 for the left foot, 1 for the right.
    pub fn index(self) -> usize {
        match self {
            Side::Left => 0,
            Side::Right => 1,
        }
    }

    /// The other foot.
    pub fn other(self) -> Side {
        match self {
            Side::Left => Side::Right,
            Side::Right => Side::Left,
        }
    }
}

/// One footstep of a plan: which foot moves, and where to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Footstep {
    /// The step number at which the walk executes it.
    pub number: i64,
    /// The foot that swings.
    pub side: Side,
    /// Where its sole's centre lands (x, y, z m) and its heading (rad).
    pub place: Place,
    /// The swing's apex above the higher of its two contacts, m (0: only the clearance).
    pub swing_height: f64,
    /// The step's duration, s (0: the timing rule's).
    pub duration: f64,
    /// An in-place step that pads a short plan.
    pub padding: bool,
}

/// The step timing (LOLA's rule) and the double supports.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimingConfig {
    /// Shortest step, s.
    pub t_min: f64,
    /// Longest step, s.
    pub t_max: f64,
    /// Walking speed |v| of the rule, m/s.
    pub speed: f64,
    /// The double support's share of a step (0 to below 1).
    pub double_support: f64,
    /// The final double support, s, and how long the pattern then holds still.
    pub settle: f64,
    /// How long the pattern goes on standing after the settle, s (the COM comes to rest).
    pub rest: f64,
    /// A walk from standing first stands still this long (the preview controller starts the
    /// COM moving, the ZMP reference not yet), s.
    pub lead: f64,
    /// ... and shifts the ZMP reference to the first support foot over at least this long, s.
    pub start_shift: f64,
    /// Where on a sole the ZMP reference stands: this far ahead of its centre, m (a foot whose
    /// ankle is well behind the sole's centre stands easier with the ZMP nearer the ankle).
    #[serde(default)]
    pub zmp_ahead: f64,
}

impl Default for TimingConfig {
    fn default() -> TimingConfig {
        TimingConfig {
            t_min: 1.0,
            t_max: 2.0,
            speed: 0.3,
            double_support: 0.25,
            settle: 0.8,
            rest: 1.0,
            lead: 1.0,
            start_shift: 0.8,
            zmp_ahead: 0.0,
        }
    }
}

/// The longest of a step's times, s: a pattern's samples are sized by them.
pub const MAX_TIME: f64 = 10.0;

impl TimingConfig {
    /// Checks the parameters.
    pub fn check(&self) -> Result<(), GaitError> {
        let ok = self.t_min.is_finite()
            && self.t_min > 0.0
            && self.t_max >= self.t_min
            && self.t_max <= MAX_TIME
            && self.settle <= MAX_TIME
            && self.rest <= MAX_TIME
            && self.lead <= MAX_TIME
            && self.start_shift <= MAX_TIME
            && self.speed.is_finite()
            && self.speed > 0.0
            && (0.0..1.0).contains(&self.double_support)
            && self.settle.is_finite()
            && self.settle > 0.0
            && self.rest.is_finite()
            && self.rest >= 0.0
            && self.lead.is_finite()
            && self.lead >= 0.0
            && self.start_shift.is_finite()
            && self.start_shift >= 0.0
            && self.zmp_ahead.is_finite();
        if ok {
            Ok(())
        } else {
            Err(GaitError::Parameter(format!(
                "timing: need 0 < t_min <= t_max, a positive speed and settle, a double support \
                 share in [0, 1), a rest, a lead and a start shift >= 0, each time at most \
                 {MAX_TIME} s: {self:?}"
            )))
        }
    }

    /// LOLA's step time for a swing of `travel` m.
    pub fn step_time(&self, travel: f64) -> f64 {
        (travel / self.speed).clamp(self.t_min, self.t_max)
    }
}

/// A step laid out in time (absolute times, s).
#[derive(Debug, Clone, PartialEq)]
pub struct Step {
    /// The footstep.
    pub footstep: Footstep,
    /// Where the swing foot starts.
    pub from: Place,
    /// Where the support foot stands.
    pub support: Place,
    /// The step's start (its double support begins).
    pub start: f64,
    /// Lift-off (the double support ends).
    pub lift: f64,
    /// Touch-down (the step ends).
    pub land: f64,
    /// The swing's path over [lift, land].
    pub swing: SwingPath,
}

/// A walk's steps in time, from a stance.
#[derive(Debug, Clone, PartialEq)]
pub struct Timeline {
    /// When the timeline starts, s.
    pub start: f64,
    /// Where the ZMP reference is at the start.
    pub zmp_start: P2,
    /// The feet at the start: left, right.
    pub feet_start: [Place; 2],
    /// The steps.
    pub steps: Vec<Step>,
    /// The feet after the last step.
    pub feet_end: [Place; 2],
    /// When the final double support ends.
    pub settled: f64,
    /// Where the ZMP reference ends (None: the midpoint of the feet's ZMP points).
    pub hold: Option<P2>,
    /// The ZMP reference's point on a sole, ahead of its centre, m.
    pub zmp_ahead: f64,
    /// With no steps: when the reference starts moving to its end (it reaches it at
    /// `settled`).
    pub shift_from: f64,
    /// When the timeline ends.
    pub end: f64,
}

/// The sole centre of a place, in the plane.
pub fn xy(p: &Place) -> P2 {
    [p[0], p[1]]
}

fn lerp(a: P2, b: P2, s: f64) -> P2 {
    [a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1])]
}

/// What the feet do at an instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Phase {
    /// Both feet on the ground; in step `step` (None: before the first or after the last).
    Double {
        /// The step whose double support this is.
        step: Option<usize>,
    },
    /// One foot on the ground, the other swinging in step `step`, `fraction` of its swing
    /// done.
    Single {
        /// The step.
        step: usize,
        /// The foot that swings.
        swing: Side,
        /// The share of the swing done.
        fraction: f64,
    },
}

impl Timeline {
    /// Lays out `steps` from the feet `feet` (left, right) starting at `start` with the ZMP
    /// reference at `zmp`; `durations` overrides the timing rule per step (0 or missing:
    /// the rule). The first step's double support moves the reference from `zmp`; from
    /// standing (`from_rest`) after the lead, over at least the start shift.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        start: f64,
        zmp: P2,
        feet: [Place; 2],
        steps: &[Footstep],
        durations: &[f64],
        timing: &TimingConfig,
        swing: &SwingConfig,
        from_rest: bool,
    ) -> Result<Timeline, GaitError> {
        timing.check()?;
        let mut t = if from_rest && !steps.is_empty() {
            start + timing.lead
        } else {
            start
        };
        let mut now = feet;
        let mut out = Vec::with_capacity(steps.len());
        for (i, f) in steps.iter().enumerate() {
            if !f.place.iter().all(|v| v.is_finite())
                || !f.swing_height.is_finite()
                || !f.duration.is_finite()
            {
                return Err(GaitError::Plan(format!(
                    "step {}: not a finite footstep",
                    f.number
                )));
            }
            let from = now[f.side.index()];
            let support = now[f.side.other().index()];
            let travel = (f.place[0] - from[0]).hypot(f.place[1] - from[1]);
            let rule = timing.step_time(travel);
            let given = durations.get(i).copied().filter(|d| *d > 0.0);
            let dur = given.unwrap_or(if f.duration > 0.0 { f.duration } else { rule });
            // A step's time sizes the pattern's samples: bounded before any is made.
            if !(timing.t_min * (1.0 - 1e-9)..=timing.t_max * (1.0 + 1e-9)).contains(&dur) {
                return Err(GaitError::Plan(format!(
                    "step {}: a duration of {} s, outside [{}, {}]",
                    f.number,
                    crate::short(dur),
                    timing.t_min,
                    timing.t_max
                )));
            }
            let mut ds = timing.double_support * dur;
            if from_rest && i == 0 {
                ds = ds.max(timing.start_shift);
            }
            let lift = t + ds;
            let land = lift + (1.0 - timing.double_support) * dur;
            let over = from[2].max(f.place[2]) + f.swing_height.max(0.0);
            let path = SwingPath::new(from, f.place, over, land - lift, swing)?;
            out.push(Step {
                footstep: *f,
                from,
                support,
                start: t,
                lift,
                land,
                swing: path,
            });
            now[f.side.index()] = f.place;
            t = land;
        }
        let settled = t + timing.settle;
        let waits = out.is_empty() && from_rest;
        let lead = if waits { timing.lead } else { 0.0 };
        Ok(Timeline {
            start,
            zmp_start: zmp,
            feet_start: feet,
            steps: out,
            feet_end: now,
            settled: settled + lead,
            hold: None,
            zmp_ahead: timing.zmp_ahead,
            shift_from: start + lead,
            end: settled + lead + timing.rest,
        })
    }

    /// The index of the step under way at `t` (the last started), if any.
    pub fn step_at(&self, t: f64) -> Option<usize> {
        self.step_started(t, self.steps.partition_point(|s| s.start <= t))
    }

    /// [`Timeline::step_at`] with `started` the number of steps started by `t`.
    #[inline]
    fn step_started(&self, t: f64, started: usize) -> Option<usize> {
        if started == 0 || t >= self.steps[started - 1].land {
            None
        } else {
            Some(started - 1)
        }
    }

    /// The phase at `t`.
    pub fn phase(&self, t: f64) -> Phase {
        self.phase_in(t, self.step_at(t))
    }

    /// The phase at `t` in step `step` (see [`Timeline::step_at`]).
    #[inline]
    fn phase_in(&self, t: f64, step: Option<usize>) -> Phase {
        match step {
            Some(i) if t >= self.steps[i].lift => {
                let s = &self.steps[i];
                Phase::Single {
                    step: i,
                    swing: s.footstep.side,
                    fraction: ((t - s.lift) / (s.land - s.lift)).clamp(0.0, 1.0),
                }
            }
            step => Phase::Double { step },
        }
    }

    /// The ZMP reference's point on a foot's sole.
    pub fn zmp_point(&self, p: &Place) -> P2 {
        let (s, c) = p[3].sin_cos();
        [p[0] + c * self.zmp_ahead, p[1] + s * self.zmp_ahead]
    }

    /// Where the ZMP reference ends.
    pub fn zmp_end(&self) -> P2 {
        self.hold.unwrap_or_else(|| {
            lerp(
                self.zmp_point(&self.feet_end[0]),
                self.zmp_point(&self.feet_end[1]),
                0.5,
            )
        })
    }

    /// The ZMP reference at `t`.
    pub fn zmp_ref(&self, t: f64) -> P2 {
        let i = self.steps.partition_point(|s| s.start <= t);
        self.zmp_ref_at(
            t,
            i,
            &|k| self.zmp_point(&self.steps[k].support),
            self.zmp_end(),
        )
    }

    /// The ZMP reference at the times `t0 + k · dt` for k in `0..count`, as
    /// [`Timeline::zmp_ref`] gives it, each step's point on its sole found once.
    pub fn zmp_refs(&self, t0: f64, dt: f64, count: usize) -> Vec<P2> {
        let points: Vec<P2> = self
            .steps
            .iter()
            .map(|s| self.zmp_point(&s.support))
            .collect();
        let end = self.zmp_end();
        let mut i = 0;
        (0..count)
            .map(|k| {
                let t = t0 + k as f64 * dt;
                while i < self.steps.len() && self.steps[i].start <= t {
                    i += 1;
                }
                self.zmp_ref_at(t, i, &|k| points[k], end)
            })
            .collect()
    }

    /// The ZMP reference at `t`, with `started` the number of steps started by then, a
    /// step's point on its sole `point(k)` and the end's `end`.
    fn zmp_ref_at(&self, t: f64, started: usize, point: &dyn Fn(usize) -> P2, end: P2) -> P2 {
        if self.steps.first().is_some_and(|s| t < s.start) {
            return self.zmp_start;
        }
        if t < self.start || self.steps.is_empty() {
            return if self.steps.is_empty() && t >= self.start {
                let s = ((t - self.shift_from) / (self.settled - self.shift_from)).clamp(0.0, 1.0);
                lerp(self.zmp_start, end, s)
            } else {
                self.zmp_start
            };
        }
        let n = self.steps.len();
        let last = &self.steps[n - 1];
        if t >= last.land {
            let s = ((t - last.land) / (self.settled - last.land)).clamp(0.0, 1.0);
            return lerp(point(n - 1), end, s);
        }
        let i = started.max(1) - 1;
        let s = &self.steps[i];
        let to = point(i);
        if t >= s.lift {
            return to;
        }
        let from = if i == 0 { self.zmp_start } else { point(i - 1) };
        lerp(from, to, (t - s.start) / (s.lift - s.start))
    }

    /// The ground's height under the COM at `t`: the support foot's in single support; in
    /// double support moving from the last support's to the next's as the ZMP reference
    /// does; standing, the feet's mean.
    pub fn ground(&self, t: f64) -> f64 {
        let mean = |f: &[Place; 2]| (f[0][2] + f[1][2]) / 2.0;
        if self.steps.is_empty() || t < self.steps[0].start {
            return mean(&self.feet_start);
        }
        let last = self.steps.last().unwrap();
        if t >= last.land {
            let s = ((t - last.land) / (self.settled - last.land)).clamp(0.0, 1.0);
            return last.support[2] + s * (mean(&self.feet_end) - last.support[2]);
        }
        let i = self.steps.partition_point(|s| s.start <= t).max(1) - 1;
        let s = &self.steps[i];
        if t >= s.lift {
            return s.support[2];
        }
        let from = if i == 0 {
            mean(&self.feet_start)
        } else {
            self.steps[i - 1].support[2]
        };
        from + (s.support[2] - from) * (t - s.start) / (s.lift - s.start)
    }

    /// The feet at `t`: each foot's place, velocity and acceleration (left, right).
    pub fn feet(&self, t: f64) -> [[Place; 3]; 2] {
        self.feet_lifted(t, self.steps.partition_point(|s| s.lift <= t))
    }

    /// The feet at `t`, with `lifted` the number of steps lifted off by then: each foot is
    /// where the last step of it took it.
    #[inline]
    fn feet_lifted(&self, t: f64, lifted: usize) -> [[Place; 3]; 2] {
        let mut feet = [
            [self.feet_start[0], [0.0; 4], [0.0; 4]],
            [self.feet_start[1], [0.0; 4], [0.0; 4]],
        ];
        let mut found = [false; 2];
        for s in self.steps[..lifted].iter().rev() {
            let k = s.footstep.side.index();
            if found[k] {
                continue;
            }
            found[k] = true;
            feet[k] = if t >= s.land {
                [s.footstep.place, [0.0; 4], [0.0; 4]]
            } else {
                s.swing.at(t - s.lift)
            };
            if found[1 - k] {
                break;
            }
        }
        feet
    }

    /// A walk through the timeline at times that never decrease (a pattern's samples): the
    /// feet and the phase at each, found from where the last were.
    pub fn cursor(&self) -> Cursor<'_> {
        Cursor {
            tl: self,
            lifted: 0,
            started: 0,
        }
    }

    /// The feet on the ground at `t` (sole centres and headings).
    pub fn on_ground(&self, t: f64) -> Vec<Place> {
        let feet = self.feet(t);
        match self.phase(t) {
            Phase::Single { swing, .. } => vec![feet[swing.other().index()][0]],
            Phase::Double { .. } => vec![feet[0][0], feet[1][0]],
        }
    }
}

/// See [`Timeline::cursor`]: [`Cursor::at`] gives what [`Timeline::feet`] and
/// [`Timeline::phase`] give, for times that never decrease.
#[derive(Debug, Clone)]
pub struct Cursor<'a> {
    tl: &'a Timeline,
    /// Steps lifted off by the last time.
    lifted: usize,
    /// Steps started by the last time.
    started: usize,
}

impl Cursor<'_> {
    /// The feet (place, velocity, acceleration; left, right) and the phase at `t`, no
    /// earlier than the last `t` asked for.
    #[inline(always)]
    pub fn at(&mut self, t: f64) -> ([[Place; 3]; 2], Phase) {
        let phase = self.phase(t);
        (self.tl.feet_lifted(t, self.lifted), phase)
    }

    /// The phase at `t`, no earlier than the last `t` asked for.
    #[inline(always)]
    pub fn phase(&mut self, t: f64) -> Phase {
        let steps = &self.tl.steps;
        while self.lifted < steps.len() && steps[self.lifted].lift <= t {
            self.lifted += 1;
        }
        while self.started < steps.len() && steps[self.started].start <= t {
            self.started += 1;
        }
        self.tl.phase_in(t, self.tl.step_started(t, self.started))
    }
}
