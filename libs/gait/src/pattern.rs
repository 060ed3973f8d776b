//! COM and ZMP patterns from footsteps, one interface for both generators:
//!
//! - [`Generator::Preview`], the default: ZMP preview control ([`crate::preview`]) tracking the
//!   timeline's ZMP reference, double supports included;
//! - [`Generator::FootPlacement`]: Archie's walk primitives with the modified foot placement
//!   ([`crate::lipm`]): single supports of T_sup each, the foot placed where eq 24 puts it
//!   (within `max_displacement` of the plan's footstep, else the plan is refused); after the
//!   last step the preview controller takes the COM over (position, velocity and
//!   acceleration continuous) and brings it to rest between the feet.
//!
//! Every sample carries the cart-table ZMP p = x − (z_c / g) ẍ and its margin in the support
//! polygon; with a [`Body`] ([`Generator::with_body`]), preview control takes the whole body's
//! departure from the cart-table model off its ZMP reference (Kajita's two-stage preview
//! control) and the samples carry the whole body's ZMP. [`plan`] stretches the time of a step
//! whose margin falls below the bar, within [T_min, T_max], until it passes, else refuses the
//! plan. [`Pattern::state_at`] gives the
//! state a new pattern starts from, so that a plan replaced mid-walk continues the COM and
//! the swing foot without a jump.

use std::sync::Arc;

use serde::Deserialize;

use crate::lipm::{LipmConfig, Pendulum, State};
use crate::preview::{Cart, Preview, PreviewConfig};
use crate::support::{margin, polygon, Pose2, Sole, P2};
use crate::swing::{Place, SwingConfig, SwingPath};
use crate::timeline::{xy, Cursor, Footstep, Phase, Step, Timeline, TimingConfig};
use crate::GaitError;

/// Which COM generator.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    /// ZMP preview control (the default).
    Preview,
    /// Walk primitives with the modified foot placement (Archie's chapter 2.1).
    FootPlacement,
}

/// The foot placement generator's parameters (the pendulum's height and gravity are the
/// pattern's).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlacementConfig {
    /// The support period T_sup, s.
    pub t_sup: f64,
    /// Weight of the terminal position error (eq 22).
    pub a: f64,
    /// Weight of the terminal velocity error (eq 22).
    pub b: f64,
    /// How far the modified placement may move a planned footstep, m.
    pub max_displacement: f64,
    /// How long before the second step's lift the pendulum takes the walk over from the
    /// preview controller, s (that step lifts then). At the lift itself the COM has run so
    /// far over the first footstep that the rear knee is nearly straight when its swing
    /// begins (Archie's 20-step walk bent it back at 60.3 rad/s², limit 60).
    #[serde(default = "default_handover_lead")]
    pub handover_lead: f64,
    /// Eq 7's misprint, as printed.
    #[serde(default)]
    pub faithful_eq_7: bool,
}

impl Default for PlacementConfig {
    /// The thesis's T_sup = 1 s; a = 10, b = 1 as in Kajita's book (the thesis gives none).
    fn default() -> PlacementConfig {
        PlacementConfig {
            t_sup: 1.0,
            a: 10.0,
            b: 1.0,
            max_displacement: 0.05,
            handover_lead: default_handover_lead(),
            faithful_eq_7: false,
        }
    }
}

fn default_handover_lead() -> f64 {
    0.04
}

/// A pattern's parameters.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PatternConfig {
    /// The COM generator.
    pub generator: Kind,
    /// The COM's height, m.
    pub z_c: f64,
    /// Gravity, m/s².
    pub g: f64,
    /// Preview control (and the sampling period of every pattern).
    pub preview: PreviewConfig,
    /// The foot placement generator.
    pub placement: PlacementConfig,
    /// Step timing.
    pub timing: TimingConfig,
    /// The swing's shape.
    pub swing: SwingConfig,
    /// The sole the ZMP must stay on.
    pub sole: Sole,
    /// The smallest margin of the ZMP in the support polygon, m.
    pub min_margin: f64,
}

/// The COM's state on both axes, with the preview controller's error sums.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ComState {
    /// x.
    pub x: Cart,
    /// y.
    pub y: Cart,
}

impl ComState {
    /// At rest at `p`.
    pub fn at_rest(p: P2) -> ComState {
        ComState {
            x: Cart {
                x: [p[0], 0.0, 0.0],
                err_sum: 0.0,
            },
            y: Cart {
                x: [p[1], 0.0, 0.0],
                err_sum: 0.0,
            },
        }
    }

    /// Position, velocity, acceleration (x and y each).
    pub fn com(&self) -> [P2; 3] {
        [
            [self.x.x[0], self.y.x[0]],
            [self.x.x[1], self.y.x[1]],
            [self.x.x[2], self.y.x[2]],
        ]
    }
}

