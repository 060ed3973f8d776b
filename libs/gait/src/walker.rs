//! The walk in step with a replanning footstep planner (KAIST's protocol, its section 3 and
//! the notes' R-I1 to R-I3), with no bus:
//!
//! - the walker counts its steps; a step's number is the one it carries from the plan (or
//!   the walker's own, for the in-place steps it adds);
//! - a plan answers a request made during step k (it echoes k) and holds the steps k + 1
//!   onwards, at least three, padded with in-place steps near the goal;
//! - a plan is taken only while the step it echoes is under way (or, standing, the last one
//!   taken): the newest plan whose number matches wins; a late plan is counted and dropped,
//!   never started from;
//! - a plan with a NaN, a step beyond the per-step limits (its time outside the timing's
//!   bounds too) or a foothold no leg reaches is refused with its reason and counted, and
//!   changes nothing: the walk goes on as if it never came (a peer that floods bad plans does
//!   not stop a walk; a planner whose plans are all refused is a lost planner, below);
//! - of a plan, only the first `steps_per_plan` steps after the step it was made for are
//!   walked unless a newer plan comes; then its next step stops the walk (shortened if the
//!   legs need it), the feet come side by side and the robot steps in place: a lost planner
//!   or link stops the robot's progress within a step of when it is noticed;
//! - when the taken plan's steps run out before the goal, the robot steps in place, for at
//!   most `plan_timeout` after the last valid plan; then, or on a stop, it brings its feet
//!   together and stands. A plan whose remaining steps are all padding, or that says its
//!   last step reaches the goal, has reached it: the robot stands there.
//!
//! Each change makes a new pattern from the state the current one has `switch_ahead` from
//! now (what was sent to the drives before then plays as it was), so the COM and a swing under
//! way continue without a jump.

use serde::Deserialize;
use stride_limits::angle::wrap;

use crate::pattern::{Generator, Pattern, Start};
use crate::swing::Place;
use crate::timeline::{Footstep, Phase, Side};
use crate::GaitError;

/// Checks a pattern against the robot's legs and their limits, up to a time of the pattern's
/// clock: as far as it can play before the walker replaces it (a plan's pattern gives way to
/// the next plan, or to the stop when none comes, within `steps_per_plan` + 1 steps);
/// infinite: all of it.
pub type JointsCheck<'a> = dyn Fn(&Pattern, f64) -> Result<(), GaitError> + 'a;

/// The per-step limits and the walker's timing.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WalkerConfig {
    /// Feet together: their spacing, m.
    pub stance_width: f64,
    /// A step's reach forward or back of the support foot, m.
    pub max_length: f64,
    /// A swing foot's least lateral distance from the support foot, m.
    pub min_width: f64,
    /// Its greatest, m.
    pub max_width: f64,
    /// A step's turn, rad.
    pub max_yaw: f64,
    /// A step's rise or fall, m.
    pub max_height: f64,
    /// How long the robot steps in place with no valid plan before it stands, s.
    pub plan_timeout: f64,
    /// A change takes over this long after it is decided (what was sent before plays), s.
    pub switch_ahead: f64,
    /// An in-place step's swing height, m.
    pub in_place_height: f64,
    /// How many of a plan's steps are walked while no newer plan comes: 1 walks the step after
    /// the one it was made for, then steps in place. A replanning planner answers at every
    /// step, so a lost planner or link stops the robot's progress within a step.
    #[serde(default = "steps_per_plan")]
    pub steps_per_plan: u32,
}

/// How long before a step is fixed (at the switch) the walker decides that no plan came for
/// it, s: a plan may come until then. A caller that ticks less often says so
/// ([`Walker::tick_ahead`]).
const STALE_DECISION: f64 = 0.1;

fn steps_per_plan() -> u32 {
    1
}

impl Default for WalkerConfig {
    fn default() -> WalkerConfig {
        WalkerConfig {
            stance_width: 0.2,
            max_length: 0.25,
            min_width: 0.12,
            max_width: 0.35,
            max_yaw: 0.35,
            max_height: 0.15,
            plan_timeout: 3.0,
            switch_ahead: 0.15,
            in_place_height: 0.03,
            steps_per_plan: steps_per_plan(),
        }
    }
}

/// A footstep plan as the walker takes it.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// The step number it echoes (the step under way when it was asked for).
    pub echo: i64,
    /// Its steps, numbered from `echo + 1`.
    pub steps: Vec<Footstep>,
    /// Its last step reaches the goal (the planner found the whole way): the robot stands
    /// there when it is done, as after padding steps, instead of stepping in place for the
    /// next plan.
    pub reaches_goal: bool,
}

