//! `stride-gait`, the walking controller, as a library: its configuration, the messages it
//! takes and sends turned into the gait's own types and back, the stabiliser hook and the move
//! into the standing pose; the app itself is in [`app`].

pub mod app;
mod gait;
mod group;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use stride_footstep::planner::Which;
use stride_gait::archie::{ArchieGait, HeightConfig};
use stride_gait::hexapod::HexGaitConfig;
use stride_gait::pattern::Generator;
use stride_gait::pattern::{Kind, PatternConfig, PlacementConfig};
use stride_gait::preview::PreviewConfig;
use stride_gait::support::Sole;
use stride_gait::swing::{Place, SwingConfig};
use stride_gait::timeline::{Footstep, Side, TimingConfig};
use stride_gait::walker::{Plan, StepCounter, WalkerConfig};
use stride_kinematics::archie::ArchieConfig;
use stride_lcmtypes::stride::{
    FootT, FootstepPlanRequestT, FootstepPlanT, HeaderT, ImuT, JointCommandT, JointTrajectoryT,
    PoseStampedT, StepCounterT, TrajectoryStatusT,
};
use stride_limits::angle::wrap;

/// The period of Archie's joint rows, s (every other 5 ms sample of the pattern).
pub use stride_gait::controller::ROW_PERIOD;

/// The most steps a footstep plan may hold (the planners' own limit): each is checked
/// against the legs, so a plan's length sizes the gait's work.
pub const MAX_PLAN_STEPS: usize = 1000;

/// Which robot the gait drives.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Robot {
    /// Archie: footstep plans, six joints a leg behind Elmo drives or Arduino boards.
    Archie,
    /// The hexapod: walks and the sensing lift on command, 18 Dynamixel servos.
    Hexapod,
}

/// Where a group of joints is driven and read.
#[derive(Debug, Clone, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Channels {
    /// Joint trajectories (stride.joint_trajectory_t) for a trajectory bridge
    /// (stride-elmo-bridge), streamed in chunks.
    pub trajectory: Option<String>,
    /// Position set-points (stride.joint_command_t) for a set-point bridge
    /// (stride-arduino-link, stride-dynamixel-bridge), one a control period.
    pub command: Option<String>,
    /// The joints' measured states (stride.joint_state_t).
    pub state: Option<String>,
    /// The trajectory bridge's status (stride.trajectory_status_t): a bridge that stopped its
    /// drives (an emergency, a stream run dry, a system stop) stops the walk, and the gait
    /// reports it and sends nothing more.
    #[serde(default)]
    pub status: Option<String>,
}

/// The pattern's parameters in the gait's file (the COM height and the sole come from the
/// robot unless given).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PatternSection {
    /// The COM generator: "preview" (the default) or "foot_placement".
    #[serde(default = "preview_kind")]
    pub generator: Kind,
    /// The COM's height, m (absent: from the legs). The thesis's 0.72 m is out of Archie's
    /// reach; the gait says so at start.
    pub z_c: Option<f64>,
    /// Gravity, m/s².
    #[serde(default = "gravity")]
    pub g: f64,
    /// Preview control.
    #[serde(default)]
    pub preview: PreviewConfig,
    /// The foot placement generator.
    #[serde(default)]
    pub placement: PlacementConfig,
    /// Step timing.
    #[serde(default)]
    pub timing: TimingConfig,
    /// The swing.
    #[serde(default)]
    pub swing: SwingConfig,
    /// The smallest margin of the ZMP in the support polygon, m.
    #[serde(default = "min_margin")]
    pub min_margin: f64,
    /// The pattern's COM is the whole robot's (the pelvis placed to carry it); otherwise the
    /// pelvis centre's.
    #[serde(default = "yes")]
    pub whole_body: bool,
    /// Preview control with the whole body's ZMP (Kajita's two-stage preview control, the
    /// second stage made this many times): the legs' own motion taken off the ZMP reference,
    /// so that the joints' whole-body ZMP keeps to the plan; 0: the cart-table model alone.
    #[serde(default = "multibody_passes")]
    pub multibody_passes: usize,
    /// How the COM height is chosen.
    #[serde(default)]
    pub height: HeightConfig,
}

fn multibody_passes() -> usize {
    2
}

fn preview_kind() -> Kind {
    Kind::Preview
}

fn gravity() -> f64 {
    stride_gait::lipm::G
}

fn min_margin() -> f64 {
    0.01
}

fn yes() -> bool {
    true
}

impl Default for PatternSection {
    fn default() -> PatternSection {
        toml::from_str("").expect("every field has a default")
    }
}

impl PatternSection {
    /// The library's pattern parameters for a COM height and a sole.
    pub fn config(&self, z_c: f64, sole: Sole) -> PatternConfig {
        PatternConfig {
            generator: self.generator,
            z_c,
            g: self.g,
            preview: self.preview,
            placement: self.placement,
            timing: self.timing,
            swing: self.swing,
            sole,
            min_margin: self.min_margin,
        }
    }
}

/// The IMU hip-attitude stabiliser hook (the thesis's R23): a proportional baseline that tilts
/// the support leg's hip against the pelvis's measured roll and pitch. Gains of 0 leave it
/// out.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Stabiliser {
    /// Hip roll correction per radian of pelvis roll.
    pub roll_gain: f64,
    /// Hip pitch correction per radian of pelvis pitch.
    pub pitch_gain: f64,
    /// The largest correction, rad.
    pub max: f64,
}