/// One sample of a pattern.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Time, s.
    pub t: f64,
    /// The COM's state.
    pub com: ComState,
    /// The ZMP reference.
    pub zmp_ref: P2,
    /// The cart-table ZMP of the COM's state.
    pub zmp: P2,
    /// The feet: place, velocity and acceleration, left and right.
    pub feet: [[Place; 3]; 2],
    /// The phase.
    pub phase: Phase,
    /// The ZMP's margin in the support polygon, m.
    pub margin: f64,
}

/// The support polygon of the phase last sampled, and its edges' lines.
#[derive(Debug, Default)]
struct Support {
    key: Option<(u8, usize)>,
    polygon: Vec<P2>,
    edges: Vec<[f64; 3]>,
}

/// The lines of a convex polygon's edges (counter-clockwise) as (n_x, n_y, c): inside is
/// n · p ≥ c, n of unit length. None of them for fewer than three corners.
fn edges(poly: &[P2]) -> Vec<[f64; 3]> {
    let n = poly.len();
    if n < 3 {
        return Vec::new();
    }
    (0..n)
        .map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % n]);
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let len = dx.hypot(dy);
            let (nx, ny) = (-dy / len, dx / len);
            [nx, ny, nx * a[0] + ny * a[1]]
        })
        .collect()
}

/// A point's margin inside a convex polygon from its edges' lines: inside, the nearest edge
/// is as near as its line. None outside (or with no edges), where the corners count too.
fn inside_margin(edges: &[[f64; 3]], p: P2) -> Option<f64> {
    let mut m = f64::INFINITY;
    for e in edges {
        let d = e[0] * p[0] + e[1] * p[1] - e[2];
        if d.is_nan() || d < 0.0 {
            return None;
        }
        m = m.min(d);
    }
    (!edges.is_empty()).then_some(m)
}

/// A COM, ZMP and swing pattern, sampled every period.
#[derive(Debug, Clone, PartialEq)]
pub struct Pattern {
    /// Sampling period, s.
    pub dt: f64,
    /// The steps in time.
    pub timeline: Timeline,
    /// The samples, the first at the timeline's start.
    pub samples: Vec<Sample>,
    /// With the foot placement generator: the planned footsteps and where each was placed.
    pub placed: Vec<(Footstep, P2)>,
}

/// Where a walk starts from: the COM's state, the ZMP reference, the feet (a foot in the
/// air with its velocity and acceleration) and the step under way.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Start {
    /// When, s.
    pub t: f64,
    /// The COM.
    pub com: ComState,
    /// The ZMP reference.
    pub zmp_ref: P2,
    /// The feet, left and right: place, velocity, acceleration.
    pub feet: [[Place; 3]; 2],
    /// The step under way, in its double support or its swing.
    pub under_way: Option<UnderWay>,
    /// The COM's jerk (x, y), when it is in motion on a pattern: a new pattern goes on with it
    /// (bumpless); None: the controller's own first jerk.
    pub jerk: Option<[f64; 2]>,
}

/// A step under way at a pattern's start: it keeps its times (a new plan may retarget it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnderWay {
    /// The step.
    pub footstep: Footstep,
    /// When its double support began, s.
    pub start: f64,
    /// When its foot lifts (lifted already when before the start's time), s.
    pub lift: f64,
    /// When it lands, s.
    pub land: f64,
    /// Where its double support moves the ZMP reference from.
    pub zmp_from: P2,
    /// Where its foot lifted from.
    pub from: Place,
}

impl Start {
    /// Standing still: the COM at rest over the midpoint of the feet.
    pub fn standing(t: f64, left: Place, right: Place) -> Start {
        let m = [(left[0] + right[0]) / 2.0, (left[1] + right[1]) / 2.0];
        Start {
            t,
            com: ComState::at_rest(m),
            zmp_ref: m,
            feet: [[left, [0.0; 4], [0.0; 4]], [right, [0.0; 4], [0.0; 4]]],
            under_way: None,
            jerk: Some([0.0, 0.0]),
        }
    }
}

impl Pattern {
    /// The sample at or just before `t`.
    pub fn index_at(&self, t: f64) -> usize {
        let k = ((t - self.timeline.start) / self.dt).floor().max(0.0) as usize;
        k.min(self.samples.len() - 1)
    }