/// What became of a plan.
#[derive(Debug, Clone, PartialEq)]
pub enum Verdict {
    /// Taken: its first step is the number given.
    Taken(i64),
    /// Its echo is not the step under way: dropped.
    Late {
        /// Its echo.
        echo: i64,
        /// The step under way.
        now: i64,
    },
    /// Refused, and why.
    Refused(String),
    /// Ignored: the walker is stopped.
    Stopped,
}

/// The walker's counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counters {
    /// Plans taken.
    pub taken: u64,
    /// Plans refused.
    pub refused: u64,
    /// Plans dropped as late.
    pub late: u64,
    /// In-place steps added.
    pub in_place: u64,
    /// Stops (commanded, or for want of a plan).
    pub stops: u64,
}

/// The step counter: what the walker publishes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepCounter {
    /// The step under way (standing: the last one taken).
    pub number: i64,
    /// The foot in the air, if any.
    pub swing: Option<Side>,
    /// The share of the step done, in [0, 1).
    pub phase: f64,
}

/// Checks a foothold (the robot's legs reach it from its support foot), outside the walker.
pub type Reach<'a> = &'a dyn Fn(&Footstep, &Place) -> Result<(), String>;

/// The walker.
#[derive(Debug, Clone)]
pub struct Walker {
    gen: Generator,
    cfg: WalkerConfig,
    pattern: Pattern,
    /// The number of the last step that was taken or started (standing: the last walked).
    last_number: i64,
    counters: Counters,
    /// When the last valid plan came.
    last_valid: f64,
    /// The step number the last taken plan echoed (at first, the walker's own).
    last_echo: i64,
    /// The goal was reached (the taken plan ended in padding).
    at_goal: bool,
    /// The taken plan ends the walk within the steps checked with it (it reaches the goal,
    /// and its last real step is the one a lost planner's walk would stop with): a caller
    /// that asks no more may have it walked to its end ([`Walker::finish_plan`]).
    ends_walk: bool,
    /// The pattern's steps ahead are a plan's (not the walker's own stand): they are walked
    /// only `steps_per_plan` beyond the last plan's echo.
    following: bool,
    /// Stopped by a command: plans are ignored until a resume.
    stopped: bool,
    /// Why the last change happened (or a plan was refused), for the status.
    note: String,
}

fn finite(f: &Footstep) -> bool {
    f.place.iter().all(|v| v.is_finite()) && f.swing_height.is_finite() && f.duration.is_finite()
}

fn rot(yaw: f64, v: [f64; 2]) -> [f64; 2] {
    let (s, c) = yaw.sin_cos();
    [c * v[0] - s * v[1], s * v[0] + c * v[1]]
}

impl Walker {
    /// A walker standing with its feet at `left` and `right` at time `now`, its step counter
    /// at `number`.
    pub fn new(
        gen: Generator,
        cfg: WalkerConfig,
        now: f64,
        left: Place,
        right: Place,
        number: i64,
    ) -> Result<Walker, GaitError> {
        let pattern = gen.generate(&gen.standing(now, left, right), &[], &[])?;
        Ok(Walker {
            gen,
            cfg,
            pattern,
            last_number: number,
            last_echo: number,
            counters: Counters::default(),
            last_valid: f64::NEG_INFINITY,
            at_goal: true,
            ends_walk: false,
            following: false,
            stopped: false,
            note: "standing".into(),
        })
    }

    /// The pattern under way.
    pub fn pattern(&self) -> &Pattern {
        &self.pattern
    }

    /// The generator.
    pub fn generator(&self) -> &Generator {
        &self.gen
    }

    /// The counters.
    pub fn counters(&self) -> Counters {
        self.counters
    }

    /// What happened last, in words.
    pub fn note(&self) -> &str {
        &self.note
    }

    /// True when stopped by a command.
    pub fn is_stopped(&self) -> bool {
        self.stopped
    }