impl Stabiliser {
    /// The pelvis's roll and pitch from an IMU's orientation (w, x, y, z), rad; None when the
    /// sensor gives none or a non-finite one.
    pub fn attitude(imu: &ImuT) -> Option<[f64; 2]> {
        let [w, x, y, z] = imu.orientation;
        let n = (w * w + x * x + y * y + z * z).sqrt();
        if !(n.is_finite() && n > 1e-6) {
            return None;
        }
        let (w, x, y, z) = (w / n, x / n, y / n, z / n);
        let roll = (2.0 * (w * x + y * z)).atan2(1.0 - 2.0 * (x * x + y * y));
        let pitch = (2.0 * (w * y - z * x)).clamp(-1.0, 1.0).asin();
        Some([roll, pitch])
    }

    /// The hip roll and pitch corrections for an attitude: −gain · error, each within ±max.
    pub fn correction(&self, attitude: [f64; 2]) -> [f64; 2] {
        [
            (-self.roll_gain * attitude[0]).clamp(-self.max, self.max),
            (-self.pitch_gain * attitude[1]).clamp(-self.max, self.max),
        ]
    }
}

/// `stride-gait`'s file (config/gait-archie.toml, config/gait-hexapod.toml).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GaitConfig {
    /// The robot.
    pub robot: Robot,
    /// Its robot file (stride-kinematics), relative to this file's folder.
    pub robot_file: PathBuf,
    /// Footstep plans (stride.footstep_plan_t).
    #[serde(default = "plan_channel")]
    pub plan_channel: String,
    /// Commands (stride.gait_command_t).
    #[serde(default = "command_channel")]
    pub command_channel: String,
    /// The step counter (stride.step_counter_t).
    #[serde(default = "step_counter_channel")]
    pub step_counter_channel: String,
    /// The gait's status (stride.trajectory_status_t: plans taken and refused, why it stands).
    #[serde(default = "status_channel")]
    pub status_channel: String,
    /// The IMU on the pelvis (stride.imu_t), for the stabiliser.
    pub imu_channel: Option<String>,
    /// The system stop (stride.gait_command_t STOP and RESUME from the launcher or `stride
    /// stop`), obeyed like a command.
    #[serde(default = "stop_channel")]
    pub stop_channel: String,
    /// Walking to a goal (Archie): goals in, plan requests to the planner out.
    #[serde(default)]
    pub goal: Option<GoalConfig>,
    /// The control loop's rate, Hz.
    #[serde(default = "rate")]
    pub rate_hz: f64,
    /// The step counter's rate, Hz.
    #[serde(default = "counter_rate")]
    pub step_counter_rate_hz: f64,
    /// While the step counter and the set-points do not change (the robot stands), they go
    /// out at this rate, Hz, rather than at theirs (faster than a set-point bridge's hold
    /// timeout: the Dynamixel bridge's is 0.5 s).
    #[serde(default = "idle_rate")]
    pub idle_rate_hz: f64,
    /// Trajectory chunks go out this far ahead of their play, s (more than the bridge's
    /// lookahead).
    #[serde(default = "lookahead")]
    pub lookahead: f64,
    /// A chunk's length, s.
    #[serde(default = "chunk")]
    pub chunk: f64,
    /// The measured joints may be this far from the pattern's start and walk (rad).
    #[serde(default = "start_tolerance")]
    pub start_tolerance: f64,
    /// Further than `start_tolerance`, but within this, the joints are first moved into the
    /// standing pose (rad); further still, the gait reports and does not move.
    #[serde(default = "pose_tolerance")]
    pub pose_tolerance: f64,
    /// ... at this speed, rad/s.
    #[serde(default = "pose_speed")]
    pub pose_speed: f64,
    /// While walking: a joint this far from where the pattern has it (rad) stops the walk.
    #[serde(default = "track_tolerance")]
    pub track_tolerance: f64,
    /// The joints' measurements lag the pattern by about this much (the bridges' queue), s.
    #[serde(default = "track_lag")]
    pub track_lag: f64,
    /// Where the robot's centre stands at start (x, y m, heading rad), in the planner's frame.
    #[serde(default)]
    pub start: [f64; 3],
    /// The joints' channels: Archie's legs "left" and "right", the hexapod's "all".
    #[serde(default)]
    pub joints: BTreeMap<String, Channels>,
    /// The pattern (Archie).
    #[serde(default)]
    pub pattern: PatternSection,
    /// The walk with the planner (Archie).
    #[serde(default)]
    pub walker: WalkerConfig,
    /// The stabiliser (Archie).
    #[serde(default)]
    pub stabiliser: Stabiliser,
    /// The hexapod's gaits.
    #[serde(default)]
    pub hexapod: HexGaitConfig,
    /// Where the ZMP reference stands on a sole, ahead of its centre (Archie), m.
    #[serde(default)]
    pub zmp_ahead: f64,
}

fn plan_channel() -> String {
    "FOOTSTEP_PLAN".into()
}
fn command_channel() -> String {
    "GAIT_COMMAND".into()
}
fn stop_channel() -> String {
    "STRIDE_STOP".into()
}
fn step_counter_channel() -> String {
    "STEP_COUNTER".into()
}
fn status_channel() -> String {
    "GAIT_STATUS".into()
}
fn rate() -> f64 {
    100.0
}
fn counter_rate() -> f64 {
    50.0
}
fn idle_rate() -> f64 {
    5.0
}
fn lookahead() -> f64 {
    0.3
}
fn chunk() -> f64 {
    0.2
}
fn start_tolerance() -> f64 {
    0.02
}
fn pose_tolerance() -> f64 {
    1.0
}
fn pose_speed() -> f64 {
    0.3
}
fn track_tolerance() -> f64 {
    0.2
}
fn track_lag() -> f64 {
    0.05
}

