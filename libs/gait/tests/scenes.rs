//! The ZMP check on the plans of every shipped scene: each scene planned by its improved
//! planner, the plan walked from standing by both generators (preview control, and the foot
//! placement with its default 5 cm limit on moving a footstep), the ZMP kept a centimetre
//! inside the support polygon (step times stretched where needed); Archie's plans also
//! through Archie's legs within their limits.

mod common;

use stride_gait::pattern::{Kind, Pattern, PatternConfig};
use stride_gait::timeline::Phase;

/// The smallest margin of a pattern's cart-table ZMP in its support polygon, worked out here
/// from the samples alone, sharing no code with the generator's own check: the ZMP
/// p = x − (z_c/g)·ẍ from each sample's COM, the soles' corners from the feet on the ground
/// (the stance sole in single support, both in double), and the distance to the nearest edge
/// of their convex hull, an edge being a pair of corners with every other corner on its
/// inner side (brute force, against the generator's monotone chain).
fn margin_by_hand(p: &Pattern, cfg: &PatternConfig) -> f64 {
    let k = cfg.z_c / cfg.g;
    let (l, w) = (cfg.sole.length / 2.0, cfg.sole.width / 2.0);
    let mut worst = f64::INFINITY;
    for s in &p.samples {
        let zmp = [
            s.com.x.x[0] - k * s.com.x.x[2],
            s.com.y.x[0] - k * s.com.y.x[2],
        ];
        let on: Vec<usize> = match s.phase {
            Phase::Single { swing, .. } => vec![swing.other().index()],
            Phase::Double { .. } => vec![0, 1],
        };
        let mut corners = Vec::new();
        for f in on {
            let [x, y, _, yaw] = s.feet[f][0];
            let (sn, cs) = yaw.sin_cos();
            for (a, b) in [(l, w), (-l, w), (-l, -w), (l, -w)] {
                corners.push([x + cs * a - sn * b, y + sn * a + cs * b]);
            }
        }
        let mut margin = f64::INFINITY;
        for i in 0..corners.len() {
            for j in 0..corners.len() {
                let (a, b) = (corners[i], corners[j]);
                let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
                let len = dx.hypot(dy);
                if len < 1e-9 {
                    continue;
                }
                // Inside is on the left of a → b; an edge has no corner on its right.
                let side = |q: [f64; 2]| (dx * (q[1] - a[1]) - dy * (q[0] - a[0])) / len;
                if corners.iter().all(|&q| side(q) >= -1e-9) {
                    margin = margin.min(side(zmp));
                }
            }
        }
        worst = worst.min(margin);
    }
    worst
}

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
            let by_hand = margin_by_hand(&pat, g.config());
            assert!(
                by_hand >= 0.01 && (by_hand - m).abs() < 1e-6,
                "{kind:?}, {}: margin {m} by the generator, {by_hand} worked out here",
                w.name
            );
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
