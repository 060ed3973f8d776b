//! Archie's path planner (seed 000, §2.6): obstacles are circles grown by half the hip width,
//! and the path runs along their tangents.
//!
//! - [`plan_tree`], faithful: the thesis's binary tree. From each open leaf, the nearest
//!   obstacle blocking the way to the goal gives two children, the intersections of the
//!   leaf's tangents with the goal's tangents on each side; children inside an obstacle are
//!   dropped; the search ends at the first level where a leaf sees the goal. Its known defect
//!   stays: a waypoint is where two tangents meet, which overshoots when they are nearly
//!   parallel (the case-9 detour). Where the thesis is silent, it drops a child the leaf
//!   cannot reach without entering another obstacle.
//!
//!   What the tree cannot do, as the thesis's algorithm (§2.6.4) cannot either: it looks at
//!   one circle at a time, so a wall of overlapping circles across the way to the goal (the
//!   centres (2, −0.5), (2, 0), (2, 0.5), radius 0.3 to 0.5 m, from the origin to (4, 0))
//!   puts every child inside a neighbouring circle; step 2.4 deletes them all and the search
//!   ends with no path, where the exact planner goes round in 4.40 to 4.59 m. The thesis's
//!   own walls (cases 4 to 11) run along the way, not across it, so its tests never met this.
//!   Its overshoot is not bounded either: beside the documented case-9 detour of about
//!   0.5 m, a field of six random circles (the test
//!   `the_faithful_trees_failures_are_as_documented`) gives 795.4 m against an optimum of
//!   5.08 m, a waypoint far out where two tangents meet almost parallel.
//! - [`plan_exact`], improved: the exact shortest path among the same circles, on the tangent
//!   graph (tangents from start and goal, bitangents between circles, arcs along them), by
//!   Dijkstra; arcs become waypoints on a polygon circumscribed about the circle, so the path
//!   never enters it and is at most a fraction of a percent longer than the exact optimum
//!   (its sides are refined where the polygon would cut into another circle the arc passes
//!   near). An obstacle reported twice, or inside another, counts once ([`distinct`]); two
//!   circles that touch leave no way between them.

pub mod steps;

use std::collections::BinaryHeap;
use std::time::{Duration, Instant};

use crate::geom::{line_intersection, point_segment_distance, v2, wrap, Circle, EPS, V2};
use crate::plan::{Least, Plan, Stats, Status};

/// Settings of Archie's planner.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Params {
    /// Added to every obstacle's radius: half the hip width, m.
    pub inflation: f64,
    /// The tree's depth limit (faithful mode).
    pub max_depth: u32,
    /// Wall-time budget.
    pub budget: Duration,
    /// Largest angle of circle a waypoint of an arc covers (improved mode), rad.
    pub arc_step: f64,
    /// How far inside one inflated obstacle a start may lie and still be planned from
    /// (improved mode), m: that obstacle's margin is narrowed to the start for the plan, and
    /// grows back along the way. A walking robot's feet drift a few millimetres into the
    /// margin that a path hugging it left them at; refused, it would step in place there.
    pub start_slack: f64,
}

impl Default for Params {
    /// The thesis's settings: obstacles grown by 0.1 m, half the hip width.
    fn default() -> Self {
        Params {
            inflation: 0.1,
            max_depth: 16,
            budget: Duration::from_millis(100),
            arc_step: 10f64.to_radians(),
            start_slack: 0.0,
        }
    }
}

impl Params {
    /// Improved settings: obstacles grown by the farthest reach of a footprint from the path
    /// (a foot's box corner lies 0.15 m to the side, half the stance and half the foot's
    /// width, and up to 0.15 m ahead, its centre's offset and half its length: 0.212 m in
    /// all), so that no footprint along a path outside the grown obstacles touches one. With
    /// the thesis's 0.1 m, the outer half of a foot beside an obstacle lies on it.
    pub fn improved() -> Params {
        Params {
            inflation: 0.215,
            start_slack: 0.05,
            ..Params::default()
        }
    }
}

/// One node of the faithful tree.
#[derive(Debug, Clone)]
struct Node {
    p: V2,
    parent: Option<usize>,
    level: u32,
    /// The thesis's id: `x_i = x_{i-1} · l_{i-1} + k` (k = 0 left, 1 right).
    id: u64,
    len: f64,
}

