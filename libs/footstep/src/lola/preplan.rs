//! LOLA's 2-D pre-planner (seed 002 §4.3, the notes' section 3.4): a point robot with a safety
//! margin among the obstacles too tall to step over finds several ways to the goal, one per
//! homotopy class, and orders them by an estimate of what their steps will cost (Eq. 4.17).
//!
//! 1. Seeds: parabolas from start to goal, offset sideways (the notes' defaults: the straight
//!    line and offsets of ±0.5, ±1, ±1.5, ±2 m), each of 20 support points.
//! 2. Shift to free space along the offset's normal by the gradient of the potential
//!    φ = Σ ln rⱼ (rⱼ the distance to obstacle j less the margin), by finite differences; a point
//!    inside an obstacle takes the largest shift of its free neighbours.
//! 3. One way per homotopy class (the winding of the way, closed by the straight line back,
//!    around each obstacle), the shortest.
//! 4. An elastic band shortens each.
//! 5. The estimate ĉ = l + Σᵢ (k_base + a₁·|2·l_d − d_free,i| when d_free,i < a₂) over the
//!    small obstacles within d_relevant of the way, d_free,i the free gap after obstacle i.

use crate::geom::{v2, V2};
use crate::ssv::{Footprint, Solid};

/// The pre-planner's parameters (the thesis gives none; the notes' defaults).
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// Sideways offsets of the seeds' apexes, m.
    pub offsets: Vec<f64>,
    /// Support points per seed.
    pub support: usize,
    /// Safety margin of the point robot, m.
    pub margin: f64,
    /// Finite-difference step, m.
    pub eps: f64,
    /// Gain of the shift, m².
    pub c_shift: f64,
    /// Largest shift per iteration, m.
    pub max_shift: f64,
    /// Shift iterations at most.
    pub iterations: usize,
    /// Extra cost of crossing a small obstacle.
    pub k_base: f64,
    /// Weight of an awkward gap.
    pub a1: f64,
    /// Gaps narrower than this are awkward, m.
    pub a2: f64,
    /// The preferred step length, m.
    pub l_d: f64,
    /// Small obstacles within this of the way count, m.
    pub d_relevant: f64,
}

impl Default for Params {
    fn default() -> Self {
        Params {
            offsets: vec![0.0, 0.5, -0.5, 1.0, -1.0, 1.5, -1.5, 2.0, -2.0],
            support: 20,
            margin: 0.25,
            eps: 0.01,
            c_shift: 0.01,
            max_shift: 0.05,
            iterations: 200,
            k_base: 0.3,
            a1: 1.0,
            a2: 0.6,
            l_d: 0.3,
            d_relevant: 0.3,
        }
    }
}

/// A way found.
#[derive(Debug, Clone, PartialEq)]
pub struct Way {
    /// Its points, start to goal.
    pub points: Vec<V2>,
    /// Its length, m.
    pub length: f64,
    /// The estimate of Eq. 4.17.
    pub cost: f64,
    /// Its homotopy class: the winding around each tall obstacle.
    pub class: Vec<i32>,
}

impl Way {
    /// The arc length from the point of the way nearest `p` to the goal, the way's direction
    /// there, and the distance from `p` to the way.
    pub fn project(&self, p: V2) -> (f64, f64, f64) {
        let mut best = (f64::INFINITY, 0.0, 0.0);
        let mut walked = 0.0;
        for w in self.points.windows(2) {
            let (a, b) = (w[0], w[1]);
            let len = a.dist(b);
            let t = if len > 1e-12 {
                ((p - a).dot(b - a) / (len * len)).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let q = a + (b - a) * t;
            let d = p.dist(q);
            if d < best.0 {
                best = (d, self.length - walked - t * len, (b - a).angle());
            }
            walked += len;
        }
        (best.1, best.2, best.0)
    }
}

/// The pre-planner's world: the tall obstacles (kept off by the margin), the small ones (priced
/// by Eq. 4.17) and the map.
pub struct Reduced<'a> {
    /// Obstacles too tall to step over.
    pub tall: &'a [Solid],
    /// Obstacles that can be stepped over.
    pub small: &'a [Solid],
    /// The map's x and y ranges.
    pub map: ([f64; 2], [f64; 2]),
}