impl GaitConfig {
    /// Checks what the types cannot: positive rates and times, the legs named for the robot,
    /// a chunk and lookahead that fit the walker's switch.
    pub fn check(&self) -> Result<(), String> {
        let pos = [
            ("rate_hz", self.rate_hz),
            ("step_counter_rate_hz", self.step_counter_rate_hz),
            ("idle_rate_hz", self.idle_rate_hz),
            ("lookahead", self.lookahead),
            ("chunk", self.chunk),
            ("start_tolerance", self.start_tolerance),
            ("pose_tolerance", self.pose_tolerance),
            ("pose_speed", self.pose_speed),
            ("track_tolerance", self.track_tolerance),
        ];
        for (name, v) in pos {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{name} must be positive, not {v}"));
            }
        }
        // The move into the pose is sized by them: rows of 10 ms over tolerance / speed.
        if self.pose_speed < 0.01 || self.pose_tolerance > std::f64::consts::PI {
            return Err(format!(
                "pose_speed {} must be at least 0.01 rad/s and pose_tolerance {} at most pi",
                self.pose_speed, self.pose_tolerance
            ));
        }
        let want: &[&str] = match self.robot {
            Robot::Archie => &["left", "right"],
            Robot::Hexapod => &["all"],
        };
        for name in self.joints.keys() {
            if !want.contains(&name.as_str()) {
                return Err(format!(
                    "joints.{name}: the {:?}'s joint groups are {want:?}",
                    self.robot
                ));
            }
        }
        if self.joints.is_empty() {
            return Err(format!("no joints: name their channels ({want:?})"));
        }
        if self.robot == Robot::Archie && self.walker.switch_ahead < self.lookahead {
            return Err(format!(
                "walker.switch_ahead ({} s) must be at least the lookahead ({} s): a new \
                 pattern replaces only what was not sent",
                self.walker.switch_ahead, self.lookahead
            ));
        }
        if self.walker.steps_per_plan == 0 {
            return Err(
                "walker.steps_per_plan must be at least 1: 0 would never walk a plan".into(),
            );
        }
        self.pattern.timing.check().map_err(|e| e.to_string())?;
        if let Some(g) = &self.goal {
            g.check()?;
        }
        Ok(())
    }

    /// The robot file's path, relative to the folder of the file the configuration came
    /// from.
    pub fn robot_path(&self, config_file: Option<&Path>) -> PathBuf {
        match config_file.and_then(Path::parent) {
            Some(dir) if self.robot_file.is_relative() => dir.join(&self.robot_file),
            _ => self.robot_file.clone(),
        }
    }
}

/// A footstep plan as the walker takes it: every step numbered, finite and on a side, the
/// plan's status a walkable one (ok, or partial with steps). An error says why not.
pub fn plan_of(msg: &FootstepPlanT) -> Result<Plan, String> {
    if msg.status != FootstepPlanT::STATUS_OK && msg.status != FootstepPlanT::STATUS_PARTIAL {
        return Err(format!(
            "the planner's status {} ({}) is no plan to walk",
            msg.status, msg.detail
        ));
    }
    if msg.num_steps < 0 || msg.num_steps as usize != msg.steps.len() {
        return Err(format!(
            "num_steps {} for {} steps",
            msg.num_steps,
            msg.steps.len()
        ));
    }
    if msg.steps.len() > MAX_PLAN_STEPS {
        return Err(format!(
            "{} steps, more than the {MAX_PLAN_STEPS} a plan may hold",
            msg.steps.len()
        ));
    }
    let mut steps = Vec::with_capacity(msg.steps.len());
    for (i, s) in msg.steps.iter().enumerate() {
        let side = match s.foot.side {
            FootT::SIDE_LEFT => Side::Left,
            FootT::SIDE_RIGHT => Side::Right,
            other => {
                return Err(format!(
                    "step {}: side {other} is neither foot",
                    s.step_number
                ))
            }
        };
        if s.step_number != msg.step_number + 1 + i as i64 {
            return Err(format!(
                "step {i} is numbered {}, not {} (the plan echoes step {})",
                s.step_number,
                msg.step_number + 1 + i as i64,
                msg.step_number
            ));
        }
        steps.push(Footstep {
            number: s.step_number,
            side,
            place: [s.foot.x, s.foot.y, s.foot.z, s.foot.yaw],
            swing_height: s.swing_height,
            duration: s.duration,
            padding: s.is_padding,
        });
    }
    Ok(Plan {
        echo: msg.step_number,
        steps,
        reaches_goal: msg.status == FootstepPlanT::STATUS_OK,
    })
}

/// The step counter's message.
pub fn counter_msg(header: HeaderT, c: &StepCounter) -> StepCounterT {
    StepCounterT {
        header,
        step_number: c.number,
        swing_side: match c.swing {
            Some(Side::Left) => FootT::SIDE_LEFT,
            Some(Side::Right) => FootT::SIDE_RIGHT,
            None => -1,
        },
        phase: c.phase,
    }
}

/// A PVT trajectory of `names`: rows at `times` (s, from the first row), starting at
/// `start_utime` (0: as soon as the bridge can) and replacing what is queued or following it.
pub fn trajectory_msg(
    header: HeaderT,
    names: &[String],
    times: &[f64],
    positions: &[Vec<f64>],
    velocities: &[Vec<f64>],
    start_utime: i64,
    append: bool,
) -> JointTrajectoryT {
    let t0 = times.first().copied().unwrap_or(0.0);
    JointTrajectoryT {
        header,
        start_utime: if append { 0 } else { start_utime },
        mode: JointTrajectoryT::MODE_PVT,
        queue: if append {
            JointTrajectoryT::QUEUE_APPEND
        } else {
            JointTrajectoryT::QUEUE_REPLACE
        },
        num_joints: names.len() as i32,
        joint_names: names.to_vec(),
        num_rows: times.len() as i32,
        // Whole microseconds from the first row, rounded to the millisecond grid of PVT rows.
        time_from_start: times
            .iter()
            .map(|t| ((t - t0) * 1e3).round() / 1e3)
            .collect(),
        positions: positions.to_vec(),
        velocities: velocities.to_vec(),
    }
}