/// The thesis's id of a child (k = 0 left, 1 right) of a node with `id` at `level`.
pub fn child_id(id: u64, level: u32, k: u64) -> u64 {
    id * level as u64 + k
}

/// The avoidance waypoints around `c` for the way from `from` to `goal`: (left, right), each the
/// intersection of a tangent from `from` with the tangent from `goal` on the same side.
pub fn avoidance_waypoints(from: V2, goal: V2, c: &Circle) -> [Option<V2>; 2] {
    let (Some(tf), Some(tg)) = (c.tangent_points(from), c.tangent_points(goal)) else {
        return [None, None];
    };
    let dir = goal - from;
    // Tangent points on the left of from→goal, and on the right.
    let side = |pts: [V2; 2], left: bool| {
        let s0 = dir.cross(pts[0] - from);
        if (s0 > 0.0) == left {
            pts[0]
        } else {
            pts[1]
        }
    };
    let pick = |left: bool| line_intersection(from, side(tf, left), goal, side(tg, left));
    [pick(true), pick(false)]
}

fn check_ends(start: V2, goal: V2, circles: &[Circle], stats: Stats) -> Result<(), Box<Plan>> {
    if circles.iter().any(|c| c.contains(start)) {
        return Err(Box::new(Plan::failed(
            Status::StartInCollision,
            "the start is inside an inflated obstacle",
            stats,
        )));
    }
    if circles.iter().any(|c| c.contains(goal)) {
        return Err(Box::new(Plan::failed(
            Status::GoalInCollision,
            "the goal is inside an inflated obstacle",
            stats,
        )));
    }
    Ok(())
}

/// A start at most `slack` inside one inflated circle (and in no other): that circle with
/// its margin narrowed to pass just inside the start, so that a path may leave from there
/// along it. None for a start outside every circle, deeper inside, or in two.
pub fn narrowed_for(start: V2, circles: &[Circle], slack: f64) -> Option<(usize, Circle)> {
    let mut inside = circles
        .iter()
        .enumerate()
        .filter(|(_, c)| c.contains(start));
    let (i, c) = inside.next()?;
    let d = start.dist(c.c);
    if inside.next().is_some() || c.r - d > slack {
        return None;
    }
    Some((
        i,
        Circle {
            c: c.c,
            r: d - 2.0 * TOUCH,
        },
    ))
}

/// The obstacles grown by the inflation.
pub fn inflate(obstacles: &[Circle], inflation: f64) -> Vec<Circle> {
    obstacles
        .iter()
        .map(|c| Circle {
            c: c.c,
            r: c.r + inflation,
        })
        .collect()
}