    /// The state to start a new pattern from at sample `k`: the COM as it is there, the feet,
    /// and the step under way (which a new plan may retarget, its times kept).
    pub fn state_at(&self, k: usize) -> Start {
        let s = &self.samples[k];
        let tl = &self.timeline;
        let step = match s.phase {
            Phase::Single { step, .. } | Phase::Double { step: Some(step) } => Some(step),
            Phase::Double { step: None } => None,
        };
        let under_way = step.map(|i| {
            let st = &tl.steps[i];
            UnderWay {
                footstep: st.footstep,
                start: st.start,
                lift: st.lift,
                land: st.land,
                zmp_from: if i == 0 {
                    tl.zmp_start
                } else {
                    tl.zmp_point(&tl.steps[i - 1].support)
                },
                from: st.from,
            }
        });
        // The jerk the pattern applies from this sample on (at its end, the last one).
        let (a, b) = match (k.checked_sub(1), self.samples.get(k + 1)) {
            (_, Some(n)) => (s, n),
            (Some(p), None) => (&self.samples[p], s),
            (None, None) => (s, s),
        };
        let jerk = Some([
            (b.com.x.x[2] - a.com.x.x[2]) / self.dt,
            (b.com.y.x[2] - a.com.y.x[2]) / self.dt,
        ]);
        Start {
            t: s.t,
            com: s.com,
            zmp_ref: s.zmp_ref,
            feet: s.feet,
            under_way,
            jerk,
        }
    }

    /// The smallest ZMP margin, and when.
    pub fn min_margin(&self) -> (f64, f64) {
        self.samples
            .iter()
            .map(|s| (s.margin, s.t))
            .fold((f64::INFINITY, 0.0), |a, b| if b.0 < a.0 { b } else { a })
    }
}

/// The whole body under a pattern: where its ZMP falls from the cart-table ZMP of the
/// pattern's COM (the legs' own accelerations, masses below and above the COM's height),
/// which a generator with a body takes off its ZMP reference ([`Generator::with_body`]).
pub trait Body: std::fmt::Debug + Send + Sync {
    /// The whole body's ZMP less the pattern's cart-table ZMP at each of its samples, with
    /// gravity `g`; zero past the last sample the body can take.
    fn zmp_offset(&self, pat: &Pattern, g: f64) -> Vec<P2>;
}

/// The generator, built once for a COM height.
#[derive(Debug, Clone)]
pub struct Generator {
    cfg: PatternConfig,
    preview: Preview,
    pendulum: Pendulum,
    body: Option<(Arc<dyn Body>, usize)>,
}

impl Generator {
    /// Builds the generator (the preview gains are computed here).
    pub fn new(cfg: PatternConfig) -> Result<Generator, GaitError> {
        cfg.timing.check()?;
        if !(cfg.min_margin.is_finite() && cfg.sole.length > 0.0 && cfg.sole.width > 0.0) {
            return Err(GaitError::Parameter(format!(
                "pattern: a sole of positive size and a finite margin: {:?}, {}",
                cfg.sole, cfg.min_margin
            )));
        }
        // The next three steps in view, however long each takes.
        if cfg.preview.horizon < 3.0 * cfg.timing.t_max - 1e-9 {
            return Err(GaitError::Parameter(format!(
                "preview control sees at least the next three steps: a horizon of {} s is \
                 shorter than three of the longest ({} s)",
                cfg.preview.horizon,
                3.0 * cfg.timing.t_max
            )));
        }
        let preview = Preview::new(cfg.preview, cfg.z_c, cfg.g)?;
        let pendulum = Pendulum::new(LipmConfig {
            z_c: cfg.z_c,
            t_sup: cfg.placement.t_sup,
            g: cfg.g,
            a: cfg.placement.a,
            b: cfg.placement.b,
            faithful: crate::lipm::Faithful {
                eq_7: cfg.placement.faithful_eq_7,
            },
        })?;
        Ok(Generator {
            cfg,
            preview,
            pendulum,
            body: None,
        })
    }

    /// The generator with the whole body under its preview-control patterns (Kajita's
    /// two-stage preview control, the second stage made again `passes` times): the body's
    /// offset from the cart-table ZMP ([`Body::zmp_offset`]) of the last pattern made is taken
    /// off the ZMP reference and the pattern made again, so that the whole body's ZMP, not the
    /// cart's, follows the reference; the samples' ZMPs and margins are the whole body's. The
    /// foot placement generator's pendulum is left as the thesis has it.
    pub fn with_body(mut self, body: Arc<dyn Body>, passes: usize) -> Generator {
        self.body = Some((body, passes));
        self
    }

    /// The parameters.
    pub fn config(&self) -> &PatternConfig {
        &self.cfg
    }

    /// Standing still with the feet at `left` and `right`: the COM at rest over the midpoint
    /// of their ZMP points (see [`TimingConfig::zmp_ahead`]).
    pub fn standing(&self, t: f64, left: Place, right: Place) -> Start {
        let a = self.cfg.timing.zmp_ahead;
        let point = |p: &Place| {
            let (s, c) = p[3].sin_cos();
            [p[0] + c * a, p[1] + s * a]
        };
        let (l, r) = (point(&left), point(&right));
        let m = [(l[0] + r[0]) / 2.0, (l[1] + r[1]) / 2.0];
        Start {
            com: ComState::at_rest(m),
            zmp_ref: m,
            ..Start::standing(t, left, right)
        }
    }

    /// The preview controller.
    pub fn preview(&self) -> &Preview {
        &self.preview
    }