/// Position set-points with their speeds.
pub fn command_msg(
    header: HeaderT,
    names: &[String],
    positions: &[f64],
    velocities: &[f64],
) -> JointCommandT {
    JointCommandT {
        header,
        num_joints: names.len() as i32,
        names: names.to_vec(),
        modes: vec![JointCommandT::MODE_POSITION; names.len()],
        setpoints: positions.to_vec(),
        velocities: velocities.to_vec(),
    }
}

/// Archie's legs and pattern generator as `cfg` sets them: the COM height from the legs
/// (or the file's `z_c`), the sole from the robot file, the ZMP reference `zmp_ahead`.
pub fn archie_gait(
    cfg: &GaitConfig,
    robot: ArchieConfig,
) -> Result<(ArchieGait, Generator), String> {
    let p = &cfg.pattern;
    let sole = Sole {
        length: robot.foot.length,
        width: robot.foot.width,
    };
    let mut legs = ArchieGait::new(robot, &p.height, cfg.zmp_ahead, ROW_PERIOD, p.whole_body)
        .map_err(|e| e.to_string())?;
    if let Some(z) = p.z_c {
        legs.z_c = z;
    }
    let mut timing = p.timing;
    timing.zmp_ahead = cfg.zmp_ahead;
    let pattern = PatternSection {
        timing,
        ..p.clone()
    }
    .config(legs.z_c, sole);
    let mut gen = Generator::new(pattern).map_err(|e| e.to_string())?;
    if p.multibody_passes > 0 {
        gen = gen.with_body(std::sync::Arc::new(legs.clone()), p.multibody_passes);
    }
    Ok((legs, gen))
}

#[cfg(test)]
mod tests {
    use super::*;
    use stride_lcmtypes::stride::FootstepT;

    #[test]
    fn a_plan_too_late_for_its_step_makes_the_gait_ask_at_once_for_the_step_at_the_switch() {
        let resend = 1.0;
        // A step begins: asked for it.
        let a = Asking {
            now: 5,
            at_switch: 5,
            asked: Some((4, 0.0)),
            taken: Some(4),
            late: false,
        };
        assert_eq!(a.next(0.1, resend), (5, true));
        // Its plan taken: nothing more until the next step, not even after `resend`.
        let a = Asking {
            asked: Some((5, 0.1)),
            taken: Some(5),
            ..a
        };
        assert_eq!(a.next(0.6, resend), (5, false));
        assert_eq!(a.next(1.2, resend), (5, false));
        // Late in the step an obstacle appears: the planner's replan, asked for step 5, comes
        // when a plan takes over in step 6. Step 6 is asked for at once, not when it begins.
        let late = Asking {
            at_switch: 6,
            late: true,
            ..a
        };
        assert_eq!(late.next(0.8, resend), (6, true));
        // Still in step 5 afterwards: step 5 is not asked for again (its plan would be late).
        let after = Asking {
            at_switch: 6,
            asked: Some((6, 0.8)),
            taken: Some(5),
            late: false,
            ..a
        };
        assert_eq!(after.next(0.9, resend), (6, false));
        // Step 6 begins: already asked.
        assert_eq!(Asking { now: 6, ..after }.next(1.0, resend), (6, false));
        // No plan for it taken (the planner gone): asked again every `resend` s.
        assert_eq!(Asking { now: 6, ..after }.next(1.8, resend), (6, true));
        // A late plan while the step at the switch was already asked for: nothing new.
        let twice = Asking {
            late: true,
            ..after
        };
        assert_eq!(twice.next(0.85, resend), (6, false));
        // The first request of a walk.
        let first = Asking {
            asked: None,
            taken: None,
            ..a
        };
        assert_eq!(first.next(0.0, resend), (5, true));
    }

    #[test]
    fn a_bridge_that_stops_its_drives_is_told_once_at_the_turn() {
        // The finding: a leg's stream ran dry under load and its bridge quick-stopped the
        // drives; the gait walked on. It now hears the turn to stopped (not the repeats of a
        // bridge still stopped, nor a stop it was told of before a resume re-armed it).
        let status = |state: i8| TrajectoryStatusT {
            node: "left-leg".into(),
            state,
            reason: "left_knee ran out of rows while moving".into(),
            ..Default::default()
        };
        let mut w = BridgeWatch::default();
        assert_eq!(
            w.on_status("left", &status(TrajectoryStatusT::STATE_MOVING)),
            None
        );
        let why = w.on_status("left", &status(TrajectoryStatusT::STATE_STOPPED));
        assert_eq!(
            why.map(|s| s.why).as_deref(),
            Some("the left bridge (left-leg) stopped its drives: left_knee ran out of rows while moving")
        );
        assert_eq!(
            w.on_status("left", &status(TrajectoryStatusT::STATE_STOPPED)),
            None
        );
        assert_eq!(
            w.on_status("left", &status(TrajectoryStatusT::STATE_MOVING)),
            None
        );
        assert!(w
            .on_status("left", &status(TrajectoryStatusT::STATE_STOPPED))
            .is_some_and(|s| !s.dry));
    }