/// The thesis's tangent binary tree (faithful). Returns the plan and, for debugging, the ids
/// of the waypoints of the path (root = 1).
pub fn plan_tree(start: V2, goal: V2, obstacles: &[Circle], p: &Params) -> (Plan, Vec<u64>) {
    let t0 = Instant::now();
    let circles = inflate(obstacles, p.inflation);
    let mut stats = Stats {
        prepare: t0.elapsed(),
        ..Stats::default()
    };
    if let Err(plan) = check_ends(start, goal, &circles, stats) {
        return (*plan, Vec::new());
    }
    let t1 = Instant::now();
    let mut nodes = vec![Node {
        p: start,
        parent: None,
        level: 1,
        id: 1,
        len: 0.0,
    }];
    let mut open = vec![0usize];
    let mut done = None;
    while !open.is_empty() {
        // Leaves that see the goal end the search; the shortest of them wins.
        let mut best: Option<(f64, usize)> = None;
        for &i in &open {
            stats.collision_queries += circles.len() as u64;
            if !circles.iter().any(|c| c.blocks(nodes[i].p, goal)) {
                let total = nodes[i].len + nodes[i].p.dist(goal);
                if best.is_none_or(|(b, _)| total < b) {
                    best = Some((total, i));
                }
            }
        }
        if let Some((_, i)) = best {
            done = Some(i);
            break;
        }
        if nodes[open[0]].level >= p.max_depth || t1.elapsed() > p.budget {
            break;
        }
        let mut next = Vec::new();
        for &i in &open {
            stats.expansions += 1;
            let leaf = nodes[i].clone();
            // The blocking obstacle nearest to the leaf.
            let blocking = circles
                .iter()
                .filter(|c| c.blocks(leaf.p, goal))
                .min_by(|a, b| leaf.p.dist(a.c).total_cmp(&leaf.p.dist(b.c)));
            let Some(c) = blocking else { continue };
            for (k, w) in avoidance_waypoints(leaf.p, goal, c).into_iter().enumerate() {
                let Some(w) = w else { continue };
                stats.generated += 1;
                stats.collision_queries += circles.len() as u64;
                // A child inside an obstacle is dropped (thesis); so is one that the leaf cannot
                // reach in a straight line without entering another obstacle (the thesis never
                // says it checks this, but its paths do not cross obstacles).
                if circles.iter().any(|c| c.contains(w) || c.blocks(leaf.p, w)) {
                    continue;
                }
                next.push(nodes.len());
                nodes.push(Node {
                    p: w,
                    parent: Some(i),
                    level: leaf.level + 1,
                    id: child_id(leaf.id, leaf.level, k as u64),
                    len: leaf.len + leaf.p.dist(w),
                });
            }
        }
        open = next;
    }
    stats.search = t1.elapsed();
    let Some(leaf) = done else {
        let why = if open.is_empty() {
            "every branch of the tree ended inside an obstacle"
        } else {
            "the tree reached its depth or time limit"
        };
        return (Plan::failed(Status::NoPath, why, stats), Vec::new());
    };
    let mut path = vec![goal];
    let mut ids = Vec::new();
    let mut at = Some(leaf);
    while let Some(i) = at {
        path.push(nodes[i].p);
        ids.push(nodes[i].id);
        at = nodes[i].parent;
    }
    path.reverse();
    ids.reverse();
    (Plan::path(path, stats, None), ids)
}

/// A point of the tangent graph: the start, the goal, or a tangent point on a circle.
#[derive(Debug, Clone, Copy)]
struct GNode {
    p: V2,
    /// The circle it lies on and its angle there.
    on: Option<(usize, f64)>,
}

/// How an edge of the graph runs.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Way {
    Straight,
    /// Along circle `i`, counter-clockwise (true) or clockwise.
    Arc(usize, bool),
}

/// The angular interval of circle `ci`'s rim that circle `cj` covers, as (centre angle, half
/// width): `None` when they do not overlap or `cj` lies inside `ci`, `(0, π)` when `ci` lies
/// inside `cj`.
fn covered(ci: &Circle, cj: &Circle) -> Option<(f64, f64)> {
    let d = ci.c.dist(cj.c);
    if d >= ci.r + cj.r {
        return None;
    }
    if d + ci.r <= cj.r {
        return Some((0.0, std::f64::consts::PI));
    }
    if d + cj.r <= ci.r {
        return None;
    }
    let cosa = (ci.r * ci.r + d * d - cj.r * cj.r) / (2.0 * ci.r * d);
    Some(((cj.c - ci.c).angle(), cosa.clamp(-1.0, 1.0).acos()))
}

/// True when the arc of circle `i` from angle `a`, going `ccw` (or clockwise) by `sweep`
/// radians, passes inside another circle.
fn arc_blocked(circles: &[Circle], i: usize, a: f64, sweep: f64, ccw: bool, grow: f64) -> bool {
    circles.iter().enumerate().any(|(j, cj)| {
        if j == i {
            return false;
        }
        // The other circle grown by how far the arc's polygon bulges out of its own: an arc
        // grazing (or touching) another circle would take its polygon inside it.
        let grown = Circle {
            c: cj.c,
            r: cj.r + grow,
        };
        let Some((mid, half)) = covered(&circles[i], &grown) else {
            return false;
        };
        if half >= std::f64::consts::PI - EPS {
            return true;
        }
        // The arc as [0, sweep] from a in its direction; the covered interval likewise.
        let rel = |ang: f64| {
            let d = if ccw { ang - a } else { a - ang };
            d.rem_euclid(std::f64::consts::TAU)
        };
        let lo = rel(mid - half * if ccw { 1.0 } else { -1.0 });
        let width = 2.0 * half;
        // Overlap of [0, sweep] with [lo, lo + width] on the circle (open intervals).
        lo + EPS < sweep || lo + width > std::f64::consts::TAU + EPS
    })
}

