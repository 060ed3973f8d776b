//! The ZMP check on the plans of every shipped scene: each scene planned by its improved
//! planner, the plan walked from standing by both generators (preview control, and the foot
//! placement with its default 5 cm limit on moving a footstep), the ZMP kept a centimetre
//! inside the support polygon (step times stretched where needed); Archie's plans also
//! through Archie's legs within their limits.

mod common;

use stride_gait::pattern::Kind;

#[test]
fn every_shipped_scenes_plan_keeps_its_zmp_inside() {
    let walks = common::scene_walks();
    let archie = common::archie();
    let mut rows = Vec::new();
    for kind in [Kind::Preview, Kind::FootPlacement] {
        let g = common::generator(kind);
        for walk in &walks {
            let w = match walk {
                Ok(w) => w,
                Err((name, why)) => {
                    rows.push(format!("{name}: {why} (no steps to walk)"));
                    continue;
                }
            };
            let start = g.standing(0.0, w.feet.0, w.feet.1);
            let pat = g
                .plan(&start, &w.steps)
                .unwrap_or_else(|e| panic!("{kind:?}, {}: {e}", w.name));
            let (m, t) = pat.min_margin();
            assert!(m >= 0.01, "{kind:?}, {}: margin {m} at {t}", w.name);
            let stretched = common::stretched(&g, &pat, &w.steps);
            let joints = if w.archie {
                match archie.joints(&pat) {
                    Ok(_) => "joints within limits".to_string(),
                    Err(e) => panic!("{kind:?}, {}: {e}", w.name),
                }
            } else {
                "ZMP only (not Archie's plan)".to_string()
            };
            rows.push(format!(
                "{kind:?}, {}: {} steps, {:.1} s, smallest margin {m:.4} m, {stretched} \
                 stretched, {joints}",
                w.name,
                w.steps.len(),
                pat.timeline.end - pat.timeline.start
            ));
        }
    }
    eprintln!("{}", rows.join("\n"));
    assert!(rows.len() >= 70, "{}", rows.len());
}