    /// D4 of the reliability findings: a bridge whose stream ran dry said MOVING, then IDLE,
    /// and the gait heard of it only from its tracking check. A stop with the bridge's count
    /// of dry streams gone up is a dry stream: the gait may stand up again by itself.
    #[test]
    fn a_stream_run_dry_is_a_stop_the_gait_tells_from_the_others() {
        let status = |state: i8, stream_stops: i64| TrajectoryStatusT {
            node: "left-leg".into(),
            state,
            stream_stops,
            reason: "trajectory stream ran dry: left_knee decelerating to a stop".into(),
            ..Default::default()
        };
        let mut w = BridgeWatch::default();
        assert!(w
            .on_status("left", &status(TrajectoryStatusT::STATE_MOVING, 0))
            .is_none());
        let stop = w
            .on_status("left", &status(TrajectoryStatusT::STATE_STOPPED, 1))
            .unwrap();
        assert!(stop.dry && stop.why.contains("ran dry"), "{stop:?}");
    }

    #[test]
    fn after_a_stop_the_feet_stand_beside_the_one_that_bears_the_weight() {
        use stride_gait::swing::SwingConfig;
        use stride_gait::timeline::{Timeline, TimingConfig};
        let steps = [
            stride_gait::timeline::Footstep {
                number: 1,
                side: Side::Left,
                place: [0.2, 0.1, 0.0, 0.0],
                swing_height: 0.03,
                duration: 0.0,
                padding: false,
            },
            stride_gait::timeline::Footstep {
                number: 2,
                side: Side::Right,
                place: [0.4, -0.1, 0.0, 0.0],
                swing_height: 0.03,
                duration: 0.0,
                padding: false,
            },
        ];
        let tl = Timeline::new(
            0.0,
            [0.0, 0.0],
            [[0.0, 0.1, 0.0, 0.0], [0.0, -0.1, 0.0, 0.0]],
            &steps,
            &[],
            &TimingConfig::default(),
            &SwingConfig::default(),
            true,
        )
        .unwrap();
        let s2 = &tl.steps[1];
        // The right foot in the air: the left (landed at 0.2) bears the weight.
        let feet = stand_from(&tl, (s2.lift + s2.land) / 2.0, 0.2);
        assert_eq!(feet[0], [0.2, 0.1, 0.0, 0.0]);
        assert!((feet[1][0] - 0.2).abs() < 1e-12 && (feet[1][1] + 0.1).abs() < 1e-12);
        // Both landed: the right, last, stays.
        let feet = stand_from(&tl, s2.land + 0.01, 0.2);
        assert_eq!(feet[1], [0.4, -0.1, 0.0, 0.0]);
        assert!((feet[0][1] - 0.1).abs() < 1e-12 && (feet[0][0] - 0.4).abs() < 1e-12);
    }

    #[test]
    fn an_anchor_maps_places_both_ways_and_puts_the_pelvis_where_it_was_measured() {
        let a = Anchor {
            x: 0.3,
            y: -0.2,
            yaw: 3.0,
        };
        let p = [1.0, 2.0, 0.05, -3.0];
        let back = a.to_gait(a.to_world(p));
        for k in 0..4 {
            assert!((back[k] - p[k]).abs() < 1e-12, "{back:?}");
        }
        // The heading wraps: 3 + (-3) is 0, 3 + 0.5 is past π.
        assert!(a.to_world(p)[3].abs() < 1e-12);
        let world = [4.0, 1.0, 3.1];
        let gait = [3.8, 1.1, -3.1];
        let b = Anchor::between(world, gait);
        let w = b.to_world([gait[0], gait[1], 0.0, gait[2]]);
        assert!((w[0] - 4.0).abs() < 1e-12 && (w[1] - 1.0).abs() < 1e-12);
        assert!((w[3] - 3.1).abs() < 1e-12, "{w:?}");
        // Halfway across ±π goes the short way round.
        let c = Anchor::default().toward(
            &Anchor {
                yaw: 3.1,
                ..Default::default()
            },
            0.5,
        );
        assert!((c.yaw - 1.55).abs() < 1e-12);
        let d = Anchor {
            yaw: 3.1,
            ..Default::default()
        }
        .toward(
            &Anchor {
                yaw: -3.1,
                ..Default::default()
            },
            0.5,
        );
        assert!((d.yaw.abs() - std::f64::consts::PI).abs() < 1e-12, "{d:?}");
        assert!(
            Anchor::default().distance(
                &Anchor {
                    x: 0.3,
                    y: 0.4,
                    yaw: 0.0
                },
                [5.0, 5.0]
            ) - 0.5
                < 1e-12
        );
    }

    fn msg(echo: i64, n: usize) -> FootstepPlanT {
        FootstepPlanT {
            step_number: echo,
            status: FootstepPlanT::STATUS_OK,
            num_steps: n as i32,
            steps: (0..n)
                .map(|i| FootstepT {
                    step_number: echo + 1 + i as i64,
                    foot: FootT {
                        side: (i % 2) as i8,
                        x: 0.1 * i as f64,
                        y: 0.1,
                        z: 0.0,
                        yaw: 0.0,
                    },
                    swing_height: 0.05,
                    duration: 0.0,
                    is_padding: i + 1 == n,
                })
                .collect(),
            ..Default::default()
        }
    }

    #[test]
    fn a_goal_facing_back_is_reached_by_feet_whose_headings_straddle_pi() {
        // The feet's mean heading is taken on the circle: -3.1 and 3.1 rad face π (their
        // plain average, 0, faces the other way).
        let cfg: GoalConfig = toml::from_str("yaw_tolerance = 0.1").unwrap();
        let goal = Goal {
            x: 1.0,
            y: 0.0,
            yaw: std::f64::consts::PI,
            any_heading: false,
        };
        let feet = [[1.0, -0.1, 0.0, 3.1], [1.0, 0.1, 0.0, -3.1]];
        assert!(at_goal(&feet, &goal, &cfg));
        assert!(!at_goal(
            &[[1.0, -0.1, 0.0, 0.0], [1.0, 0.1, 0.0, 0.0]],
            &goal,
            &cfg
        ));
    }