/// The circles that matter: near-duplicates merged ([`merge_near`], never over a point of
/// `keep`), then none that lies inside another (a mapper that reports an obstacle twice, or
/// twice a hair apart, changes nothing).
pub fn distinct(circles: &[Circle], keep: &[V2]) -> Vec<Circle> {
    let circles = merge_near(circles, keep);
    // k lies in m (within a micrometre); of two that lie in each other the later one goes.
    let within = |k: usize, m: usize| {
        let (a, b) = (circles[k], circles[m]);
        a.c.dist(b.c) + a.r <= b.r + 1e-6
    };
    let inside = |k: usize, m: usize| within(k, m) && (!within(m, k) || m < k);
    (0..circles.len())
        .filter(|&k| !(0..circles.len()).any(|m| m != k && inside(k, m)))
        .map(|k| circles[k])
        .collect()
}

/// How far the circle enclosing two near-duplicates may reach beyond the larger of them and
/// still be taken for both, m: at least 1 mm, more for large circles, as far as two circles
/// that nearly coincide leave their tangents and arcs degenerate (the gap between one's arc
/// and the other's boundary is about d²/2r for centres d apart, under [`TOUCH`] for d up to
/// about sqrt(2 r TOUCH)).
fn merge_reach(r: f64) -> f64 {
    (2.0 * (2.0 * r * TOUCH).sqrt()).max(1e-3)
}

/// Two circles that nearly coincide (one reaching beyond the other by at most
/// [`merge_reach`]) replaced by the smallest circle enclosing both, until no such pair is
/// left: the path keeps out of both, and no arc has to pass between two boundaries a hair
/// apart (two copies of a disk 1 µm to 1 mm apart left no path at all). A pair whose
/// enclosing circle would reach a third circle that neither reaches is left as it is (the
/// enclosing circle closed a 0.32 mm gap the disks left open), and so is one whose enclosing
/// circle would cover a point of `keep` (the start, the goal) that neither covers.
pub fn merge_near(circles: &[Circle], keep: &[V2]) -> Vec<Circle> {
    let mut out: Vec<Circle> = circles.to_vec();
    loop {
        let mut merged = None;
        'pairs: for i in 0..out.len() {
            for j in i + 1..out.len() {
                let (a, b) = (out[i], out[j]);
                let d = a.c.dist(b.c);
                // The enclosing circle's radius, and how far it reaches beyond the larger.
                let big = a.r.max(b.r);
                let r = (d + a.r + b.r) / 2.0;
                if r <= big {
                    continue; // one lies inside the other: `distinct` keeps the larger
                }
                if r - big <= merge_reach(big) {
                    let (big_c, small) = if a.r >= b.r { (a, b) } else { (b, a) };
                    // On the line through both centres, reaching both far sides.
                    let u = if d > 0.0 {
                        (small.c - big_c.c) * (1.0 / d)
                    } else {
                        v2(0.0, 0.0)
                    };
                    let c = big_c.c + u * (r - big_c.r);
                    let m = Circle { c, r };
                    // Not where the enclosing circle would close a gap that both leave open
                    // to a third circle: the way between them stays.
                    let closes = out.iter().enumerate().any(|(k, o)| {
                        k != i
                            && k != j
                            && m.c.dist(o.c) < m.r + o.r
                            && a.c.dist(o.c) >= a.r + o.r
                            && b.c.dist(o.c) >= b.r + o.r
                    });
                    let covers = keep
                        .iter()
                        .any(|&q| m.c.dist(q) <= m.r && a.c.dist(q) > a.r && b.c.dist(q) > b.r);
                    if closes || covers {
                        continue;
                    }
                    merged = Some((i, j, m));
                    break 'pairs;
                }
            }
        }
        match merged {
            Some((i, j, c)) => {
                out[i] = c;
                out.remove(j);
            }
            None => return out,
        }
    }
}

/// Closer than this, two circles touch: an arc passing there would squeeze through a gap of
/// no width.
const TOUCH: f64 = 1e-6;