    /// The pendulum of the foot placement generator.
    pub fn pendulum(&self) -> &Pendulum {
        &self.pendulum
    }

    /// True when `steps` begins with the step under way at `start` (the plan retargets it).
    pub fn continues(start: &Start, steps: &[Footstep]) -> bool {
        start.under_way.is_some_and(|u| {
            steps
                .first()
                .is_some_and(|f| f.number == u.footstep.number && f.side == u.footstep.side)
        })
    }

    /// The timeline of `steps` from `start` with step durations `durations` (per step of
    /// `steps`; 0: the rule's): a step under way keeps its times (retargeted to the plan's
    /// step of its number, if the plan has one; a swing continues from where the foot is).
    pub fn timeline(
        &self,
        start: &Start,
        steps: &[Footstep],
        durations: &[f64],
    ) -> Result<Timeline, GaitError> {
        let feet = [start.feet[0][0], start.feet[1][0]];
        let Some(uw) = start.under_way else {
            // Standing (a settled pattern's COM creeps at most millimetres a second): a walk
            // starts with the lead.
            let com = start.com.com();
            let at_rest =
                com[1].iter().all(|v| v.abs() < 2e-3) && com[2].iter().all(|v| v.abs() < 2e-2);
            return Timeline::new(
                start.t,
                start.zmp_ref,
                feet,
                steps,
                durations,
                &self.cfg.timing,
                &self.cfg.swing,
                at_rest,
            );
        };
        let (target, rest, rest_durations) = if Generator::continues(start, steps) {
            (steps[0], &steps[1..], durations.get(1..).unwrap_or(&[]))
        } else {
            (uw.footstep, steps, durations)
        };
        let k = target.side.index();
        let over = start.feet[k][0][2].max(target.place[2]) + target.swing_height.max(0.0);
        // In the air with its target and height unchanged (a replanning planner's plans keep
        // the step under way): the very path it is on, from its lift-off.
        let same = start.t > uw.lift
            && target.place == uw.footstep.place
            && target.swing_height == uw.footstep.swing_height;
        let path = if same {
            let over = uw.from[2].max(target.place[2]) + target.swing_height.max(0.0);
            SwingPath::new(
                uw.from,
                target.place,
                over,
                uw.land - uw.lift,
                &self.cfg.swing,
            )?
        } else if start.t > uw.lift {
            // In the air, retargeted: on from where the foot is, landing when it was to,
            // rising above where it is by no more of the clearance than the swing has time
            // left for (a foot about to land is not lifted again).
            let left = (uw.land - start.t).max(self.cfg.preview.period);
            let share = (left / (uw.land - uw.lift)).clamp(0.0, 1.0);
            let mut swing = self.cfg.swing;
            swing.clearance *= share;
            let over = over - target.swing_height.max(0.0) * (1.0 - share);
            SwingPath::from_state(start.feet[k], target.place, over, left, &swing)?
        } else {
            SwingPath::new(
                start.feet[k][0],
                target.place,
                over,
                uw.land - uw.lift,
                &self.cfg.swing,
            )?
        };
        let support = feet[target.side.other().index()];
        let first = Step {
            footstep: target,
            // Where its path starts: the lift-off place of the path kept, else where the
            // foot is.
            from: if same { uw.from } else { start.feet[k][0] },
            support,
            start: uw.start,
            lift: uw.lift.max(uw.start),
            land: uw.land.max(start.t + self.cfg.preview.period),
            swing: path,
        };
        // A swing retargeted in the air: its path starts now.
        let first = if start.t > uw.lift && !same {
            Step {
                lift: start.t,
                ..first
            }
        } else {
            first
        };
        let mut after = feet;
        after[k] = target.place;
        let mut t = Timeline::new(
            first.land,
            [0.0, 0.0],
            after,
            rest,
            rest_durations,
            &self.cfg.timing,
            &self.cfg.swing,
            false,
        )?;
        let _ = t.zmp_start;
        t.start = start.t;
        t.zmp_start = uw.zmp_from;
        t.feet_start = feet;
        t.steps.insert(0, first);
        Ok(t)
    }

    /// The pattern of `steps` from `start`, step times as given (0: the rule's), unchecked.
    pub fn generate(
        &self,
        start: &Start,
        steps: &[Footstep],
        durations: &[f64],
    ) -> Result<Pattern, GaitError> {
        self.generate_with(start, steps, durations, true, None)
    }