/// The tall obstacles' footprints and the map, as the shifting and the checks ask them.
struct Flat {
    tall: Vec<Footprint>,
    map: ([f64; 2], [f64; 2]),
}

impl Flat {
    /// The clearance of `p`: the least distance to a tall obstacle's footprint less the margin
    /// (negative inside), and to the map's border.
    fn clearance(&self, p: V2, margin: f64) -> f64 {
        let border = (p.x - self.map.0[0])
            .min(self.map.0[1] - p.x)
            .min(p.y - self.map.1[0])
            .min(self.map.1[1] - p.y);
        self.tall
            .iter()
            .map(|t| t.distance(p) - margin)
            .fold(border, f64::min)
    }

    fn free(&self, a: V2, b: V2, margin: f64) -> bool {
        let n = (a.dist(b) / 0.03).ceil().max(1.0) as usize;
        (0..=n).all(|i| self.clearance(a + (b - a) * (i as f64 / n as f64), margin) > 0.0)
    }

    fn potential(&self, p: V2, margin: f64) -> f64 {
        self.tall
            .iter()
            .map(|t| (t.distance(p) - margin).max(1e-6).ln())
            .sum()
    }
}

fn length(points: &[V2]) -> f64 {
    points.windows(2).map(|w| w[0].dist(w[1])).sum()
}

/// The winding number of the way closed by the straight line back, around `o`.
fn winding(points: &[V2], o: V2) -> i32 {
    let mut total = 0.0;
    let n = points.len();
    for k in 0..n {
        let (a, b) = (points[k] - o, points[(k + 1) % n] - o);
        total += a.cross(b).atan2(a.dot(b));
    }
    (total / std::f64::consts::TAU).round() as i32
}

/// The ways from `start` to `goal`, cheapest estimate first (empty when none is free).
pub fn preplan(start: V2, goal: V2, reduced: &Reduced, p: &Params) -> Vec<Way> {
    let world = &Flat {
        tall: reduced.tall.iter().map(Solid::footprint).collect(),
        map: reduced.map,
    };
    let d = goal - start;
    let len = d.norm().max(1e-9);
    let n = v2(-d.y / len, d.x / len);
    let m = p.margin;
    let mut found: Vec<Way> = Vec::new();
    for &offset in &p.offsets {
        // A parabola through start and goal with its apex `offset` to the side.
        let mut pts: Vec<V2> = (0..=p.support)
            .map(|k| {
                let t = k as f64 / p.support as f64;
                start + d * t + n * (4.0 * offset * t * (1.0 - t))
            })
            .collect();
        let mut ok = false;
        for it in 0..p.iterations {
            // Freedom costs more to check than a shift: every fifth iteration.
            if it % 5 == 0 && pts.windows(2).all(|w| world.free(w[0], w[1], m)) {
                ok = true;
                break;
            }
            let shifts: Vec<Option<f64>> = pts
                .iter()
                .map(|&q| {
                    (world.clearance(q, m) > 0.0).then(|| {
                        let g = (world.potential(q + n * p.eps, m)
                            - world.potential(q - n * p.eps, m))
                            / (2.0 * p.eps);
                        (p.c_shift * g).clamp(-p.max_shift, p.max_shift)
                    })
                })
                .collect();
            for k in 1..pts.len() - 1 {
                let s = shifts[k].unwrap_or_else(|| {
                    // Inside: the largest shift of its free neighbours (or outwards along
                    // the seed's side).
                    [shifts[k - 1], shifts[k + 1]]
                        .into_iter()
                        .flatten()
                        .max_by(|a, b| a.abs().total_cmp(&b.abs()))
                        .unwrap_or(p.max_shift * if offset < 0.0 { -1.0 } else { 1.0 })
                });
                pts[k] = pts[k] + n * s;
            }
        }
        if !ok {
            continue;
        }
        let pts = elastic_band(pts, world, m);
        let mut closed = pts.clone();
        closed.push(start);
        let class: Vec<i32> = reduced
            .tall
            .iter()
            .map(|t| {
                let bb = t.aabb();
                winding(
                    &closed,
                    v2((bb.mins.x + bb.maxs.x) / 2.0, (bb.mins.y + bb.maxs.y) / 2.0),
                )
            })
            .collect();
        let length = length(&pts);
        match found.iter_mut().find(|w| w.class == class) {
            Some(w) if w.length <= length => {}
            Some(w) => {
                *w = Way {
                    points: pts,
                    length,
                    cost: 0.0,
                    class,
                }
            }
            None => found.push(Way {
                points: pts,
                length,
                cost: 0.0,
                class,
            }),
        }
    }
    for w in &mut found {
        w.cost = estimate(w, reduced, p);
    }
    found.sort_by(|a, b| a.cost.total_cmp(&b.cost));
    found
}

