//! Archie's optimum against a reference that shares no code with the planner: the shortest
//! path among polygons inscribed in the grown circles is a lower bound, among polygons
//! circumscribed about them an upper bound (a visibility graph and Dijkstra, written here).

use std::path::PathBuf;

use proptest::prelude::*;
use stride_footstep::archie::{exact_length, Params};
use stride_footstep::geom::{v2, Circle};
use stride_footstep::scene::Scene;

type P = (f64, f64);

/// The regular `n`-gon inscribed in (`scale` = 1) or circumscribed about (`scale` =
/// 1/cos(π/n)) a circle, counter-clockwise.
fn polygon(c: P, r: f64, n: usize, scale: f64) -> Vec<P> {
    (0..n)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / n as f64;
            (c.0 + r * scale * a.cos(), c.1 + r * scale * a.sin())
        })
        .collect()
}

/// True when the segment a-b has a stretch of positive length strictly inside the convex,
/// counter-clockwise polygon (clipped against each side's half-plane).
fn enters(a: P, b: P, poly: &[P]) -> bool {
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    for k in 0..poly.len() {
        let (p, q) = (poly[k], poly[(k + 1) % poly.len()]);
        // Inside: to the left of p->q by more than a hair.
        let e = (q.0 - p.0, q.1 - p.1);
        let len = (e.0 * e.0 + e.1 * e.1).sqrt();
        let side = |x: P| (e.0 * (x.1 - p.1) - e.1 * (x.0 - p.0)) / len - 1e-9;
        let (sa, sd) = (side(a), side(b) - side(a));
        if sd.abs() < 1e-15 {
            if sa <= 0.0 {
                return false;
            }
            continue;
        }
        let t = -sa / sd;
        if sd > 0.0 {
            lo = lo.max(t);
        } else {
            hi = hi.min(t);
        }
        if hi - lo <= 1e-12 {
            return false;
        }
    }
    hi - lo > 1e-12
}

/// The shortest path from `s` to `g` among the polygons, or `None`.
fn shortest(s: P, g: P, polys: &[Vec<P>]) -> Option<f64> {
    let inside = |x: P| polys.iter().any(|p| point_inside(x, p));
    let mut nodes = vec![s, g];
    for p in polys {
        nodes.extend(p.iter().copied().filter(|&v| !inside(v)));
    }
    let n = nodes.len();
    let free = |i: usize, j: usize| !polys.iter().any(|p| enters(nodes[i], nodes[j], p));
    let dist = |i: usize, j: usize| {
        ((nodes[i].0 - nodes[j].0).powi(2) + (nodes[i].1 - nodes[j].1).powi(2)).sqrt()
    };
    let mut best = vec![f64::INFINITY; n];
    let mut done = vec![false; n];
    best[0] = 0.0;
    for _ in 0..n {
        let u = (0..n)
            .filter(|&k| !done[k])
            .min_by(|&a, &b| best[a].total_cmp(&best[b]))?;
        if !best[u].is_finite() {
            return None;
        }
        if u == 1 {
            return Some(best[1]);
        }
        done[u] = true;
        for v in 0..n {
            if !done[v] && best[u] + dist(u, v) < best[v] && free(u, v) {
                best[v] = best[u] + dist(u, v);
            }
        }
    }
    None
}

fn point_inside(x: P, poly: &[P]) -> bool {
    (0..poly.len()).all(|k| {
        let (p, q) = (poly[k], poly[(k + 1) % poly.len()]);
        (q.0 - p.0) * (x.1 - p.1) - (q.1 - p.1) * (x.0 - p.0) > 1e-9
    })
}

const SIDES: usize = 24;

/// (lower, upper) bounds of the optimum among `circles` grown by `p.inflation`.
fn bounds(s: P, g: P, circles: &[Circle], p: &Params) -> (Option<f64>, Option<f64>) {
    let grown: Vec<(P, f64)> = circles
        .iter()
        .map(|c| ((c.c.x, c.c.y), c.r + p.inflation))
        .collect();
    let inscribed: Vec<Vec<P>> = grown
        .iter()
        .map(|&(c, r)| polygon(c, r, SIDES, 1.0))
        .collect();
    let out = 1.0 / (std::f64::consts::PI / SIDES as f64).cos();
    let circumscribed: Vec<Vec<P>> = grown
        .iter()
        .map(|&(c, r)| polygon(c, r, SIDES, out))
        .collect();
    (shortest(s, g, &inscribed), shortest(s, g, &circumscribed))
}