/// The exact shortest path from `start` to `goal` among the circles (already inflated, and
/// [`distinct`]), as the graph's node sequence and edge kinds, with its length. An arc may
/// not pass within `grow` of another circle.
fn tangent_graph_path(
    start: V2,
    goal: V2,
    circles: &[Circle],
    grow: f64,
    stats: &mut Stats,
) -> Option<(Vec<GNode>, Vec<Way>, f64)> {
    let mut nodes = vec![GNode { p: start, on: None }, GNode { p: goal, on: None }];
    let mut edges: Vec<Vec<(usize, f64, Way)>> = vec![Vec::new(), Vec::new()];
    let free = |a: V2, b: V2, stats: &mut Stats| {
        stats.collision_queries += circles.len() as u64;
        !circles.iter().any(|c| c.blocks(a, b))
    };
    let add_node =
        |nodes: &mut Vec<GNode>, edges: &mut Vec<Vec<(usize, f64, Way)>>, i: usize, p: V2| {
            nodes.push(GNode {
                p,
                on: Some((i, (p - circles[i].c).angle())),
            });
            edges.push(Vec::new());
            nodes.len() - 1
        };
    let inside_other = |p: V2, skip: &[usize]| {
        circles
            .iter()
            .enumerate()
            .any(|(k, c)| !skip.contains(&k) && c.contains(p))
    };
    // Start to goal.
    if free(start, goal, stats) {
        let d = start.dist(goal);
        edges[0].push((1, d, Way::Straight));
    }
    // Start and goal to every circle.
    for (k, endpoint) in [(0usize, start), (1usize, goal)] {
        for (i, c) in circles.iter().enumerate() {
            let Some(pts) = c.tangent_points(endpoint) else {
                continue;
            };
            for t in pts {
                if inside_other(t, &[i]) || !free(endpoint, t, stats) {
                    continue;
                }
                let n = add_node(&mut nodes, &mut edges, i, t);
                let d = endpoint.dist(t);
                edges[k].push((n, d, Way::Straight));
                edges[n].push((k, d, Way::Straight));
            }
        }
    }
    // Bitangents between circles.
    for i in 0..circles.len() {
        for j in i + 1..circles.len() {
            let (a, b) = (circles[i], circles[j]);
            let d = a.c.dist(b.c);
            if d < EPS {
                continue;
            }
            let base = (b.c - a.c).angle();
            let mut pairs = Vec::new();
            // Outer tangents: normals at base ± acos((ra - rb)/d).
            if d > (a.r - b.r).abs() {
                let t = ((a.r - b.r) / d).acos();
                for s in [1.0, -1.0] {
                    let n = V2::polar(base + s * t);
                    pairs.push((a.c + n * a.r, b.c + n * b.r));
                }
            }
            // Inner tangents: only between disjoint circles (touching ones leave no way
            // between them).
            if d > a.r + b.r + EPS {
                let t = ((a.r + b.r) / d).acos();
                for s in [1.0, -1.0] {
                    let n = V2::polar(base + s * t);
                    pairs.push((a.c + n * a.r, b.c - n * b.r));
                }
            }
            for (pa, pb) in pairs {
                if inside_other(pa, &[i, j]) || inside_other(pb, &[i, j]) || !free(pa, pb, stats) {
                    continue;
                }
                let na = add_node(&mut nodes, &mut edges, i, pa);
                let nb = add_node(&mut nodes, &mut edges, j, pb);
                let len = pa.dist(pb);
                edges[na].push((nb, len, Way::Straight));
                edges[nb].push((na, len, Way::Straight));
            }
        }
    }
    // Arcs between angularly consecutive points of each circle.
    for (i, c) in circles.iter().enumerate() {
        let mut on: Vec<(f64, usize)> = nodes
            .iter()
            .enumerate()
            .filter_map(|(n, g)| g.on.filter(|(ci, _)| *ci == i).map(|(_, a)| (a, n)))
            .collect();
        on.sort_by(|x, y| x.0.total_cmp(&y.0));
        let m = on.len();
        if m < 2 {
            continue;
        }
        for k in 0..m {
            let (a0, n0) = on[k];
            let (a1, n1) = on[(k + 1) % m];
            let sweep = (a1 - a0).rem_euclid(std::f64::consts::TAU);
            if !(1e-9..=std::f64::consts::TAU - 1e-9).contains(&sweep) {
                // The same point, reached by two tangents: joined at no cost.
                edges[n0].push((n1, 0.0, Way::Straight));
                edges[n1].push((n0, 0.0, Way::Straight));
                continue;
            }
            if arc_blocked(circles, i, a0, sweep, true, grow) {
                continue;
            }
            let len = sweep * c.r;
            edges[n0].push((n1, len, Way::Arc(i, true)));
            edges[n1].push((n0, len, Way::Arc(i, false)));
        }
    }
    // Dijkstra from the start to the goal.
    let n = nodes.len();
    let mut dist = vec![f64::INFINITY; n];
    let mut prev: Vec<Option<(usize, Way)>> = vec![None; n];
    let mut heap = BinaryHeap::new();
    dist[0] = 0.0;
    heap.push(Least(0.0, 0));
    while let Some(Least(d, u)) = heap.pop() {
        if d > dist[u] {
            continue;
        }
        stats.expansions += 1;
        if u == 1 {
            break;
        }
        for &(v, w, way) in &edges[u] {
            stats.generated += 1;
            if d + w < dist[v] {
                dist[v] = d + w;
                prev[v] = Some((u, way));
                heap.push(Least(d + w, v));
            }
        }
    }
    if !dist[1].is_finite() {
        return None;
    }
    let mut seq = vec![1];
    let mut ways = Vec::new();
    let mut at = 1;
    while let Some((p, way)) = prev[at] {
        seq.push(p);
        ways.push(way);
        at = p;
    }
    seq.reverse();
    ways.reverse();
    Some((seq.into_iter().map(|k| nodes[k]).collect(), ways, dist[1]))
}

