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

/// Archie's gait over a generator with its whole body under the patterns (two passes).
pub fn balanced(kind: Kind) -> Generator {
    generator(kind).with_body(std::sync::Arc::new(archie()), 2)
}

/// The whole body's ZMP under Archie's joint rows, worked out here from the robot file and
/// the rows alone, sharing no code with the gait: each leg's chain built joint by joint (hip
/// yaw about z, roll about x, pitch about y, knee and ankle pitch about y, ankle roll about x;
/// the links as the robot file gives them); the pelvis placed from where the pattern puts the
/// stance sole (the left in double support) and that leg's chain, not from the gait's pelvis;
/// point masses at the pelvis centre, the thighs' and shanks' middles and the ankle roll axes;
/// accelerations by central second differences; p = Σ m (x (z̈ + g) − z ẍ) / Σ m (z̈ + g).
/// Gives each interior row's time, ZMP, and the support polygon's margin (the soles' convex
/// hull, brute force, on the pattern's phase at the row), and checks every foot on the ground
/// lands where the pattern puts it (to 0.1 mm: the chain is right).
pub fn whole_body_zmp(
    plan: &stride_gait::archie::JointPlan,
    pat: &stride_gait::pattern::Pattern,
) -> Vec<(f64, [f64; 2], f64)> {
    use nalgebra::{Rotation3, Vector3};
    use stride_gait::timeline::Phase;
    let r = robot();
    let l = r.links;
    let g = 9.80665;
    let stride = (0.01 / pat.dt).round() as usize;
    let axis = |a: [f64; 3], t: f64| {
        Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(Vector3::from(a)), t)
    };
    let (x, y, z) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
    // One leg in the pelvis frame: its mass points and its sole frame.
    let chain = |side: f64, q: &[f64; 6]| {
        let hip = Vector3::new(0.0, side * l.a6 / 2.0, l.d6);
        let r1 = axis(z, q[0]) * axis(x, q[1]) * axis(y, q[2]);
        let knee = hip + r1 * Vector3::new(0.0, side * l.d3, -l.a3);
        let r2 = r1 * axis(y, q[3]);
        let ankle = knee + r2 * Vector3::new(0.0, 0.0, -l.a2);
        let r3 = r2 * axis(y, q[4]);
        let roll = ankle + r3 * Vector3::new(0.0, 0.0, -l.a1);
        let r4 = r3 * axis(x, q[5]);
        let sole = roll + r4 * Vector3::new(0.0, 0.0, -l.sole);
        ([(hip + knee) / 2.0, (knee + ankle) / 2.0, roll], (r4, sole))
    };
    let m = r.mass;
    let mut bodies = Vec::new();
    for (i, t) in plan.times.iter().enumerate() {
        let s = &pat.samples[i * stride];
        let legs = [
            chain(1.0, &plan.left.positions[i]),
            chain(-1.0, &plan.right.positions[i]),
        ];
        let on: Vec<usize> = match s.phase {
            Phase::Single { swing, .. } => vec![swing.other().index()],
            Phase::Double { .. } => vec![0, 1],
        };
        // Where the pattern puts a sole frame: below the ankle, its centre ahead.
        let sole_at = |k: usize| {
            let [fx, fy, fz, yaw] = s.feet[k][0];
            let b = r.foot.centre_ahead;
            (
                axis(z, yaw),
                Vector3::new(fx - yaw.cos() * b, fy - yaw.sin() * b, fz),
            )
        };
        let (rs, ps) = sole_at(on[0]);
        let (rl, pl) = legs[on[0]].1;
        let rot = rs * rl.inverse();
        let origin = ps - rot * pl;
        let world = |p: Vector3<f64>| origin + rot * p;
        for &k in &on {
            let (_, p) = sole_at(k);
            let d = (world(legs[k].1 .1) - p).norm();
            assert!(d < 1e-4, "row {i}: sole {k} {d} m from the pattern's");
        }
        let mut pts = vec![(m.pelvis, world(Vector3::zeros()))];
        for leg in &legs {
            for (mass, p) in [m.thigh, m.shank, m.foot].into_iter().zip(leg.0) {
                pts.push((mass, world(p)));
            }
        }
        bodies.push((*t, pts, s));
    }
    let (len, wid) = (r.foot.length / 2.0, r.foot.width / 2.0);
    (1..bodies.len().saturating_sub(1))
        .map(|i| {
            let (t0, t1, t2) = (bodies[i - 1].0, bodies[i].0, bodies[i + 1].0);
            let (h1, h2) = (t1 - t0, t2 - t1);
            let (mut nx, mut ny, mut den) = (0.0, 0.0, 0.0);
            for (k, &(mass, p)) in bodies[i].1.iter().enumerate() {
                let (a, b) = (bodies[i - 1].1[k].1, bodies[i + 1].1[k].1);
                let acc = 2.0 * ((b - p) / h2 - (p - a) / h1) / (h1 + h2);
                let w = mass * (acc.z + g);
                nx += p.x * w - mass * p.z * acc.x;
                ny += p.y * w - mass * p.z * acc.y;
                den += w;
            }
            let zmp = [nx / den, ny / den];
            // The soles on the ground at the row and its neighbours (the difference spans them).
            let corners =
                ground_corners(&[bodies[i - 1].2, bodies[i].2, bodies[i + 1].2], [len, wid]);
            (t1, zmp, hull_margin(&corners, zmp))
        })
        .collect()
}

/// The corners of the soles on the ground at any of `samples` (the stance sole in single
/// support, both in double), the soles `half` (length, width) each side of their centres.
pub fn ground_corners(samples: &[&stride_gait::pattern::Sample], half: [f64; 2]) -> Vec<[f64; 2]> {
    use stride_gait::timeline::Phase;
    let [l, w] = half;
    let mut corners = Vec::new();
    for s in samples {
        let on: &[usize] = match s.phase {
            Phase::Single { swing, .. } => &[swing.other().index()][..],
            Phase::Double { .. } => &[0, 1],
        };
        for &f in on {
            let [x, y, _, yaw] = s.feet[f][0];
            let (sn, cs) = yaw.sin_cos();
            for (a, b) in [(l, w), (-l, w), (-l, -w), (l, -w)] {
                corners.push([x + cs * a - sn * b, y + sn * a + cs * b]);
            }
        }
    }
    corners
}

/// A point's distance inside the convex hull of `corners` (negative outside), brute force: an
/// edge is a pair of corners with every other corner on its inner side.
pub fn hull_margin(corners: &[[f64; 2]], p: [f64; 2]) -> f64 {
    let mut margin = f64::INFINITY;
    for &a in corners {
        for &b in corners {
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let len = dx.hypot(dy);
            if len < 1e-9 {
                continue;
            }
            // Inside is on the left of a → b; an edge has no corner on its right.
            let side = |q: [f64; 2]| (dx * (q[1] - a[1]) - dy * (q[0] - a[0])) / len;
            if corners.iter().all(|&q| side(q) >= -1e-9) {
                margin = margin.min(side(p));
            }
        }
    }
    margin
}