    /// [`Generator::generate`], with the whole body under the pattern if `whole` (and the
    /// generator has one): all of it, or with `played`, up to step `played`'s touch-down and
    /// as far beyond as the preview looks back from there ([`Generator::preview_reach`]); the
    /// rest is the cart-table model's, its ZMP and margins the cart's.
    fn generate_with(
        &self,
        start: &Start,
        steps: &[Footstep],
        durations: &[f64],
        whole: bool,
        played: Option<i64>,
    ) -> Result<Pattern, GaitError> {
        match self.cfg.generator {
            Kind::Preview => {
                let tl = self.timeline(start, steps, durations)?;
                let Some((body, passes)) = self.body.as_ref().filter(|_| whole) else {
                    return Ok(self.preview_pattern(tl, start.com, start.jerk, Vec::new()));
                };
                let until = played
                    .and_then(|n| tl.steps.iter().find(|s| s.footstep.number == n))
                    .map_or(f64::INFINITY, |s| s.land + self.preview_reach());
                let g = self.cfg.g;
                let (com, jerk) = (start.com, start.jerk);
                let pass = |until: f64, shift: &[P2]| {
                    self.preview_pattern_until(tl.clone(), com, jerk, Vec::new(), until, shift)
                };
                let mut pat = pass(until, &[]);
                let (mut offset, mut shift) = (body.zmp_offset(&pat, g), Vec::new());
                for _ in 0..*passes {
                    shift = offset;
                    pat = pass(until, &shift);
                    offset = body.zmp_offset(&pat, g);
                }
                if until < tl.end {
                    // The same rows to `until` (the same shift), then the cart's to the end.
                    pat = pass(f64::INFINITY, &shift);
                }
                self.whole_body_zmp(&mut pat, &offset);
                Ok(pat)
            }
            Kind::FootPlacement => self.placement_pattern(start, steps),
        }
    }

    #[inline(always)]
    fn sample(
        &self,
        tl: &Timeline,
        t: f64,
        com: ComState,
        zmp_ref: Option<P2>,
        support: &mut Support,
        cursor: &mut Cursor,
    ) -> Sample {
        let zmp = [self.preview.zmp(&com.x.x), self.preview.zmp(&com.y.x)];
        let (feet, phase) = cursor.at(t);
        let margin = self.margin_of(tl, support, t, phase, &feet, zmp);
        Sample {
            t,
            com,
            zmp_ref: zmp_ref.unwrap_or_else(|| tl.zmp_ref(t)),
            zmp,
            feet,
            phase,
            margin,
        }
    }

    /// A sample's ZMP's margin in its support polygon.
    #[inline(always)]
    fn margin(&self, tl: &Timeline, support: &mut Support, s: &Sample) -> f64 {
        self.margin_of(tl, support, s.t, s.phase, &s.feet, s.zmp)
    }

    /// [`Generator::margin`] of a ZMP at `t` in a phase with the feet there.
    #[inline(always)]
    fn margin_of(
        &self,
        tl: &Timeline,
        support: &mut Support,
        t: f64,
        phase: Phase,
        feet: &[[Place; 3]; 2],
        zmp: P2,
    ) -> f64 {
        // The support polygon changes only with the phase: made once for each.
        let key = match phase {
            Phase::Single { step, .. } => (1, step),
            Phase::Double { step: Some(step) } => (2, step),
            Phase::Double { step: None } => (3, usize::from(t >= tl.start)),
        };
        if support.key != Some(key) {
            let on: &[usize] = match phase {
                Phase::Single { swing, .. } => &[swing.other().index()][..],
                Phase::Double { .. } => &[0, 1],
            };
            let ground: Vec<Pose2> = on
                .iter()
                .map(|&k| Pose2 {
                    p: xy(&feet[k][0]),
                    yaw: feet[k][0][3],
                })
                .collect();
            support.polygon = polygon(&self.cfg.sole, &ground);
            support.edges = edges(&support.polygon);
            support.key = Some(key);
        }
        inside_margin(&support.edges, zmp).unwrap_or_else(|| margin(&support.polygon, zmp))
    }

    /// The samples' ZMPs moved by the body's offsets to the whole body's, and their margins.
    fn whole_body_zmp(&self, pat: &mut Pattern, offset: &[P2]) {
        let mut support = Support::default();
        for (s, d) in pat.samples.iter_mut().zip(offset) {
            s.zmp = [s.zmp[0] + d[0], s.zmp[1] + d[1]];
            s.margin = self.margin(&pat.timeline, &mut support, s);
        }
    }

    /// Preview control over the whole timeline from `com`; with `jerk`, the controller
    /// takes the COM over bumplessly (its first jerk that one, see [`Preview::bumpless`]).
    fn preview_pattern(
        &self,
        tl: Timeline,
        com: ComState,
        jerk: Option<[f64; 2]>,
        placed: Vec<(Footstep, P2)>,
    ) -> Pattern {
        self.preview_pattern_until(tl, com, jerk, placed, f64::INFINITY, &[])
    }