/// The exact shortest path among the inflated circles (improved mode). `cost` is the path's
/// length as returned (waypoints outside the circles); [`exact_length`] gives the optimum.
pub fn plan_exact(start: V2, goal: V2, obstacles: &[Circle], p: &Params) -> Plan {
    let t0 = Instant::now();
    let full = distinct(&inflate(obstacles, p.inflation), &[start, goal]);
    let mut circles = full.clone();
    let mut stats = Stats::default();
    // A start a little inside one margin: that margin narrowed to it for this plan.
    let narrowed = narrowed_for(start, &circles, p.start_slack);
    if let Some((i, c)) = narrowed {
        circles[i] = c;
    }
    if let Err(plan) = check_ends(start, goal, &circles, stats) {
        return *plan;
    }
    // From there along the narrowed margin, growing back to the whole one where it can.
    let path = exact_path(start, goal, &circles, p, &mut stats).map(|way| {
        narrowed
            .and_then(|(i, c)| regain(&way, &full, i, c))
            .unwrap_or(way)
    });
    stats.search = t0.elapsed();
    let Some(path) = path else {
        return Plan::failed(
            Status::NoPath,
            "the goal cannot be reached around the obstacles",
            stats,
        );
    };
    Plan::path(path, stats, Some(1.0))
}

/// How fast a way from a start inside a margin regains the whole margin: the narrowed
/// margin grows back by this much per metre along the way (5 cm of start slack in 0.25 m).
const REGAIN: f64 = 0.2;

/// `way`, planned from a start inside circle `i`'s margin along that margin narrowed to the
/// start (`narrowed`), with the margin growing back: each waypoint inside the whole margin
/// (`full`) moves out from the centre as the narrowed circle grows by [`REGAIN`] per metre
/// along the way, up to the whole margin. Replanned at every step, a walk whose feet drift
/// into a margin is brought back out of it, where a way along the narrowed margin keeps every
/// millimetre of drift, step after step. None if the moved way would enter another margin or
/// come nearer the centre than the start.
fn regain(way: &[V2], full: &[Circle], i: usize, narrowed: Circle) -> Option<Vec<V2>> {
    let c = full[i];
    let mut along = 0.0;
    let mut out = Vec::with_capacity(way.len());
    for (k, &w) in way.iter().enumerate() {
        if k > 0 {
            along += way[k - 1].dist(w);
        }
        let rho = w.dist(c.c);
        let last = k + 1 == way.len();
        if k == 0 || last || rho >= c.r || narrowed.r <= 0.0 {
            out.push(w);
            continue;
        }
        let grown = (narrowed.r + REGAIN * along).min(c.r);
        out.push(c.c + (w - c.c) * (grown / narrowed.r));
    }
    let clear = out.windows(2).all(|s| {
        !narrowed.blocks(s[0], s[1])
            && full
                .iter()
                .enumerate()
                .all(|(j, o)| j == i || !o.blocks(s[0], s[1]))
    });
    clear.then_some(out)
}

