//! The planner's settings: the robot's step limits and sole, the mode, the budget.

use std::time::Duration;

use crate::plan::Cancel;

/// The 2-D pre-planner whose way the couplings follow.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PrePlanner {
    /// The thesis's: seeds shifted to free space, one way per homotopy class, the cheapest by
    /// Eq. 4.17 ([`preplan`](mod@crate::lola::preplan)).
    Thesis,
    /// A distance field over the tall obstacles: the shortest way, as a heuristic that is a
    /// lower bound of its length from anywhere.
    Field,
}

/// The robot: foot, shank and step limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Robot {
    /// Sole length and width, m.
    pub foot: (f64, f64),
    /// Radius of the sole's two rounded triangles, m.
    pub sole_radius: f64,
    /// Ankle height above the sole, m.
    pub ankle: f64,
    /// Shank length (ankle to knee), m.
    pub shank: f64,
    /// Shank radius, m.
    pub shank_radius: f64,
    /// Centre of gravity height (for the shank's tilt), m.
    pub cog_height: f64,
    /// Nominal distance between the feet, m.
    pub width: f64,
    /// Highest obstacle a swing may step over, m.
    pub h_max: f64,
    /// Largest step up or down, m.
    pub max_step_height: f64,
    /// The swing's reference height above the higher foothold, m.
    pub swing_height: f64,
}

impl Default for Robot {
    /// LOLA's proportions (the thesis gives no sizes: anthropometric for 1.80 m, see the
    /// module's doc).
    fn default() -> Self {
        Robot {
            foot: (0.22, 0.12),
            sole_radius: 0.02,
            ankle: 0.10,
            shank: 0.44,
            shank_radius: 0.06,
            cog_height: 0.88,
            width: 0.20,
            h_max: 0.15,
            max_step_height: 0.15,
            swing_height: 0.02,
        }
    }
}

/// Which planner.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// The thesis's search tree and heuristic, no coupling.
    Thesis,
    /// Lattice, the pre-planner's couplings, best partial plan at the deadline.
    Improved,
}

/// The settings of a search.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// The robot.
    pub robot: Robot,
    /// Desired step: advance, extra width, turn (m, m, rad).
    pub desired: (f64, f64, f64),
    /// k of the step cost.
    pub k: f64,
    /// Weight of the heading, m/rad.
    pub w_theta: f64,
    /// The 34-suggestion set instead of 85.
    pub reduced: bool,
    /// Goal tolerance: position (m) and heading (rad) of the mid-stance point.
    pub tolerance: (f64, f64),
    /// The search stops at this many steps (the receding horizon), if set.
    pub horizon: Option<usize>,
    /// Time budget.
    pub budget: Duration,
    /// Set to stop the search at once (it answers as at its budget).
    pub cancel: Cancel,
    /// Expansion cap.
    pub max_expansions: u64,
    /// Margin of the distance field's point robot around tall obstacles, m (the thesis's
    /// pre-planner keeps its own, 0.25 m).
    pub margin: f64,
    /// Margin of the field whose way gives the desired heading where it leaves room (wider,
    /// so that the feet and shanks pass obstacles with room to spare), m.
    pub heading_margin: f64,
    /// Which 2-D pre-planner the couplings follow.
    pub preplanner: PrePlanner,
    /// Coupling 1: the pre-planner's way as heuristic.
    pub couple_heuristic: bool,
    /// Coupling 3: the pre-planner's way as desired heading.
    pub couple_heading: bool,
    /// Coupling 2: suggestions whose mid-stance point lies farther than this from the
    /// pre-planner's way are dropped, m.
    pub corridor: Option<f64>,
    /// The weights of the anytime passes (improved mode; the last should be 1).
    pub weights: Vec<f64>,
    /// Lattice cell for duplicate detection: position (m) and yaw (degrees).
    pub lattice: (f64, f64),
    /// A coarser lattice and a weight for a first, scouting pass (improved mode): its plan
    /// comes quickly, without a bound, and prunes the passes after it.
    pub scout: Option<((f64, f64), f64)>,
}

impl Settings {
    /// The defaults for `mode`: desired step 0.3 m, k 1.5, W_θ 0.2 m/rad, 85 suggestions,
    /// tolerance 0.1 m and 0.1 rad, a budget of 400 ms (the thesis's navigation cycle), in
    /// improved mode both couplings with a 0.1 m margin.
    pub fn new(mode: Mode) -> Settings {
        let improved = mode == Mode::Improved;
        Settings {
            robot: Robot::default(),
            desired: (0.3, 0.0, 0.0),
            k: 1.5,
            w_theta: 0.2,
            reduced: false,
            tolerance: (0.1, 0.1),
            horizon: None,
            budget: Duration::from_millis(400),
            cancel: Cancel::default(),
            max_expansions: 1_000_000,
            margin: 0.1,
            heading_margin: 0.25,
            preplanner: if improved {
                PrePlanner::Field
            } else {
                PrePlanner::Thesis
            },
            couple_heuristic: true,
            couple_heading: true,
            corridor: None,
            weights: vec![1.5, 1.2, 1.0],
            lattice: (0.05, 5.0),
            scout: improved.then_some(((0.2, 15.0), 2.0)),
        }
    }
}