    /// The step counter at `t`.
    pub fn counter(&self, t: f64) -> StepCounter {
        let tl = &self.pattern.timeline;
        match tl.step_at(t) {
            Some(i) => {
                let s = &tl.steps[i];
                StepCounter {
                    number: s.footstep.number,
                    swing: matches!(tl.phase(t), Phase::Single { .. }).then_some(s.footstep.side),
                    phase: ((t - s.start) / (s.land - s.start)).clamp(0.0, 1.0 - 1e-9),
                }
            }
            None => {
                let done = tl.steps.iter().take_while(|s| s.land <= t).last();
                StepCounter {
                    // Never below a step already counted (a stand after a refused plan has no
                    // step of its own).
                    number: done.map_or(self.last_number, |s| {
                        s.footstep.number.max(self.last_number)
                    }),
                    swing: None,
                    phase: 0.0,
                }
            }
        }
    }

    /// True when the robot stands still at `t` (no step under way or to come, the COM at
    /// rest).
    pub fn standing(&self, t: f64) -> bool {
        t >= self.pattern.timeline.end
    }

    /// Checks a plan's steps: finite, each within the per-step limits from the foot it steps
    /// from beside (the support foot), each foothold reachable.
    pub fn check(&self, plan: &Plan, feet: [Place; 2], reach: Reach) -> Result<(), String> {
        let c = &self.cfg;
        let timing = &self.gen.config().timing;
        let mut feet = feet;
        for f in &plan.steps {
            if !finite(f) {
                return Err(format!("step {}: not a finite footstep", f.number));
            }
            // 0: the timing rule's; else within its bounds (a step's time sizes its pattern).
            if f.duration != 0.0 && !(timing.t_min..=timing.t_max).contains(&f.duration) {
                return Err(format!(
                    "step {}: a duration of {} s, outside [{}, {}] (0: the timing rule's)",
                    f.number,
                    crate::short(f.duration),
                    timing.t_min,
                    timing.t_max
                ));
            }
            let support = feet[f.side.other().index()];
            // The step in the support foot's frame.
            let d = rot(
                -support[3],
                [f.place[0] - support[0], f.place[1] - support[1]],
            );
            let lateral = match f.side {
                Side::Left => d[1],
                Side::Right => -d[1],
            };
            let yaw = wrap(f.place[3] - support[3]);
            let dz = f.place[2] - support[2];
            let short = crate::short;
            let what = if d[0].abs() > c.max_length {
                Some(format!("{} m along, at most {}", short(d[0]), c.max_length))
            } else if lateral < c.min_width || lateral > c.max_width {
                Some(format!(
                    "{} m beside the support foot, outside [{}, {}]",
                    short(lateral),
                    c.min_width,
                    c.max_width
                ))
            } else if yaw.abs() > c.max_yaw {
                Some(format!("a turn of {yaw:.3} rad, at most {}", c.max_yaw))
            } else if dz.abs() > c.max_height {
                Some(format!(
                    "{} m up or down, at most {}",
                    short(dz),
                    c.max_height
                ))
            } else {
                None
            };
            if let Some(w) = what {
                return Err(format!("step {}: {w}", f.number));
            }
            reach(f, &support).map_err(|e| format!("step {}: {e}", f.number))?;
            feet[f.side.index()] = f.place;
        }
        Ok(())
    }

    /// The time a change decided at `now` takes over, and the state there (past the
    /// pattern's end, standing still there, at that time).
    fn switch(&self, now: f64) -> (usize, Start) {
        let t = now + self.cfg.switch_ahead;
        let k = self.pattern.index_at(t);
        let mut start = self.pattern.state_at(k);
        if t > start.t + self.pattern.dt {
            start.t = t;
            start.under_way = None;
        }
        (k, start)
    }

    /// The footsteps of the current pattern not started yet at sample `k` (the step under
    /// way is the start's).
    fn steps_from(&self, k: usize) -> Vec<Footstep> {
        let t = self.pattern.samples[k].t;
        let tl = &self.pattern.timeline;
        tl.steps
            .iter()
            .filter(|s| s.start > t)
            .map(|s| s.footstep)
            .collect()
    }

    /// Makes the pattern from the switch on: `steps` after the swing under way, if any,
    /// checked by `joints` (the robot's legs and their limits).
    fn replace(
        &mut self,
        now: f64,
        steps: Vec<Footstep>,
        joints: &JointsCheck,
    ) -> Result<(), GaitError> {
        self.replace_until(now, steps, None, false, joints)
    }

