//! The notes' R-H3 and R-H4: is the improved heuristic a lower bound of the exact cost, and
//! how often is the thesis's not?
//!
//! On flat ground with no obstacle, a uniform-cost search from a state over every action (the
//! full set, so its costs are at most those of any adaptive choice) with the planner's lattice
//! duplicate detection (0.05 m, 5°, side) gives the exact cost of reaching every goal disc
//! whose cost is within its horizon. For random states (a stance foot and the foot it was
//! placed from) and random goals on a 4 m × 4 m map, the improved heuristic must never exceed
//! that cost; the thesis's (Eq. 14 with α the least energy per metre) is measured.

use std::collections::{BinaryHeap, HashMap};

use proptest::prelude::Rng;
use proptest::test_runner::{TestRng, TestRunner};
use stride_footstep::geom::{v2, wrap, V2};
use stride_footstep::kaist::search::apply;
use stride_footstep::kaist::{self, CostParams};
use stride_footstep::plan::{Foot, Least};

const TOLERANCE: f64 = 0.10;
/// The horizon of each search, in units of m·g (about seven steps).
const HORIZON: f64 = 36.0;

/// Every state reached within the horizon: (stance, other, cost).
fn uniform_cost(p: &CostParams, stance: Foot, other: Foot) -> Vec<(Foot, Foot, f64)> {
    let acts = kaist::actions(p);
    let key = |f: &Foot| {
        (
            (f.p.x / 0.05).round() as i64,
            (f.p.y / 0.05).round() as i64,
            (wrap(f.yaw) / 5f64.to_radians()).round() as i64,
            f.left,
        )
    };
    let mut nodes = vec![(stance, other, 0.0)];
    let mut best: HashMap<_, f64> = HashMap::from([(key(&stance), 0.0)]);
    let mut closed = Vec::new();
    let mut heap = BinaryHeap::from([Least(0.0, 0)]);
    let mut done = std::collections::HashSet::new();
    while let Some(Least(g, i)) = heap.pop() {
        let (s, o, _) = nodes[i];
        if g > HORIZON || !done.insert(key(&s)) {
            continue;
        }
        closed.push((s, o, g));
        for a in &acts {
            let f = apply(&s, a);
            let c = g + a.energy_mg(p);
            let k = key(&f);
            if c <= HORIZON && best.get(&k).is_none_or(|&b| c < b) {
                best.insert(k, c);
                nodes.push((f, s, c));
                heap.push(Least(c, nodes.len() - 1));
            }
        }
    }
    closed
}

/// The exact cost of bringing the centre within the tolerance of `goal`, if within the
/// horizon.
fn exact(closed: &[(Foot, Foot, f64)], goal: V2) -> Option<f64> {
    closed
        .iter()
        .filter(|(s, o, _)| ((s.p + o.p) * 0.5).dist(goal) < TOLERANCE)
        .map(|n| n.2)
        .fold(None, |a: Option<f64>, c| Some(a.map_or(c, |a| a.min(c))))
}

#[test]
fn r_h3_improved_heuristic_never_exceeds_the_exact_cost() {
    let p = CostParams::kaist_sim();
    let acts = kaist::actions(&p);
    let alpha = kaist::alpha(&p, &acts);
    // A fixed seed: the same 1080 pairs every run.
    let mut rng: TestRng = TestRunner::deterministic().rng().clone();
    let (mut checked, mut violations, mut thesis_over, mut thesis_worst) = (0, 0, 0, 0.0f64);
    let (mut ratio_sum, mut consistency) = (0.0, 0);
    let states = 12;
    for _ in 0..states {
        // A random state: the stance foot placed from the other by a random action.
        let yaw = rng.next_u32() as f64 / u32::MAX as f64 * std::f64::consts::TAU;
        let a = acts[(rng.next_u32() as usize) % acts.len()];
        let other = Foot {
            p: v2(0.0, 0.0),
            z: 0.0,
            yaw,
            left: rng.next_u32().is_multiple_of(2),
        };
        let stance = apply(&other, &a);
        let closed = uniform_cost(&p, stance, other);
        let centre = (stance.p + other.p) * 0.5;
        let heading = stance.yaw + wrap(other.yaw - stance.yaw) / 2.0;
        let mut goals = 0;
        while goals < 90 {
            // A goal on the 4 m x 4 m map around the state.
            let g = centre
                + v2(
                    (rng.next_u32() as f64 / u32::MAX as f64) * 4.0 - 2.0,
                    (rng.next_u32() as f64 / u32::MAX as f64) * 4.0 - 2.0,
                );
            let Some(c) = exact(&closed, g) else {
                continue;
            };
            goals += 1;
            checked += 1;
            let h = kaist::h_improved(
                &p,
                stance.p.dist(g),
                (g - stance.p).angle(),
                stance.yaw,
                centre.dist(g),
                TOLERANCE,
            );
            if h > c + 1e-9 {
                violations += 1;
                eprintln!("violation: h {h:.4} > c* {c:.4} for {stance:?} {other:?} -> {g:?}");
            }
            if c > 0.0 {
                ratio_sum += h / c;
            }
            let d = centre.dist(g);
            let ht = kaist::h_thesis(&p, alpha, d, heading, (g - centre).angle());
            if ht > c + 1e-9 {
                thesis_over += 1;
                if c > 0.0 {
                    thesis_worst = thesis_worst.max(ht / c);
                }
            }
            // R-H4 on the first step: h(s) <= c(s, s') + h(s') for every action.
            for a in &acts {
                let f = apply(&stance, a);
                let mid = (f.p + stance.p) * 0.5;
                let h2 = kaist::h_improved(
                    &p,
                    f.p.dist(g),
                    (g - f.p).angle(),
                    f.yaw,
                    mid.dist(g),
                    TOLERANCE,
                );
                if h > a.energy_mg(&p) + h2 + 1e-9 {
                    consistency += 1;
                }
            }
        }
    }
    eprintln!(
        "R-H3: {checked} (state, goal) pairs: improved heuristic over the exact cost {violations} \
         times, on average {:.3} of it; the thesis's over it {thesis_over} times ({:.1} %), \
         worst {:.3} (where the exact cost is not 0). R-H4: {consistency} inconsistent edges of {}.",
        ratio_sum / checked as f64,
        100.0 * thesis_over as f64 / checked as f64,
        thesis_worst,
        checked * acts.len()
    );
    assert!(checked >= 1000, "{checked}");
    assert_eq!(violations, 0);
}