    /// [`Generator::preview_pattern`] sampled only up to the first sample at or after `until`
    /// (the rest of the timeline still previewed), `shift` taken off the ZMP reference the
    /// controller tracks (sample by sample from the first; the samples keep the reference).
    fn preview_pattern_until(
        &self,
        tl: Timeline,
        com: ComState,
        jerk: Option<[f64; 2]>,
        placed: Vec<(Footstep, P2)>,
        until: f64,
        shift: &[P2],
    ) -> Pattern {
        let dt = self.cfg.preview.period;
        let whole = ((tl.end - tl.start) / dt).ceil() as usize;
        let ticks = if until < tl.end {
            (((until - tl.start) / dt).ceil().max(0.0) as usize + 1).min(whole)
        } else {
            whole
        };
        let n = self.preview.horizon_ticks();
        let refs = tl.zmp_refs(tl.start, dt, ticks + n + 1);
        let shifted = |d: usize| {
            refs.iter()
                .enumerate()
                .map(|(k, p)| p[d] - shift.get(k).map_or(0.0, |s| s[d]))
                .collect::<Vec<f64>>()
        };
        let (rx, ry) = (shifted(0), shifted(1));
        let mut state = com;
        if let Some(u) = jerk {
            self.preview.bumpless(&mut state.x, rx[0], &rx[1..=n], u[0]);
            self.preview.bumpless(&mut state.y, ry[0], &ry[1..=n], u[1]);
        }
        // A shifted reference is curved: its sums by recursion, not by straight runs.
        let (px, py) = if shift.is_empty() {
            (
                self.preview.preview_terms(&rx, ticks),
                self.preview.preview_terms(&ry, ticks),
            )
        } else {
            (
                self.preview.preview_terms_recursive(&rx, ticks),
                self.preview.preview_terms_recursive(&ry, ticks),
            )
        };
        let (px, py) = (px.unwrap_or_default(), py.unwrap_or_default());
        let mut samples = Vec::with_capacity(ticks + 1);
        let mut support = Support::default();
        let mut cursor = tl.cursor();
        for k in 0..=ticks {
            let t = tl.start + k as f64 * dt;
            samples.push(self.sample(&tl, t, state, Some(refs[k]), &mut support, &mut cursor));
            if k < ticks {
                match (px.get(k), py.get(k)) {
                    (Some(&a), Some(&b)) => {
                        self.preview.tick_with(&mut state.x, rx[k], a);
                        self.preview.tick_with(&mut state.y, ry[k], b);
                    }
                    _ => {
                        self.preview
                            .tick(&mut state.x, rx[k], &rx[k + 1..k + 1 + n]);
                        self.preview
                            .tick(&mut state.y, ry[k], &ry[k + 1..k + 1 + n]);
                    }
                }
            }
        }
        Pattern {
            dt,
            timeline: tl,
            samples,
            placed,
        }
    }

