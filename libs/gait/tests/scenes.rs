//! The ZMP check on the plans of every shipped scene: each scene planned by its improved
//! planner, the plan walked by the preview controller from standing, the ZMP kept a
//! centimetre inside the support polygon (step times stretched where needed); Archie's plans
//! also through Archie's legs within their limits.

mod common;

use std::path::PathBuf;
use std::time::Duration;

use stride_footstep::plan::{Foot, Status};
use stride_footstep::planner::{for_scene, plan, scene_request, Which};
use stride_footstep::scene::Scene;
use stride_gait::pattern::Kind;
use stride_gait::timeline::{Footstep, Side};

fn place(f: &Foot) -> [f64; 4] {
    [f.p.x, f.p.y, f.z, f.yaw]
}

#[test]
fn every_shipped_scenes_plan_keeps_its_zmp_inside() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/scenes");
    let g = common::generator(Kind::Preview);
    let archie = common::archie();
    let mut rows = Vec::new();
    for dir in ["archie", "kaist", "lola"] {
        let mut files: Vec<PathBuf> = std::fs::read_dir(root.join(dir))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "toml"))
            .collect();
        files.sort();
        for f in files {
            let scene = Scene::load(&f).unwrap();
            let which = for_scene(&scene);
            // Archie's planner makes steps no longer than the gait takes.
            let mut req = scene_request(&scene, false);
            if which == Which::Archie {
                req.max_step = Some(0.25);
            }
            let p = plan(&req, &scene, Duration::from_millis(300));
            if !matches!(p.status, Status::Ok | Status::Partial) || p.steps.len() < 3 {
                rows.push(format!(
                    "{}: {} (no steps to walk)",
                    scene.name,
                    p.status.name()
                ));
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
            let steps: Vec<Footstep> = p.steps[n..]
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
            let start = g.standing(0.0, place(&left), place(&right));
            let pat = g
                .plan(&start, &steps)
                .unwrap_or_else(|e| panic!("{}: {e}", scene.name));
            let (m, t) = pat.min_margin();
            assert!(m >= 0.01, "{}: margin {m} at {t}", scene.name);
            let stretched = pat
                .timeline
                .steps
                .iter()
                .zip(&steps)
                .skip(1) // the first's double support is the start's shift
                .filter(|(s, f)| {
                    let travel = (f.place[0] - s.from[0]).hypot(f.place[1] - s.from[1]);
                    s.land - s.start > g.config().timing.step_time(travel) + 1e-9
                })
                .count();
            let joints = if which == Which::Archie {
                match archie.joints(&pat) {
                    Ok(_) => "joints within limits".to_string(),
                    Err(e) => panic!("{}: {e}", scene.name),
                }
            } else {
                "ZMP only (not Archie's plan)".to_string()
            };
            rows.push(format!(
                "{}: {} steps, {:.1} s, smallest margin {m:.4} m, {stretched} stretched, {joints}",
                scene.name,
                steps.len(),
                pat.timeline.end - pat.timeline.start
            ));
        }
    }
    eprintln!("{}", rows.join("\n"));
    assert!(rows.len() >= 35, "{}", rows.len());
}