fn check(s: P, g: P, circles: &[Circle], p: &Params) -> Result<(), String> {
    let opt = exact_length(v2(s.0, s.1), v2(g.0, g.1), circles, p);
    let (lo, hi) = bounds(s, g, circles, p);
    match (lo, opt, hi) {
        // Blocked among the inscribed polygons: blocked among the circles too.
        (None, o, _) => o.map_or(Ok(()), |o| Err(format!("optimum {o} where no way exists"))),
        (Some(lo), None, hi) => match hi {
            Some(hi) => Err(format!(
                "no optimum, but a way of {hi} round the circumscribed"
            )),
            // Blocked round the circles and the circumscribed polygons, open only between the
            // inscribed ones: a gap narrower than the polygons' difference ({lo} m).
            None => {
                let _ = lo;
                Ok(())
            }
        },
        (Some(lo), Some(o), hi) => {
            if o < lo - 1e-9 {
                return Err(format!("optimum {o} below the lower bound {lo}"));
            }
            if let Some(hi) = hi {
                if o > hi + 1e-9 {
                    return Err(format!("optimum {o} above the upper bound {hi}"));
                }
            }
            Ok(())
        }
    }
}

#[test]
fn every_shipped_scenes_optimum_lies_between_the_polygon_bounds() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/scenes/archie");
    let mut n = 0;
    for e in std::fs::read_dir(dir).unwrap() {
        let path = e.unwrap().path();
        if path.extension().is_none_or(|x| x != "toml") {
            continue;
        }
        let scene = Scene::load(&path).unwrap();
        for p in [Params::default(), Params::improved()] {
            let (s, g) = (scene.start.p(), scene.goal.p());
            check((s.x, s.y), (g.x, g.y), &scene.circles(), &p)
                .unwrap_or_else(|e| panic!("{}: {e}", scene.name));
            // The bounds are not vacuous: both exist and lie within 2 % of each other.
            let (lo, hi) = bounds((s.x, s.y), (g.x, g.y), &scene.circles(), &p);
            let (lo, hi) = (lo.unwrap(), hi.unwrap());
            assert!(hi <= lo * 1.02, "{}: {lo} to {hi}", scene.name);
            n += 1;
        }
    }
    assert!(n >= 22, "{n}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// Random fields, walls of overlapping circles across the way, and goals walled in.
    #[test]
    fn the_optimum_lies_between_the_polygon_bounds(
        cs in prop::collection::vec((0.5f64..4.5, -2.0f64..2.0, 0.2f64..0.7), 0..7),
        wall in prop::option::of((1.0f64..4.0, 0.2f64..0.5, 3usize..9)),
        ring in any::<bool>(),
        improved in any::<bool>(),
    ) {
        let p = if improved { Params::improved() } else { Params::default() };
        let mut circles: Vec<Circle> = cs.iter().map(|&(x, y, r)| Circle { c: v2(x, y), r }).collect();
        if let Some((x, r, k)) = wall {
            let half = k as f64 * r / 2.0;
            circles.extend((0..k).map(|i| Circle { c: v2(x, -half + i as f64 * r), r }));
        }
        let goal = (5.0, 0.0);
        if ring {
            circles.extend((0..12).map(|i| {
                let a = std::f64::consts::TAU * i as f64 / 12.0;
                Circle { c: v2(goal.0 + 0.9 * a.cos(), goal.1 + 0.9 * a.sin()), r: 0.25 }
            }));
        }
        let grown: Vec<Circle> = circles.iter().map(|c| Circle { c: c.c, r: c.r + p.inflation }).collect();
        prop_assume!(!grown.iter().any(|c| c.c.dist(v2(0.0, 0.0)) <= c.r + 1e-6 || c.c.dist(v2(goal.0, goal.1)) <= c.r + 1e-6));
        check((0.0, 0.0), goal, &circles, &p).map_err(TestCaseError::fail)?;
    }
}