/// The exact shortest way among `circles` (inflated, [`distinct`]) as waypoints, or None.
fn exact_path(
    start: V2,
    goal: V2,
    circles: &[Circle],
    p: &Params,
    stats: &mut Stats,
) -> Option<Vec<V2>> {
    let (seq, ways, _) = tangent_graph_path(start, goal, circles, TOUCH, stats)?;
    // Straight parts as they are; an arc as the vertices of a polygon circumscribed about the
    // circle (its sides are tangent to the circle, the first and last along the straight parts
    // that arrive and leave), so the path stays outside it.
    let mut path = vec![seq[0].p];
    for (k, way) in ways.iter().enumerate() {
        let (a, b) = (seq[k], seq[k + 1]);
        if let Way::Arc(i, ccw) = *way {
            let c = circles[i];
            let (a0, a1) = (a.on.expect("on a circle").1, b.on.expect("on a circle").1);
            let sweep = if ccw {
                (a1 - a0).rem_euclid(std::f64::consts::TAU)
            } else {
                -(a0 - a1).rem_euclid(std::f64::consts::TAU)
            };
            // Sides of at most arc_step, fewer than needed where the polygon would cut into
            // another circle the arc passes near: then halved until it does not.
            let mut m = (sweep.abs() / p.arc_step).ceil().max(1.0) as usize;
            let polygon = |m: usize| {
                let step = sweep / m as f64;
                let r = c.r / (step / 2.0).cos();
                (0..m)
                    .map(|s| c.c + V2::polar(a0 + step * (s as f64 + 0.5)) * r)
                    .collect::<Vec<V2>>()
            };
            let mut pts = polygon(m);
            let enters = |pts: &[V2]| {
                std::iter::once(a.p)
                    .chain(pts.iter().copied())
                    .chain([b.p])
                    .collect::<Vec<V2>>()
                    .windows(2)
                    .any(|w| {
                        circles.iter().enumerate().any(|(j, o)| {
                            j != i && point_segment_distance(o.c, w[0], w[1]) < o.r - 1e-9
                        })
                    })
            };
            while enters(&pts) && m < 1 << 16 {
                m *= 2;
                pts = polygon(m);
            }
            path.extend(pts);
        }
        path.push(b.p);
    }
    // Collinear points (the tangent points between straight parts and arcs) add nothing.
    Some(simplify(&path))
}

/// Drops points that lie on the segment between their neighbours.
fn simplify(path: &[V2]) -> Vec<V2> {
    let mut out: Vec<V2> = Vec::with_capacity(path.len());
    for &p in path {
        if out.last().is_some_and(|q| q.dist(p) < 1e-9) {
            continue;
        }
        while out.len() >= 2 {
            let (a, b) = (out[out.len() - 2], out[out.len() - 1]);
            if ((b - a).cross(p - b)).abs() < 1e-9 && (b - a).dot(p - b) >= 0.0 {
                out.pop();
            } else {
                break;
            }
        }
        out.push(p);
    }
    out
}

/// The length of the exact shortest path among the inflated circles (arcs included), or
/// `None` when there is none.
pub fn exact_length(start: V2, goal: V2, obstacles: &[Circle], p: &Params) -> Option<f64> {
    let circles = distinct(&inflate(obstacles, p.inflation), &[start, goal]);
    tangent_graph_path(start, goal, &circles, TOUCH, &mut Stats::default()).map(|(_, _, d)| d)
}

/// Headings of the path's segments: the heading at each waypoint is that of the segment that
/// ends there (the start keeps `start_yaw`).
pub fn headings(path: &[V2], start_yaw: f64) -> Vec<f64> {
    let mut out = vec![start_yaw];
    for w in path.windows(2) {
        out.push((w[1] - w[0]).angle());
    }
    out
}

/// Wraps an angle difference (used by the footsteps).
pub fn heading_change(from: f64, to: f64) -> f64 {
    wrap(to - from)
}

/// `v2`, for the scene builders of the tests.
pub fn at(x: f64, y: f64) -> V2 {
    v2(x, y)
}
