//! What the gait's tests share: Archie's robot file, the pattern's default parameters and
//! straight walks.

#![allow(dead_code)]

use std::path::Path;

use stride_gait::archie::{ArchieGait, HeightConfig};
use stride_gait::pattern::{Generator, Kind, PatternConfig, PlacementConfig};
use stride_gait::preview::PreviewConfig;
use stride_gait::support::Sole;
use stride_gait::swing::{Place, SwingConfig};
use stride_gait::timeline::{Footstep, Side, TimingConfig};
use stride_kinematics::archie::ArchieConfig;

/// Archie's sole centre is 8 cm ahead of its ankle: the ZMP reference 3 cm ahead of the
/// ankle keeps 6 cm of sole behind it and the shanks more upright.
pub const ZMP_AHEAD: f64 = -0.05;

pub fn robot() -> ArchieConfig {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/robots/archie.toml");
    ArchieConfig::load(&path).unwrap()
}

pub fn z_c() -> f64 {
    archie().z_c
}

pub fn config(kind: Kind) -> PatternConfig {
    let r = robot();
    PatternConfig {
        generator: kind,
        z_c: z_c(),
        g: 9.80665,
        preview: PreviewConfig::default(),
        placement: PlacementConfig::default(),
        swing: SwingConfig::default(),
        // Archie's sole centre is 8 cm ahead of its ankle: the ZMP reference 3 cm ahead of
        // the ankle keeps 6 cm of sole behind it and the shanks more upright.
        timing: TimingConfig {
            zmp_ahead: ZMP_AHEAD,
            ..TimingConfig::default()
        },
        sole: Sole {
            length: r.foot.length,
            width: r.foot.width,
        },
        min_margin: 0.01,
    }
}

pub fn generator(kind: Kind) -> Generator {
    Generator::new(config(kind)).unwrap()
}

/// Archie's gait: the whole robot's COM on the pattern, rows every 10 ms.
pub fn archie() -> ArchieGait {
    ArchieGait::new(robot(), &HeightConfig::default(), ZMP_AHEAD, 0.01, true).unwrap()
}

/// The feet standing at x = 0, 0.2 m apart: left, right.
pub fn standing() -> (Place, Place) {
    ([0.0, 0.1, 0.0, 0.0], [0.0, -0.1, 0.0, 0.0])
}

/// `n` steps straight ahead, the left foot first, numbered from `first`: each lands
/// `length` ahead of the support foot, the last beside it.
pub fn straight(n: usize, length: f64, first: i64) -> Vec<Footstep> {
    let mut x = [0.0, 0.0];
    (0..n)
        .map(|i| {
            let side = if i % 2 == 0 { Side::Left } else { Side::Right };
            let k = side.index();
            x[k] = if i + 1 == n {
                x[1 - k]
            } else {
                x[1 - k] + length
            };
            let y = if side == Side::Left { 0.1 } else { -0.1 };
            Footstep {
                number: first + i as i64,
                side,
                place: [x[k], y, 0.0, 0.0],
                swing_height: 0.0,
                duration: 0.0,
                padding: false,
            }
        })
        .collect()
}

/// A shipped scene's plan, as the gait walks it from standing.
pub struct SceneWalk {
    /// The scene's name.
    pub name: String,
    /// Planned by Archie's planner (with steps no longer than the gait takes).
    pub archie: bool,
    /// Where the feet stand: left, right.
    pub feet: (Place, Place),
    /// The plan's steps, numbered from 1.
    pub steps: Vec<Footstep>,
}

/// The expansions each scene's search may make.
pub const SCENE_EXPANSIONS: u64 = 60_000;

/// Every shipped scene (config/scenes/{archie,kaist,lola}) planned by its improved planner:
/// the walk, or the scene's name and why there is none.
pub fn scene_walks() -> Vec<Result<SceneWalk, (String, String)>> {
    use stride_footstep::plan::{Foot, Status};
    use stride_footstep::planner::{for_scene, plan_within, scene_request, Limits, Which};
    use stride_footstep::scene::Scene;
    let place = |f: &Foot| [f.p.x, f.p.y, f.z, f.yaw];
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/scenes");
    let mut out = Vec::new();
    for dir in ["archie", "kaist", "lola"] {
        let mut files: Vec<std::path::PathBuf> = std::fs::read_dir(root.join(dir))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "toml"))
            .collect();
        files.sort();
        for f in files {
            let scene = Scene::load(&f).unwrap();
            let which = for_scene(&scene);
            let mut req = scene_request(&scene, false);
            if which == Which::Archie {
                req.max_step = Some(0.25);
            }
            // An expansion cap, not a time budget: the same plans on any machine, loaded or
            // not (the cap is several times what the slowest scene's first plan takes).
            req.max_expansions = Some(SCENE_EXPANSIONS);
            let limits = Limits {
                max_budget: std::time::Duration::from_secs(3600),
                ..Limits::default()
            };
            let p = plan_within(
                &req,
                &scene,
                limits.max_budget,
                &limits,
                &stride_footstep::plan::Cancel::new(),
            );
            if !matches!(p.status, Status::Ok | Status::Partial) || p.steps.len() < 3 {
                out.push(Err((scene.name.clone(), p.status.name().to_string())));
                continue;
            }
            // The feet where they stand: the plan lists them first (Archie's planner the
            // standing foot only; the other beside it at the planner's stance).
            let n = which.standing();
            let (mut left, mut right) = Foot::standing(scene.start.p(), scene.start.yaw, 0.2);
            for f in &p.steps[..n] {
                if f.left {
                    left = *f;
                } else {
                    right = *f;
                }
            }
            let steps = p.steps[n..]
                .iter()
                .enumerate()
                .map(|(i, f)| Footstep {
                    number: i as i64 + 1,
                    side: if f.left { Side::Left } else { Side::Right },
                    place: place(f),
                    swing_height: 0.0,
                    duration: 0.0,
                    padding: false,
                })
                .collect();
            out.push(Ok(SceneWalk {
                name: scene.name.clone(),
                archie: which == Which::Archie,
                feet: (place(&left), place(&right)),
                steps,
            }));
        }
    }
    out
}

/// How many of a pattern's steps (the first's aside: its double support is the start's
/// shift) were given more time than the timing rule's to keep the ZMP inside.
pub fn stretched(g: &Generator, pat: &stride_gait::pattern::Pattern, steps: &[Footstep]) -> usize {
    pat.timeline
        .steps
        .iter()
        .zip(steps)
        .skip(1)
        .filter(|(s, f)| {
            let travel = (f.place[0] - s.from[0]).hypot(f.place[1] - s.from[1]);
            s.land - s.start > g.config().timing.step_time(travel) + 1e-9
        })
        .count()
}