    #[test]
    fn a_plan_message_becomes_the_walkers_plan() {
        let p = plan_of(&msg(4, 3)).unwrap();
        assert_eq!(p.echo, 4);
        assert_eq!(p.steps.len(), 3);
        assert_eq!(p.steps[0].number, 5);
        assert_eq!(p.steps[1].side, Side::Right);
        assert!(p.steps[2].padding);
        assert_eq!(p.steps[1].place, [0.1, 0.1, 0.0, 0.0]);
    }

    #[test]
    fn plans_that_make_no_sense_are_errors() {
        let mut m = msg(4, 3);
        m.status = FootstepPlanT::STATUS_NO_PATH;
        m.detail = "blocked".into();
        assert!(plan_of(&m).unwrap_err().contains("blocked"));
        let mut m = msg(4, 3);
        m.num_steps = 5;
        assert!(plan_of(&m).unwrap_err().contains("num_steps"));
        let mut m = msg(4, 3);
        m.steps[1].step_number = 9;
        assert!(plan_of(&m).unwrap_err().contains("numbered 9"));
        let mut m = msg(4, 3);
        m.steps[0].foot.side = 7;
        assert!(plan_of(&m).unwrap_err().contains("side 7"));
    }

    #[test]
    fn the_stabiliser_tilts_against_the_pelvis_and_stays_within_its_bound() {
        // Rolled 0.1 rad: w = cos 0.05, x = sin 0.05.
        let imu = ImuT {
            orientation: [0.05f64.cos(), 0.05f64.sin(), 0.0, 0.0],
            ..Default::default()
        };
        let a = Stabiliser::attitude(&imu).unwrap();
        assert!((a[0] - 0.1).abs() < 1e-12 && a[1].abs() < 1e-12);
        let s = Stabiliser {
            roll_gain: 0.5,
            pitch_gain: 0.5,
            max: 0.03,
        };
        assert_eq!(s.correction(a), [-0.03, 0.0]);
        assert!(Stabiliser::attitude(&ImuT::default()).is_none());
    }
}

/// Walking to a goal: the gait asks the planner for the steps from where its feet will stand
/// when the step under way lands, at every step (the planner's answer echoes the step), and
/// again every `resend` s while no plan is taken (a planner restarted, a request lost), until
/// it stands within `tolerance` of the goal.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GoalConfig {
    /// Goals (stride.pose_stamped_t: position and heading, world frame).
    #[serde(default = "goal_channel")]
    pub channel: String,
    /// Plan requests (stride.footstep_plan_request_t).
    #[serde(default = "request_channel")]
    pub request_channel: String,
    /// Which planner: "archie", "kaist" or "lola".
    #[serde(default = "archie_planner")]
    pub planner: String,
    /// The thesis's planner instead of the improved one.
    #[serde(default)]
    pub faithful: bool,
    /// Standing this close to the goal (the feet's centre) is there, m; the planner is asked
    /// for half of it.
    #[serde(default = "goal_tolerance")]
    pub tolerance: f64,
    /// The heading's tolerance, rad (π: any heading).
    #[serde(default = "yaw_tolerance")]
    pub yaw_tolerance: f64,
    /// The planner's budget, ms (0: its own).
    #[serde(default)]
    pub budget_ms: u64,
    /// A request is sent again after this long without a plan taken, s.
    #[serde(default = "resend")]
    pub resend: f64,
    /// Extra planner parameters (e.g. max_step, the walker's max_length).
    #[serde(default)]
    pub params: BTreeMap<String, f64>,
    /// Where the pelvis really is (stride.odometry_t, world frame: a state estimator, or the
    /// simulated world): the gait's frame is anchored to it, so that a request starts from
    /// the feet where they stand and a plan is walked where the planner put it. None: the
    /// gait's own frame is taken for the world.
    #[serde(default)]
    pub odometry_channel: Option<String>,
    /// The share of each estimate's difference from the anchor taken (its noise averaged).
    #[serde(default = "odometry_gain")]
    pub odometry_gain: f64,
    /// An estimate further than this from the anchor (m) is not believed: dropped, counted.
    #[serde(default = "odometry_max_jump")]
    pub odometry_max_jump: f64,
}

fn odometry_gain() -> f64 {
    0.05
}
fn odometry_max_jump() -> f64 {
    0.3
}
fn goal_channel() -> String {
    "WALK_GOAL".into()
}
fn request_channel() -> String {
    "FOOTSTEP_PLAN_REQUEST".into()
}
fn archie_planner() -> String {
    "archie".into()
}
fn goal_tolerance() -> f64 {
    0.15
}
fn yaw_tolerance() -> f64 {
    std::f64::consts::PI
}
fn resend() -> f64 {
    1.0
}

impl GoalConfig {
    /// Checks the planner's name and the numbers.
    pub fn check(&self) -> Result<(), String> {
        self.planner_id()?;
        let ok = |v: f64| v.is_finite() && v > 0.0;
        if !(ok(self.tolerance) && ok(self.yaw_tolerance) && ok(self.resend)) {
            return Err("goal: tolerance, yaw_tolerance and resend must be positive".into());
        }
        if !(ok(self.odometry_gain) && self.odometry_gain <= 1.0 && ok(self.odometry_max_jump)) {
            return Err(
                "goal: odometry_gain must be in (0, 1] and odometry_max_jump positive".into(),
            );
        }
        if let Some((k, v)) = self.params.iter().find(|(_, v)| !v.is_finite()) {
            return Err(format!("goal.params.{k} = {v} is not a number"));
        }
        Ok(())
    }

    /// The request's planner constant.
    pub fn planner_id(&self) -> Result<i8, String> {
        self.planner
            .parse::<Which>()
            .map(Which::id)
            .map_err(|e| format!("goal.planner: {e}"))
    }
}