    /// The foot placement generator. A walk from standing has no momentum for the walk
    /// primitives (the thesis gives no initial state; Kajita's, at rest over the first foot,
    /// places the first feet far from the plan), so the preview controller walks the first
    /// step; shortly before the second lifts (the handover lead), with the COM's state there,
    /// Kajita's algorithm takes over: the first support's ZMP placed within its sole by eq 24
    /// (a few millimetres, see [`crate::lipm::walk_footsteps`]), then the other footsteps,
    /// each a single support of T_sup; after the last the preview controller settles the COM
    /// between the feet. Position and velocity are continuous throughout; the acceleration
    /// jumps at each support exchange, as the pendulum's ZMP does.
    fn placement_pattern(&self, start: &Start, steps: &[Footstep]) -> Result<Pattern, GaitError> {
        if start.under_way.is_some() {
            return Err(GaitError::Plan(
                "the foot placement generator starts a plan between steps, not mid-step".into(),
            ));
        }
        let full_tl = self.timeline(start, steps, &[])?;
        if steps.len() < 2 {
            return Ok(self.preview_pattern(full_tl, start.com, start.jerk, Vec::new()));
        }
        // The preview controller walks the first step: its samples up to the second's lift.
        let until = full_tl.steps[1].lift + self.cfg.preview.period;
        let full =
            self.preview_pattern_until(full_tl, start.com, start.jerk, Vec::new(), until, &[]);
        let p = &self.pendulum;
        let t_sup = self.cfg.placement.t_sup;
        let dt = self.cfg.preview.period;
        let first = full.timeline.steps[0].clone();
        // The pendulum takes over the handover lead before the second step lifts (not before
        // the first has landed), and the second step lifts then: the first step's foot is
        // the support, the COM on its way over it.
        let lead = self.cfg.placement.handover_lead.max(0.0);
        let handover = (full.timeline.steps[1].lift - lead).max(first.land);
        let k1 = full.index_at(handover + dt / 2.0);
        let t1 = full.samples[k1].t;
        let at1 = full.samples[k1].com;
        let mut feet = full.timeline.feet_start;
        feet[first.footstep.side.index()] = first.footstep.place;
        // The pendulum's supports: the first step's foot, then the plan's footsteps.
        // The pendulum's feet are the soles' ZMP points.
        let p0 = first.footstep.place;
        let zp = |p: &Place| full.timeline.zmp_point(p);
        let mut nominal: Vec<(P2, f64)> = vec![(zp(&p0), p0[3])];
        nominal.extend(steps[1..].iter().map(|f| (zp(&f.place), f.place[3])));
        let initial = State {
            x: [at1.x.x[0], at1.y.x[0]],
            v: [at1.x.x[1], at1.y.x[1]],
        };
        let supports = crate::lipm::walk_footsteps(p, &nominal, initial);
        let mut placed_steps = Vec::with_capacity(steps.len() - 1);
        let mut placed = Vec::with_capacity(steps.len() - 1);
        for (f, s) in steps[1..].iter().zip(&supports[1..]) {
            // The sole whose ZMP point the pendulum's foot is.
            let z = zp(&f.place);
            let foot = [f.place[0] + s.foot[0] - z[0], f.place[1] + s.foot[1] - z[1]];
            let d = (foot[0] - f.place[0]).hypot(foot[1] - f.place[1]);
            if d.is_nan() || d > self.cfg.placement.max_displacement {
                return Err(GaitError::Plan(format!(
                    "step {}: the modified foot placement moves it {d:.3} m from the plan \
                     (at most {} m)",
                    f.number, self.cfg.placement.max_displacement
                )));
            }
            let mut g = *f;
            g.place[0] = foot[0];
            g.place[1] = foot[1];
            g.duration = t_sup;
            placed_steps.push(g);
            placed.push((*f, foot));
        }
        // The placed steps: single supports only (the swing takes the whole period).
        let timing = TimingConfig {
            double_support: 0.0,
            ..self.cfg.timing
        };
        let walk_tl = Timeline::new(
            t1,
            zp(&p0),
            feet,
            &placed_steps,
            &vec![t_sup; placed_steps.len()],
            &timing,
            &self.cfg.swing,
            false,
        )?;
        let mut tl = full.timeline.clone();
        tl.steps.truncate(1);
        tl.steps.extend(walk_tl.steps.iter().cloned());
        tl.feet_end = walk_tl.feet_end;
        let mut samples: Vec<Sample> = full.samples[..k1].to_vec();
        // Every placed step's support, and the last foot's, which brings the COM over it.
        let k_walk = (t_sup * (placed_steps.len() + 1) as f64 / dt).round() as usize;
        let mut support = Support::default();
        let mut cursor = tl.cursor();
        for k in 0..k_walk {
            let t = t1 + k as f64 * dt;
            // The pendulum's support is the timeline's, so that the ZMP and the support
            // polygon change at the same sample (their instants agree only to rounding):
            // support n while placed step n swings (the timeline's step n + 1), the last
            // once every step has landed.
            let n = match cursor.phase(t) {
                Phase::Single { step, .. } => step.saturating_sub(1),
                Phase::Double { .. } => placed_steps.len(),
            }
            .min(supports.len() - 1);
            let [pos, vel, acc] = supports[n].at(p, t - t1 - n as f64 * t_sup);
            let com = ComState {
                x: Cart {
                    x: [pos[0], vel[0], acc[0]],
                    err_sum: 0.0,
                },
                y: Cart {
                    x: [pos[1], vel[1], acc[1]],
                    err_sum: 0.0,
                },
            };
            samples.push(self.sample(&tl, t, com, None, &mut support, &mut cursor));
        }
        // The settle from the last support's end, by the preview controller.
        let last = &supports[placed_steps.len()];
        let [pos, vel, acc] = last.at(p, t_sup);
        let com = ComState {
            x: Cart {
                x: [pos[0], vel[0], acc[0]],
                err_sum: 0.0,
            },
            y: Cart {
                x: [pos[1], vel[1], acc[1]],
                err_sum: 0.0,
            },
        };
        let settle_start = t1 + k_walk as f64 * dt;
        // The pendulum stops the COM over the last foot: the settle starts from (nearly)
        // rest, so its reference waits the lead before it moves.
        let rest_tl = Timeline::new(
            settle_start,
            last.foot,
            tl.feet_end,
            &[],
            &[],
            &self.cfg.timing,
            &self.cfg.swing,
            true,
        )?;
        // The pendulum's jerk: d/dt ẍ = (g / z_c) ẋ.
        let k = self.cfg.g / self.cfg.z_c;
        let settle = self.preview_pattern(rest_tl, com, Some([k * vel[0], k * vel[1]]), Vec::new());
        tl.settled = settle.timeline.settled;
        tl.end = settle.timeline.end;
        for mut s in settle.samples {
            s.phase = Phase::Double { step: None };
            s.zmp_ref = settle.timeline.zmp_ref(s.t);
            samples.push(s);
        }
        Ok(Pattern {
            dt,
            timeline: tl,
            samples,
            placed,
        })
    }