    /// [`Walker::replace`], the legs checked up to the touch-down of step `until` (a step
    /// number; None: to the end), and the whole body put under the pattern up to there too
    /// when the pattern is `replaced` before its later rows play ([`Generator::plan_until`]).
    fn replace_until(
        &mut self,
        now: f64,
        steps: Vec<Footstep>,
        until: Option<i64>,
        replaced: bool,
        joints: &JointsCheck,
    ) -> Result<(), GaitError> {
        let (_, start) = self.switch(now);
        let played = until.filter(|_| replaced);
        let pat = self.gen.plan_until(&start, &steps, played)?;
        let end = until
            .and_then(|n| {
                let tl = &pat.timeline;
                tl.steps
                    .iter()
                    .find(|s| s.footstep.number == n)
                    .map(|s| s.land)
            })
            .unwrap_or(f64::INFINITY);
        joints(&pat, end)?;
        // The steps landed before the switch stay counted.
        self.last_number = self.last_number.max(self.counter(start.t).number);
        self.pattern = pat;
        Ok(())
    }

    /// How many steps beyond the last that can play from a plan's pattern are made with it:
    /// those the preview of its last played sample sees (each step lasts at least t_min), and
    /// one more for the ZMP's shift toward it. The pattern's samples up to there are the
    /// whole plan's.
    fn previewed_steps(&self) -> usize {
        let c = self.gen.config();
        (c.preview.horizon / c.timing.t_min).ceil() as usize + 1
    }

    /// The step a plan that comes at `now` must echo to be taken (the step under way at the
    /// switch); None while stopped. A plan for another step is dropped as late.
    pub fn wanted_echo(&self, now: f64) -> Option<i64> {
        if self.stopped {
            return None;
        }
        let (_, start) = self.switch(now);
        Some(self.counter(start.t).number)
    }

    /// Takes a plan that came at `now` (see the module). `feet_reach` checks a foothold;
    /// `joints` checks a whole pattern against the legs and their limits.
    pub fn on_plan(
        &mut self,
        plan: &Plan,
        now: f64,
        reach: Reach,
        joints: &JointsCheck,
    ) -> Verdict {
        if self.stopped {
            return Verdict::Stopped;
        }
        let (k, start) = self.switch(now);
        let counter = self.counter(start.t);
        if plan.echo != counter.number {
            self.counters.late += 1;
            self.note = format!(
                "a plan for step {} came during step {}: dropped",
                plan.echo, counter.number
            );
            return Verdict::Late {
                echo: plan.echo,
                now: counter.number,
            };
        }
        // The feet the plan starts from: where the current pattern has them when its steps
        // up to the echo are done.
        let mut kept: Vec<Footstep> = self
            .steps_from(k)
            .into_iter()
            .filter(|f| f.number <= plan.echo)
            .collect();
        let mut feet = [start.feet[0][0], start.feet[1][0]];
        if let Some(u) = start.under_way {
            feet[u.footstep.side.index()] = u.footstep.place;
        }
        for f in &kept {
            feet[f.side.index()] = f.place;
        }
        let refuse = |me: &mut Walker, why: String| {
            me.counters.refused += 1;
            me.note = format!("plan refused: {why}");
            Verdict::Refused(why)
        };
        if let Err(why) = self.check(plan, feet, reach) {
            return refuse(self, why);
        }
        // Padding at the end is the goal: the robot stands instead.
        let mut steps: Vec<Footstep> = plan.steps.clone();
        let real = steps.iter().rposition(|f| !f.padding).map_or(0, |i| i + 1);
        let at_goal = plan.reaches_goal || real < steps.len() || steps.is_empty();
        steps.truncate(real);
        let first = steps.first().map_or(plan.echo + 1, |f| f.number);
        // What can play of the plan: its steps up to `steps_per_plan` beyond the echo, and the
        // next, with which the walk stops when no newer plan comes. The pattern is made of
        // those and the steps its preview sees; the legs are checked up to that next step's
        // touch-down. A plan's later steps give way to the next plan before they play.
        let walked = self.cfg.steps_per_plan as usize;
        let stop_step = steps.get(walked).map(|f| f.number);
        let ends_walk = at_goal && steps.len() <= walked + 1;
        steps.truncate(walked + 1 + self.previewed_steps());
        kept.extend(steps);
        // Unless it ends the walk, the pattern gives way before its later rows play: to the
        // next plan, or to the stop at `stop_step` when none comes.
        match self.replace_until(now, kept, stop_step, !ends_walk, joints) {
            Ok(()) => {
                self.counters.taken += 1;
                self.last_valid = now;
                self.last_echo = plan.echo;
                self.at_goal = at_goal;
                self.ends_walk = ends_walk;
                self.following = true;
                self.last_number = self.last_number.max(plan.echo);
                self.note = format!("plan for step {} taken", plan.echo);
                Verdict::Taken(first)
            }
            Err(e) => refuse(self, e.to_string()),
        }
    }