/// Where the gait's frame lies in the world (the planner's frame): the planar transform from
/// gait to world, its origin (m) and heading (rad). The gait walks its patterns in its own
/// frame; where the body really goes drifts from it (the drives' lag at each touch-down), and
/// measured poses of the pelvis correct the anchor.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Anchor {
    /// The gait frame's origin in the world, m.
    pub x: f64,
    /// The gait frame's origin in the world, m.
    pub y: f64,
    /// Its heading in the world, rad.
    pub yaw: f64,
}

impl Anchor {
    /// A place of the gait's frame in the world.
    pub fn to_world(&self, p: Place) -> Place {
        let (s, c) = self.yaw.sin_cos();
        [
            self.x + c * p[0] - s * p[1],
            self.y + s * p[0] + c * p[1],
            p[2],
            wrap(p[3] + self.yaw),
        ]
    }

    /// A place of the world in the gait's frame.
    pub fn to_gait(&self, p: Place) -> Place {
        let (s, c) = self.yaw.sin_cos();
        let (dx, dy) = (p[0] - self.x, p[1] - self.y);
        [
            c * dx + s * dy,
            -s * dx + c * dy,
            p[2],
            wrap(p[3] - self.yaw),
        ]
    }

    /// The anchor that puts the pelvis at `gait` (x, y, heading in the gait's frame) where it
    /// was measured, `world`.
    pub fn between(world: [f64; 3], gait: [f64; 3]) -> Anchor {
        let yaw = wrap(world[2] - gait[2]);
        let (s, c) = yaw.sin_cos();
        Anchor {
            x: world[0] - (c * gait[0] - s * gait[1]),
            y: world[1] - (s * gait[0] + c * gait[1]),
            yaw,
        }
    }

    /// `gain` of the way to `to` (the heading on the circle).
    pub fn toward(&self, to: &Anchor, gain: f64) -> Anchor {
        Anchor {
            x: self.x + gain * (to.x - self.x),
            y: self.y + gain * (to.y - self.y),
            yaw: wrap(self.yaw + gain * wrap(to.yaw - self.yaw)),
        }
    }

    /// How far apart two anchors put a point of the gait's frame at `at`, m.
    pub fn distance(&self, other: &Anchor, at: [f64; 2]) -> f64 {
        let (a, b) = (
            self.to_world([at[0], at[1], 0.0, 0.0]),
            other.to_world([at[0], at[1], 0.0, 0.0]),
        );
        (a[0] - b[0]).hypot(a[1] - b[1])
    }
}

/// The pelvis of a joint plan that starts at `start` (walker time, s) at walker time `t`:
/// x, y and heading, between its rows, held after its last (the robot stands there); None
/// before the plan.
pub fn pelvis_at(plan: &stride_gait::archie::JointPlan, start: f64, t: f64) -> Option<[f64; 3]> {
    let i = plan.times.partition_point(|&x| start + x <= t);
    let planar = |p: &stride_kinematics::math::Pose| {
        use stride_kinematics::math::Frame;
        let at = p.position();
        [at[0], at[1], p.yaw()]
    };
    if i == 0 {
        return None;
    }
    if i >= plan.times.len() {
        return plan.pelvis.last().map(planar);
    }
    let (t0, t1) = (start + plan.times[i - 1], start + plan.times[i]);
    let s = if t1 > t0 { (t - t0) / (t1 - t0) } else { 0.0 };
    let (a, b) = (planar(&plan.pelvis[i - 1]), planar(&plan.pelvis[i]));
    Some([
        a[0] + s * (b[0] - a[0]),
        a[1] + s * (b[1] - a[1]),
        wrap(a[2] + s * wrap(b[2] - a[2])),
    ])
}

/// The pelvis of an odometry message: x, y and heading (None unless finite).
pub fn odometry_pelvis(m: &stride_lcmtypes::stride::OdometryT) -> Option<[f64; 3]> {
    let [w, x, y, z] = m.pose.orientation;
    let yaw = (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z));
    let p = [m.pose.position[0], m.pose.position[1], yaw];
    p.iter().all(|v| v.is_finite()).then_some(p)
}

/// What a trajectory bridge's status last said: a bridge stopped goes on saying so every
/// second until a trajectory re-arms it, so only the turn to stopped counts.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BridgeWatch {
    last: Option<i8>,
    stream_stops: Option<i64>,
}

/// A trajectory bridge stopped its drives.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BridgeStop {
    /// Why, in words (the bridge's node and reason).
    pub why: String,
    /// Its stream ran dry (the gait's rows came too late): the joints decelerated to a stop
    /// within their limits, nothing is wrong with the drives.
    pub dry: bool,
}

impl BridgeWatch {
    /// Takes the status of the bridge of joint group `group`: why it stopped its drives, when
    /// this status is the turn to stopped.
    pub fn on_status(&mut self, group: &str, m: &TrajectoryStatusT) -> Option<BridgeStop> {
        let stopped = TrajectoryStatusT::STATE_STOPPED;
        let turned = m.state == stopped && self.last != Some(stopped);
        let dry = self.stream_stops.is_some_and(|n| m.stream_stops > n);
        self.last = Some(m.state);
        self.stream_stops = Some(m.stream_stops);
        turned.then(|| BridgeStop {
            why: format!(
                "the {group} bridge ({}) stopped its drives: {}",
                m.node, m.reason
            ),
            dry,
        })
    }
}