    /// The pattern of a plan, checked: where the ZMP's margin in the support polygon falls
    /// below the bar, the step under way then is given more time (up to T_max) and the
    /// pattern made again; a plan that still fails is refused, with the step and the margin.
    /// With a body, the plan's own step times are tried with the whole body under the
    /// pattern; failing, the step times are searched on the cart-table model alone (a tenth
    /// of the cost a try, and the whole body's ZMP keeps within millimetres of it), then the
    /// whole body put under the pattern again, its steps stretched further if need be (eight
    /// tries at most).
    pub fn plan(&self, start: &Start, steps: &[Footstep]) -> Result<Pattern, GaitError> {
        self.plan_until(start, steps, None)
    }

    /// [`Generator::plan`] of a pattern that plays only until step `played`'s touch-down
    /// (None: all of it), as a walker's plan does before the next plan or its stop replaces
    /// it: the whole body is put under the pattern, and its margins checked, up to there and
    /// as far beyond as the preview looks back from it; the later rows, which never play, are
    /// the cart-table model's.
    pub fn plan_until(
        &self,
        start: &Start,
        steps: &[Footstep],
        played: Option<i64>,
    ) -> Result<Pattern, GaitError> {
        let mut durations: Vec<f64> = vec![0.0; steps.len()];
        if self.body.is_some() && self.cfg.generator == Kind::Preview {
            // The plan's own step times first; failing, further ones searched on the cart-table
            // model, then a few more tries with the body at most: each costs three patterns and
            // the legs' kinematics over the whole plan, and a plan the gait waits for is late.
            if let Ok(p) = self.retime(start, steps, &mut durations, Some(played), 1) {
                return Ok(p);
            }
            self.retime(start, steps, &mut durations, None, 64)?;
            return self.retime(start, steps, &mut durations, Some(played), 8);
        }
        self.retime(start, steps, &mut durations, None, 64)
    }

    /// How far back from a row the preview control's reference still moves it, s: beyond
    /// this lookahead its gains hold less than a thousandth of their sum (about 1.4 s at
    /// Archie's COM height; the horizon is 6 s).
    pub fn preview_reach(&self) -> f64 {
        let gains = self.preview.preview_gains();
        let total: f64 = gains.iter().map(|g| g.abs()).sum();
        let mut tail = total;
        for (j, g) in gains.iter().enumerate() {
            if tail <= 1e-3 * total {
                return j as f64 * self.cfg.preview.period;
            }
            tail -= g.abs();
        }
        gains.len() as f64 * self.cfg.preview.period
    }

    /// [`Generator::plan`]'s search from `durations` (left at the times of the pattern
    /// returned), with the whole body if `whole` (up to the step it holds, see
    /// [`Generator::plan_until`]), `tries` patterns at most.
    fn retime(
        &self,
        start: &Start,
        steps: &[Footstep],
        durations: &mut [f64],
        whole: Option<Option<i64>>,
        tries: usize,
    ) -> Result<Pattern, GaitError> {
        let timing = &self.cfg.timing;
        for _ in 0..tries {
            let pat =
                self.generate_with(start, steps, durations, whole.is_some(), whole.flatten())?;
            let bad = pat
                .samples
                .iter()
                .find(|s| s.margin.is_nan() || s.margin < self.cfg.min_margin);
            let Some(bad) = bad else {
                return Ok(pat);
            };
            let fail = |why: &str| {
                Err(GaitError::Zmp(format!(
                    "the ZMP comes {:.4} m from the support polygon's edge at {:.3} s \
                     (at least {} m wanted){why}",
                    bad.margin,
                    bad.t - start.t,
                    self.cfg.min_margin
                )))
            };
            if self.cfg.generator == Kind::FootPlacement || steps.is_empty() {
                return fail("");
            }
            // The step under way (or the last, in the final settle; the first before it).
            let i = match bad.phase {
                Phase::Single { step, .. } | Phase::Double { step: Some(step) } => step,
                Phase::Double { step: None } => {
                    if bad.t >= pat.timeline.steps.last().map_or(f64::MAX, |s| s.land) {
                        pat.timeline.steps.len() - 1
                    } else {
                        0
                    }
                }
            };
            // The timeline's first step is the one under way, when there is one: its times
            // are fixed. The plan's step j is the timeline's j (the plan retargets the step
            // under way) or j + 1.
            let under = start.under_way.is_some();
            if under && i == 0 {
                return fail(" during the step under way, whose times are fixed");
            }
            let j = if under && !Generator::continues(start, steps) {
                i - 1
            } else {
                i
            };
            let s = &pat.timeline.steps[i];
            let now = s.land - s.start;
            if now >= timing.t_max - 1e-9 {
                return fail(&format!(
                    " in step {}, whose time is stretched to T_max = {} s already",
                    steps[j].number, timing.t_max
                ));
            }
            durations[j] = (now * 1.15).min(timing.t_max);
        }
        Err(GaitError::Zmp(
            "no step timing found that keeps the ZMP inside".into(),
        ))
    }
}
