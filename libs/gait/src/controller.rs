//! Archie's walking controller: the walker (plans in step with the planner, the stand, the
//! stop) and the legs (the pattern's joints, checked) joined, so that an app gives it plans and
//! time and plays the joints it gives back. Knows no bus: the app turns messages into
//! [`Plan`]s and publishes the rows.

use std::cell::RefCell;

use crate::archie::{ArchieGait, Joints};
use crate::pattern::Pattern;
use crate::swing::Place;
use crate::timeline::Footstep;
use crate::walker::{Plan, Verdict, Walker, WalkerConfig};
use crate::GaitError;

/// The period of the joints' rows, s.
pub const ROW_PERIOD: f64 = 0.01;

/// What became of the plans offered in one turn, and of the walker's own tick.
#[derive(Debug, Default)]
pub struct Intake {
    /// A new pattern's joints to play (a plan taken, or the walker's own change).
    pub adopt: Option<Joints>,
    /// Why plans were refused (a plan refused changes nothing: the walk goes on).
    pub refusals: Vec<String>,
    /// Plans taken.
    pub taken: u64,
    /// The step the last plan taken was asked for, and its index among those offered.
    pub taken_echo: Option<(i64, usize)>,
    /// Plans dropped: late for their step, for a step another offered plan answers later,
    /// or offered while stopped.
    pub dropped: u64,
    /// A plan came for a step already under way (ask again at once for the step that will be).
    pub late: bool,
    /// The walker changed its pattern by itself (a stand, steps in place).
    pub changed: bool,
    /// The walker's own stand is beyond the legs (unchecked, not played: the rows made go on).
    pub stand_beyond: Option<String>,
}

/// The walker and the legs.
pub struct Controller {
    /// The legs: joints from patterns, checked.
    pub legs: ArchieGait,
    /// Plans to patterns, in step with the planner.
    pub walker: Walker,
    /// The joints of the walker's pattern, made as far as it can play (the rest, should it be
    /// needed, as the stream comes near: [`Controller::extend`]).
    pub joints: Joints,
    /// How far ahead of a decision the walker switches to a new pattern, s.
    pub switch_ahead: f64,
    /// How far the end of what was streamed may move from one turn to the next (the
    /// stream's chunk), s: the walker decides the steps that will be fixed by then.
    pub decide_within: f64,
}

impl Controller {
    /// When a change decided at `t` is to take over, as the walker's `now` (it switches
    /// `switch_ahead` later): at the end of what was sent to the trajectory bridges while a
    /// stream runs (`stream_end`), so that the new pattern's rows are appended to the rows
    /// queued there, with no clock between them; standing, on a row of the current pattern.
    pub fn switch_time(&self, t: f64, stream_end: Option<f64>) -> f64 {
        switch_time(&self.walker, t, self.switch_ahead, stream_end)
    }

    /// The plans that came since the last turn (in their order) at walker time `t`, then the
    /// walker's own tick. Of the plans for the step a plan is taken for, only the newest is
    /// made into a pattern (the one it would replace the others with): a flood of copies
    /// costs nothing beyond their decoding.
    pub fn take(&mut self, plans: &[Plan], t: f64, stream_end: Option<f64>) -> Intake {
        let mut out = Intake::default();
        let switch = self.switch_time(t, stream_end);
        let wanted = self.walker.wanted_echo(switch);
        let newest = plans.iter().rposition(|p| Some(p.echo) == wanted);
        let legs = &self.legs;
        let cache: RefCell<Option<Joints>> = RefCell::new(None);
        let check = |p: &Pattern, until: f64| -> Result<(), GaitError> {
            *cache.borrow_mut() = Some(legs.joints_until(p, until)?);
            Ok(())
        };
        let reach = |_: &Footstep, _: &[f64; 4]| -> Result<(), String> { Ok(()) };
        for (i, plan) in plans.iter().enumerate() {
            if Some(plan.echo) == wanted && Some(i) != newest {
                out.dropped += 1;
                continue;
            }
            // Each decision on the walker's pattern as it stands then (a plan taken moves it).
            let at = self.switch_time(t, stream_end);
            match self.walker.on_plan(plan, at, &reach, &check) {
                Verdict::Taken(_) => {
                    out.adopt = cache.borrow_mut().take();
                    out.taken += 1;
                    out.taken_echo = Some((plan.echo, i));
                }
                Verdict::Refused(why) => out.refusals.push(why),
                Verdict::Late { echo, now } => {
                    out.dropped += 1;
                    out.late |= echo < now;
                }
                Verdict::Stopped => out.dropped += 1,
            }
        }
        let at = self.switch_time(t, stream_end);
        out.changed = self.walker.tick_ahead(at, self.decide_within, &check);
        if out.changed {
            if let Some(j) = cache.borrow_mut().take() {
                out.adopt = Some(j);
            } else {
                match legs.joints_until(self.walker.pattern(), f64::INFINITY) {
                    Ok(j) => out.adopt = Some(j),
                    // The walker's own stand, unchecked: the rows already made go on.
                    Err(e) => out.stand_beyond = Some(e.to_string()),
                }
            }
        }
        out
    }

    /// Makes the pattern's joints up to walker time `until`; an error when its later rows are
    /// beyond the legs.
    pub fn extend(&mut self, until: f64) -> Result<(), GaitError> {
        self.legs
            .extend(self.walker.pattern(), &mut self.joints, until)
    }

    /// A new walker standing with its feet at `left` and `right` from `t` (its step counter
    /// going on from where it stood: it never goes back), and its joints; an error, and
    /// nothing changed, when the stand is beyond the legs.
    pub fn stand(
        &mut self,
        cfg: WalkerConfig,
        t: f64,
        [left, right]: [Place; 2],
    ) -> Result<(), String> {
        let number = self.walker.counter(t).number;
        let gen = self.walker.generator().clone();
        let walker = Walker::new(gen, cfg, t, left, right, number).map_err(|e| e.to_string())?;
        let joints = self
            .legs
            .joints_until(walker.pattern(), f64::INFINITY)
            .map_err(|e| e.to_string())?;
        (self.walker, self.joints) = (walker, joints);
        Ok(())
    }

    /// The walk ends in a stand at `t` (its later rows are beyond the legs: `why`): the stand's
    /// joints, or an error when the stand itself is beyond them (the rows made go on).
    pub fn halt(
        &mut self,
        t: f64,
        stream_end: Option<f64>,
        why: &str,
    ) -> Result<Joints, GaitError> {
        let at = self.switch_time(t, stream_end);
        self.walker.halt(at, why);
        self.legs.joints_until(self.walker.pattern(), f64::INFINITY)
    }
}

/// [`Controller::switch_time`] for a walker switching `switch_ahead` after a decision.
pub fn switch_time(walker: &Walker, t: f64, switch_ahead: f64, stream_end: Option<f64>) -> f64 {
    if let Some(end) = stream_end {
        return end - switch_ahead + 1e-7;
    }
    let start = walker.pattern().timeline.start;
    let rows = ((t + switch_ahead - start) / ROW_PERIOD - 1e-6)
        .ceil()
        .max(0.0);
    (start + rows * ROW_PERIOD - switch_ahead + 1e-7).max(t)
}