/// Where the feet stand once the robot is brought into its standing pose from the walk of
/// `timeline` at `t` (the drives stopped under it): the foot that bears the weight stays (the
/// support of the step under way; between steps, the one that landed last), the other comes
/// beside it, `width` apart.
pub fn stand_from(timeline: &stride_gait::timeline::Timeline, t: f64, width: f64) -> [Place; 2] {
    let mut feet = timeline.feet_start;
    let mut anchor = Side::Left;
    for s in &timeline.steps {
        if s.land <= t {
            feet[s.footstep.side.index()] = s.footstep.place;
            anchor = s.footstep.side;
        } else if s.start <= t {
            anchor = s.footstep.side.other();
        }
    }
    let a = feet[anchor.index()];
    let side = match anchor {
        Side::Left => -1.0,
        Side::Right => 1.0,
    };
    let (s, c) = a[3].sin_cos();
    let beside = [a[0] - s * side * width, a[1] + c * side * width, a[2], a[3]];
    let mut out = feet;
    out[anchor.other().index()] = beside;
    out
}

/// A goal to walk to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Goal {
    /// Position, m.
    pub x: f64,
    /// Position, m.
    pub y: f64,
    /// Heading, rad.
    pub yaw: f64,
    /// Any heading will do.
    pub any_heading: bool,
}

/// A goal message as a goal (None for one not made of finite numbers). A child frame of
/// "goal_any_heading" leaves the heading free.
pub fn goal_of(m: &PoseStampedT) -> Option<Goal> {
    let [w, x, y, z] = m.pose.orientation;
    let yaw = (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z));
    let g = Goal {
        x: m.pose.position[0],
        y: m.pose.position[1],
        yaw,
        any_heading: m.child_frame == "goal_any_heading",
    };
    (g.x.is_finite() && g.y.is_finite() && g.yaw.is_finite()).then_some(g)
}

/// Where the feet stand once step `number` (and every step before it) of `timeline` has
/// landed, and the side that swings next.
pub fn feet_after(timeline: &stride_gait::timeline::Timeline, number: i64) -> ([Place; 2], Side) {
    let mut feet = timeline.feet_start;
    let mut next = Side::Left;
    for s in timeline
        .steps
        .iter()
        .filter(|s| s.footstep.number <= number)
    {
        feet[s.footstep.side.index()] = s.footstep.place;
        next = s.footstep.side.other();
    }
    (feet, next)
}

/// What the gait knows when it decides to ask the planner (see [`Asking::next`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Asking {
    /// The step under way now.
    pub now: i64,
    /// The step under way when a plan that came now would take over (after the rows already
    /// sent): a plan is taken for that step only.
    pub at_switch: i64,
    /// The step last asked for, and when (s).
    pub asked: Option<(i64, f64)>,
    /// The step the last plan taken was asked for.
    pub taken: Option<i64>,
    /// A plan came for a step already past at its switch since the last decision (the
    /// planner's replan when the world changed comes at any time of a step).
    pub late: bool,
}

impl Asking {
    /// The step to ask for at `t` and whether to ask now: the step under way, as each begins;
    /// after a late plan, at once the step at the switch (else the replan would wait for the
    /// next step's request); never a step below the one asked; again every `resend` s while
    /// no plan for the step asked is taken (a planner restarted, a request lost).
    pub fn next(&self, t: f64, resend: f64) -> (i64, bool) {
        let asked = self.asked.map(|(s, _)| s);
        let step = match asked {
            Some(s) if self.late && self.at_switch > s => self.at_switch,
            Some(s) => self.now.max(s),
            None => self.now,
        };
        let due = match self.asked {
            Some((s, at)) => step != s || (self.taken != Some(s) && t - at >= resend),
            None => true,
        };
        (step, due)
    }
}

/// A plan request from the feet `feet` (left, right), `next` to swing first, during step
/// `step`, to `goal`.
pub fn request_msg(
    header: HeaderT,
    id: i64,
    step: i64,
    feet: [Place; 2],
    next: Side,
    goal: &Goal,
    cfg: &GoalConfig,
) -> FootstepPlanRequestT {
    let foot = |side: Side| {
        let p = feet[side.index()];
        FootT {
            side: match side {
                Side::Left => FootT::SIDE_LEFT,
                Side::Right => FootT::SIDE_RIGHT,
            },
            x: p[0],
            y: p[1],
            z: p[2],
            yaw: p[3],
        }
    };
    FootstepPlanRequestT {
        header,
        request_id: id,
        step_number: step,
        stance: foot(next.other()),
        swing: foot(next),
        goal_x: goal.x,
        goal_y: goal.y,
        goal_yaw: goal.yaw,
        goal_tolerance: cfg.tolerance / 2.0,
        goal_yaw_tolerance: if goal.any_heading {
            std::f64::consts::PI
        } else {
            cfg.yaw_tolerance
        },
        planner: cfg.planner_id().unwrap_or(Which::Archie.id()),
        faithful: cfg.faithful,
        max_expansions: 0,
        max_time_us: cfg.budget_ms as i64 * 1000,
        num_params: cfg.params.len() as i32,
        param_names: cfg.params.keys().cloned().collect(),
        param_values: cfg.params.values().copied().collect(),
    }
}

/// True when the feet stand within the goal's tolerances.
pub fn at_goal(feet: &[Place; 2], goal: &Goal, cfg: &GoalConfig) -> bool {
    let (x, y) = (
        (feet[0][0] + feet[1][0]) / 2.0,
        (feet[0][1] + feet[1][1]) / 2.0,
    );
    let d = (x - goal.x).hypot(y - goal.y);
    // The feet's mean heading (on the circle: -3.1 and 3.1 rad average to π, not 0).
    let yaw = (feet[0][3].sin() + feet[1][3].sin()).atan2(feet[0][3].cos() + feet[1][3].cos());
    let dyaw = (yaw - goal.yaw + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
        - std::f64::consts::PI;
    d <= cfg.tolerance && (goal.any_heading || dyaw.abs() <= cfg.yaw_tolerance)
}