    /// Ends the walk soon: the steps already lifted land, then the feet come together and the
    /// robot stands.
    fn stand_soon(&mut self, now: f64) {
        self.following = false;
        let (_, start) = self.switch(now);
        let steps = self.together(&start, Vec::new());
        let ok = |_: &Pattern, _: f64| Ok(());
        if self.replace(now, steps, &ok).is_err() {
            // Keep what is under way: it ends standing too.
        }
    }

    /// `steps`, then a step that brings the feet together (the later foot beside the other
    /// at the stance width), when they are not.
    fn together(&self, start: &Start, mut steps: Vec<Footstep>) -> Vec<Footstep> {
        let mut feet = [start.feet[0][0], start.feet[1][0]];
        if let Some(u) = start.under_way {
            feet[u.footstep.side.index()] = u.footstep.place;
        }
        for f in &steps {
            feet[f.side.index()] = f.place;
        }
        let last_side = steps
            .last()
            .map(|f| f.side)
            .or(start.under_way.map(|u| u.footstep.side))
            .unwrap_or(Side::Right);
        let mover = last_side.other();
        let anchor = feet[last_side.index()];
        let side = match mover {
            Side::Left => 1.0,
            Side::Right => -1.0,
        };
        let off = rot(anchor[3], [0.0, side * self.cfg.stance_width]);
        let target = [anchor[0] + off[0], anchor[1] + off[1], anchor[2], anchor[3]];
        let now = feet[mover.index()];
        let apart = (now[0] - target[0]).hypot(now[1] - target[1]) + wrap(now[3] - target[3]).abs();
        if apart > 1e-3 {
            let number = steps
                .last()
                .map(|f| f.number)
                .or(start.under_way.map(|u| u.footstep.number))
                .unwrap_or(self.last_number)
                + 1;
            steps.push(Footstep {
                number,
                side: mover,
                place: target,
                swing_height: self.cfg.in_place_height,
                duration: 0.0,
                padding: false,
            });
        }
        steps
    }

    /// A stop command: the feet together, then stand; plans are ignored until [`resume`].
    ///
    /// [`resume`]: Walker::resume
    pub fn stop(&mut self, now: f64) {
        if !self.stopped {
            self.stopped = true;
            self.counters.stops += 1;
            self.note = "stopped by command".into();
            self.stand_soon(now);
        }
    }

    /// The rest of the pattern cannot be played (its later rows, made as the walk comes near
    /// them, are beyond the legs): counted as a refusal, the feet come together at `now` and
    /// the robot stands.
    pub fn halt(&mut self, now: f64, why: &str) {
        self.counters.refused += 1;
        self.note = format!("plan refused: {why}");
        self.stand_soon(now);
    }

    /// Takes plans again after a stop.
    pub fn resume(&mut self) {
        self.stopped = false;
        self.note = "resumed: waiting for a plan".into();
    }

    /// No newer plan will come: the robot is at the goal once the steps already fixed land
    /// (its caller judged so, and asks no more). A taken plan that ends the walk within the
    /// steps checked with it (it reaches the goal, its last real step no further than the one
    /// a lost planner's walk stops with) is walked to its end, its padding in place, and the
    /// robot stands, not kept stepping in place for `plan_timeout`; any other plan is
    /// stopped as a lost planner's is. Returns whether the plan is walked to its end.
    pub fn finish_plan(&mut self) -> bool {
        if self.ends_walk {
            self.following = false;
        }
        self.ends_walk
    }

    /// Keeps the walk going at `now`: when the taken steps are about to run out before the
    /// goal, adds in-place steps (for at most `plan_timeout` after the last valid plan), then
    /// brings the feet together. Returns true when the pattern changed.
    pub fn tick(&mut self, now: f64, joints: &JointsCheck) -> bool {
        self.tick_ahead(now, STALE_DECISION, joints)
    }