/// Shortens a free way, keeping it free: each point moves halfway towards its neighbours'
/// midpoint while that keeps its segments free; then points in a straight line go.
fn elastic_band(mut pts: Vec<V2>, world: &Flat, m: f64) -> Vec<V2> {
    for _ in 0..40 {
        let mut moved = false;
        for k in 1..pts.len() - 1 {
            let mid = (pts[k - 1] + pts[k + 1]) * 0.5;
            let to = pts[k] + (mid - pts[k]) * 0.5;
            if to.dist(pts[k]) > 1e-4
                && world.free(pts[k - 1], to, m)
                && world.free(to, pts[k + 1], m)
            {
                pts[k] = to;
                moved = true;
            }
        }
        if !moved {
            break;
        }
    }
    let mut out = vec![pts[0]];
    for k in 1..pts.len() - 1 {
        let last = *out.last().expect("one point");
        if !world.free(last, pts[k + 1], m) {
            out.push(pts[k]);
        }
    }
    out.push(pts[pts.len() - 1]);
    out
}

/// Eq. 4.17 for a way.
fn estimate(w: &Way, world: &Reduced, p: &Params) -> f64 {
    // The small obstacles near the way, in the order the way meets them (arc length of the
    // nearest point).
    let mut near: Vec<(f64, f64)> = Vec::new();
    for o in world.small {
        let fp = o.footprint();
        let mut best = (f64::INFINITY, 0.0);
        let mut walked = 0.0;
        for s in w.points.windows(2) {
            let seg = s[0].dist(s[1]);
            let n = (seg / 0.05).ceil().max(1.0) as usize;
            for i in 0..=n {
                let t = i as f64 / n as f64;
                let d = fp.distance(s[0] + (s[1] - s[0]) * t);
                if d < best.0 {
                    best = (d, walked + t * seg);
                }
            }
            walked += seg;
        }
        if best.0 <= p.d_relevant {
            // Its extent along the way: twice its footprint's radius at the nearest point,
            // at least.
            let bb = o.aabb();
            let depth = (bb.maxs.x - bb.mins.x).min(bb.maxs.y - bb.mins.y);
            near.push((best.1, depth));
        }
    }
    near.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut cost = w.length;
    for (i, &(at, depth)) in near.iter().enumerate() {
        cost += p.k_base;
        if let Some(&(next, next_depth)) = near.get(i + 1) {
            let gap = next - at - (depth + next_depth) / 2.0;
            if gap < p.a2 {
                cost += p.a1 * (2.0 * p.l_d - gap).abs();
            }
        }
    }
    cost
}
