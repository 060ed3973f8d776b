//! The ZMP check on the plans of every shipped scene: each scene planned by its improved
//! planner (to an expansion cap, not a time budget, so what is checked is the same on any
//! machine), the plan walked from standing by both generators (preview control, and the foot
//! placement with its default 5 cm limit on moving a footstep), the ZMP kept a centimetre
//! inside the support polygon (step times stretched where needed); Archie's plans also
//! through Archie's legs within their limits, and by preview control with his whole body
//! under the pattern, its ZMP worked out from the joint rows.

mod common;

use stride_gait::pattern::{Kind, Pattern, PatternConfig};

/// The smallest margin of a pattern's cart-table ZMP in its support polygon, worked out here
/// from the samples' COM positions alone, sharing no model with the generator: the COM's
/// acceleration by central finite differences of its positions, the ZMP
/// p = x − (z_c/g)·ẍ, and its distance to the nearest edge of the soles' convex hull, an
/// edge being a pair of corners with every other corner on its inner side (brute force,
/// against the generator's monotone chain). Returns the margin and its time.
///
/// The soles are those on the ground at any of the three samples the difference spans (the
/// stance sole in single support, both in double): the second difference is the mean of
/// the acceleration over that span, weighted by a triangle, so its ZMP is a weighted mean of
/// the ZMPs of the span, each inside the soles on the ground at its instant; at a support
/// exchange between two samples (the foot placement generator's, which has no double
/// support) both soles bear the body at the exchange. No other slack: elsewhere the sole is
/// the stance sole alone.
fn margin_by_hand(p: &Pattern, cfg: &PatternConfig) -> (f64, f64) {
    let k = cfg.z_c / cfg.g;
    let (l, w) = (cfg.sole.length / 2.0, cfg.sole.width / 2.0);
    let mut worst = (f64::INFINITY, 0.0);
    for i in 1..p.samples.len().saturating_sub(1) {
        let (a, s, b) = (&p.samples[i - 1], &p.samples[i], &p.samples[i + 1]);
        let (h0, h1) = (s.t - a.t, b.t - s.t);
        // The second derivative through three samples, their spacing as sampled.
        let acc = |x0: f64, x1: f64, x2: f64| {
            2.0 * (h0 * x2 - (h0 + h1) * x1 + h1 * x0) / (h0 * h1 * (h0 + h1))
        };
        let zmp = [
            s.com.x.x[0] - k * acc(a.com.x.x[0], s.com.x.x[0], b.com.x.x[0]),
            s.com.y.x[0] - k * acc(a.com.y.x[0], s.com.y.x[0], b.com.y.x[0]),
        ];
        let corners = common::ground_corners(&[a, s, b], [l, w]);
        let margin = common::hull_margin(&corners, zmp);
        if margin < worst.0 {
            worst = (margin, s.t);
        }
    }
    worst
}

#[test]
fn every_shipped_scenes_plan_keeps_its_zmp_inside() {
    let walks = common::scene_walks();
    let archie = common::archie();
    let mut rows = Vec::new();
    for kind in [Kind::Preview, Kind::FootPlacement] {
        let plain = common::generator(kind);
        let balanced = common::balanced(kind);
        for walk in &walks {
            let Ok(w) = walk else { continue };
            // Archie's walks by preview control carry his whole body: the ZMP checked is the
            // whole body's under the joint rows; the others' the cart-table ZMP of the COM.
            let whole = w.archie && kind == Kind::Preview;
            let g = if whole { &balanced } else { &plain };
            let start = g.standing(0.0, w.feet.0, w.feet.1);
            let pat = g
                .plan(&start, &w.steps)
                .unwrap_or_else(|e| panic!("{kind:?}, {}: {e}", w.name));
            let (m, t) = pat.min_margin();
            assert!(m >= 0.01, "{kind:?}, {}: margin {m} at {t}", w.name);
            let plan = w.archie.then(|| {
                archie
                    .joints(&pat)
                    .unwrap_or_else(|e| panic!("{kind:?}, {}: {e}", w.name))
            });
            let (by_hand, at) = match &plan {
                Some(plan) if whole => common::whole_body_zmp(plan, &pat)
                    .into_iter()
                    .map(|(t, _, m)| (m, t))
                    .fold((f64::INFINITY, 0.0), |a, b| if b.0 < a.0 { b } else { a }),
                _ => margin_by_hand(&pat, g.config()),
            };
            assert!(
                by_hand >= 0.01,
                "{kind:?}, {}: margin {by_hand} at {at} from the {} ({m} by the generator's own \
                 state)",
                w.name,
                if whole {
                    "joint rows"
                } else {
                    "COM's positions"
                }
            );
            let stretched = common::stretched(g, &pat, &w.steps);
            let joints = match (&plan, whole) {
                (Some(_), true) => "joints within limits, the whole body's ZMP",
                (Some(_), false) => "joints within limits, the cart-table ZMP",
                (None, _) => "ZMP only (not Archie's plan)",
            };
            rows.push(format!(
                "{kind:?}, {}: {} steps, {:.1} s, smallest margin {by_hand:.4} m ({m:.4} m by \
                 the generator), {stretched} stretched, {joints}",
                w.name,
                w.steps.len(),
                pat.timeline.end - pat.timeline.start
            ));
        }
    }
    eprintln!("{}", rows.join("\n"));
    // Every scene plans but the one built to be refused: a scene that stops planning fails.
    let refused: Vec<String> = walks
        .iter()
        .filter_map(|w| w.as_ref().err())
        .map(|(name, why)| format!("{name}: {why}"))
        .collect();
    assert_eq!(
        refused,
        ["kaist-b9: goal outside map"],
        "scenes that did not plan"
    );
    assert_eq!(rows.len(), 2 * (walks.len() - 1), "{}", rows.len());
    assert!(walks.len() >= 36, "{} scenes", walks.len());
}