    /// [`Walker::tick`] by a caller whose next tick may come as much as `within` s later (a
    /// gait that decides at the end of what it streamed, which moves a chunk at a time): the
    /// step that will have started by then is decided now, while it can still change.
    pub fn tick_ahead(&mut self, now: f64, within: f64, joints: &JointsCheck) -> bool {
        if self.stopped {
            return false;
        }
        let (k, start) = self.switch(now);
        let ahead: Vec<Footstep> = self.steps_from(k);
        // The next step of the plan is further from its echo than a plan is walked (none
        // came for the steps since, even one that reaches the goal): in place instead.
        // Decided when the step is about to be fixed (a plan may come until then).
        let t = self.pattern.samples[k].t;
        let stale = self.following
            && self
                .pattern
                .timeline
                .steps
                .iter()
                .find(|s| s.start > t)
                .is_some_and(|s| {
                    s.start <= t + within.max(STALE_DECISION)
                        && !s.footstep.padding
                        && s.footstep.number > self.last_echo + i64::from(self.cfg.steps_per_plan)
                });
        if stale {
            self.at_goal = false;
            // The plan's next step (it was checked with the plan), then the feet side by side
            // and in place: the stop the walk's momentum takes gently (a stop sharper than the
            // pattern needs leaves the measured motion, which lags it, less margin). Shortened
            // when the full step is beyond the legs, at once when no step is.
            let mut done = Err(GaitError::Plan("no step to stop with".into()));
            if let Some(n) = ahead.first() {
                let beside = self.together(&start, Vec::new());
                for share in [1.0, 0.75, 0.5, 0.25] {
                    let mut step = *n;
                    if let Some(b) = beside.first().filter(|b| b.side == n.side) {
                        for i in 0..3 {
                            step.place[i] = b.place[i] + share * (n.place[i] - b.place[i]);
                        }
                    }
                    done = self.in_place(now, &start, vec![step], joints);
                    if done.is_ok() {
                        break;
                    }
                }
            }
            if done.is_err() {
                done = self.in_place(now, &start, Vec::new(), joints);
            }
            return match done {
                Ok(()) => {
                    // The walker's own steps from here: not a plan's.
                    self.following = false;
                    true
                }
                Err(e) => {
                    // Neither: feet together and stand, as on a plan timeout (the next step
                    // is decided again if the pattern cannot change).
                    let note = format!("no plan for the next step, none in place ({e}): standing");
                    if self.stand_now(now, &start, Vec::new(), note) {
                        self.at_goal = true;
                        self.following = false;
                    }
                    true
                }
            };
        }
        if self.at_goal || ahead.len() >= 2 {
            // At the goal, or enough steps ahead: nothing to do until the last one starts.
            return false;
        }
        if now - self.last_valid > self.cfg.plan_timeout {
            self.at_goal = true;
            self.following = false;
            let note = format!(
                "no valid plan for {} s: feet together, standing",
                self.cfg.plan_timeout
            );
            self.stand_now(now, &start, ahead, note);
            return true;
        }
        self.in_place(now, &start, ahead, joints).is_ok()
    }

    /// Stands after `steps` with the feet side by side, unchecked (a stand must happen),
    /// counted as a stop with `note`; whether the pattern changed.
    fn stand_now(&mut self, now: f64, start: &Start, steps: Vec<Footstep>, note: String) -> bool {
        self.counters.stops += 1;
        self.note = note;
        let steps = self.together(start, steps);
        self.replace(now, steps, &|_, _| Ok(())).is_ok()
    }

    /// Makes the pattern `steps`, then the feet side by side (in place from a long stride is
    /// beyond the legs: the ankles' limits), then steps in place with the foot that would
    /// swing next, checked by `joints`.
    fn in_place(
        &mut self,
        now: f64,
        start: &Start,
        steps: Vec<Footstep>,
        joints: &JointsCheck,
    ) -> Result<(), GaitError> {
        let mut steps = self.together(start, steps);
        let mut feet = [start.feet[0][0], start.feet[1][0]];
        if let Some(u) = start.under_way {
            feet[u.footstep.side.index()] = u.footstep.place;
        }
        for f in &steps {
            feet[f.side.index()] = f.place;
        }
        let mut side = steps
            .last()
            .map(|f| f.side)
            .or(start.under_way.map(|u| u.footstep.side))
            .unwrap_or(Side::Left)
            .other();
        let mut number = steps
            .last()
            .map(|f| f.number)
            .or(start.under_way.map(|u| u.footstep.number))
            .unwrap_or(self.counter(start.t).number);
        let mut added = 0;
        while steps.len() < 3 {
            number += 1;
            steps.push(Footstep {
                number,
                side,
                place: feet[side.index()],
                swing_height: self.cfg.in_place_height,
                duration: 0.0,
                padding: true,
            });
            added += 1;
            side = side.other();
        }
        self.replace(now, steps, joints)?;
        self.counters.in_place += added;
        self.note = "no plan for the next step: stepping in place".into();
        Ok(())
    }
}
