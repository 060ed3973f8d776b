//! The world as the planner keeps it: the map, the surfaces, the obstacles as swept-sphere
//! solids, and the foothold and swing checks against them.

use parry3d_f64::bounding_volume::{Aabb, BoundingVolume};

use crate::geom::{convex_overlap, foot_cspace, rectangle, v2, V2};
use crate::grid::Grid;
use crate::plan::{Foot, Stats};
use crate::scene::{Obstacle, Scene};
use crate::ssv::{overlaps, Solid, P3};

use super::settings::Robot;

/// An obstacle as the planner keeps it.
#[derive(Debug, Clone)]
pub(super) struct Thing {
    pub(super) solid: Solid,
    pub(super) aabb: Aabb,
    pub(super) top: f64,
    /// For an upright box: its footprint and the height of its bottom (a foothold test is then
    /// a point test against the footprint grown by the turned sole: [`foot_cspace`]).
    pub(super) prism: Option<(Vec<V2>, f64)>,
    /// A surface's edge (not an obstacle to the 2-D pre-planner).
    pub(super) edge: bool,
}

/// The world: the map, the surfaces, the obstacles (with the surfaces' edges).
#[derive(Debug, Clone)]
pub struct World {
    /// x and y ranges of the map, m.
    pub map: ([f64; 2], [f64; 2]),
    /// Steppable surfaces: corners and height.
    pub surfaces: Vec<(Vec<V2>, f64)>,
    pub(super) things: Vec<Thing>,
}

/// Radius of a surface edge's capsule, m.
pub const EDGE_RADIUS: f64 = 0.01;

impl World {
    /// The world of a scene (extruded polygons stand in as their bounding cylinders).
    pub fn of(scene: &Scene) -> World {
        let (x, y, _) = Grid::extent_of(scene);
        let map = (x, y);
        let mut things = Vec::new();
        for o in &scene.obstacle {
            let solid = match *o {
                Obstacle::Sphere { centre, radius } => {
                    Solid::sphere(P3::new(centre[0], centre[1], centre[2]), radius)
                }
                Obstacle::Capsule { a, b, radius } => {
                    Solid::capsule(P3::new(a[0], a[1], a[2]), P3::new(b[0], b[1], b[2]), radius)
                }
                Obstacle::RoundedTriangle { points, radius } => {
                    let p = points.map(|q| P3::new(q[0], q[1], q[2]));
                    Solid::rounded_triangle(p[0], p[1], p[2], radius)
                }
                Obstacle::Box {
                    x,
                    y,
                    yaw,
                    length,
                    width,
                    ..
                } => {
                    let (lo, hi) = (o.bottom(), o.top().min(10.0));
                    Solid::Box {
                        centre: P3::new(x, y, (lo + hi) / 2.0),
                        yaw,
                        half: parry3d_f64::math::Vector::new(
                            length / 2.0,
                            width / 2.0,
                            (hi - lo) / 2.0,
                        ),
                    }
                }
                Obstacle::Circle { .. } | Obstacle::Polygon { .. } => {
                    let c = o.bounding_circle();
                    Solid::Cylinder {
                        base: P3::new(c.c.x, c.c.y, o.bottom()),
                        radius: c.r,
                        height: o.top().min(10.0) - o.bottom(),
                    }
                }
            };
            things.push(solid);
        }
        let obstacles = things.len();
        let mut surfaces = Vec::new();
        for s in &scene.surface {
            let poly = s.polygon();
            for k in 0..poly.len() {
                let (a, b) = (poly[k], poly[(k + 1) % poly.len()]);
                things.push(Solid::capsule(
                    P3::new(a.x, a.y, s.height),
                    P3::new(b.x, b.y, s.height),
                    EDGE_RADIUS,
                ));
            }
            surfaces.push((poly, s.height));
        }
        let things: Vec<Thing> = things
            .into_iter()
            .enumerate()
            .map(|(k, solid)| Thing {
                edge: k >= obstacles,
                aabb: solid.aabb(),
                top: solid.top(),
                prism: match solid {
                    Solid::Box { centre, yaw, half } => Some((
                        rectangle(v2(centre.x, centre.y), yaw, (2.0 * half.x, 2.0 * half.y))
                            .to_vec(),
                        centre.z - half.z,
                    )),
                    _ => None,
                },
                solid,
            })
            .collect();
        World {
            map,
            surfaces,
            things,
        }
    }

    /// The obstacles as the 2-D pre-planner sees them: too tall to step over (over `h_max`
    /// above their base), and small; surfaces' edges are neither.
    pub fn reduced(&self, h_max: f64) -> (Vec<Solid>, Vec<Solid>) {
        let (mut tall, mut small) = (Vec::new(), Vec::new());
        for t in self.things.iter().filter(|t| !t.edge) {
            if t.top - t.aabb.mins.z.max(0.0) > h_max {
                tall.push(t.solid);
            } else {
                small.push(t.solid);
            }
        }
        (tall, small)
    }

    pub(super) fn in_map(&self, p: V2) -> bool {
        (self.map.0[0]..=self.map.0[1]).contains(&p.x)
            && (self.map.1[0]..=self.map.1[1]).contains(&p.y)
    }

    /// The sole's corners at `f`.
    pub fn sole(&self, f: &Foot, r: &Robot) -> [V2; 4] {
        let (d, s) = (V2::polar(f.yaw), v2(-f.yaw.sin(), f.yaw.cos()));
        let (l, w) = (r.foot.0 / 2.0, r.foot.1 / 2.0);
        [(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)]
            .map(|(a, b)| f.p + d * (a * l) + s * (b * w))
    }

    /// The foot's two rounded triangles with its sole at height `z`.
    pub fn foot_solids(&self, p: V2, yaw: f64, z: f64, r: &Robot) -> [Solid; 2] {
        let (d, s) = (V2::polar(yaw), v2(-yaw.sin(), yaw.cos()));
        let (l, w) = (
            r.foot.0 / 2.0 - r.sole_radius,
            r.foot.1 / 2.0 - r.sole_radius,
        );
        let zc = z + r.sole_radius;
        let c = [(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)].map(|(a, b)| {
            let q = p + d * (a * l) + s * (b * w);
            P3::new(q.x, q.y, zc)
        });
        [
            Solid::rounded_triangle(c[0], c[1], c[2], r.sole_radius),
            Solid::rounded_triangle(c[0], c[2], c[3], r.sole_radius),
        ]
    }

    /// The shank above a foot at `p`, `yaw`, sole at `z`, leaning back by `tilt` rad.
    pub fn shank(&self, p: V2, yaw: f64, z: f64, tilt: f64, r: &Robot) -> Solid {
        let d = V2::polar(yaw);
        let ankle = P3::new(p.x, p.y, z + r.ankle);
        let knee = ankle
            + parry3d_f64::math::Vector::new(
                -d.x * tilt.sin() * r.shank,
                -d.y * tilt.sin() * r.shank,
                tilt.cos() * r.shank,
            );
        Solid::capsule(ankle, knee, r.shank_radius)
    }

    /// Where a foot at `f` would stand: the height of its surface, if the sole lies wholly on
    /// one (or on the floor) inside the map and its SSVs touch no obstacle.
    pub fn foothold(&self, f: &Foot, r: &Robot, stats: &mut Stats) -> Option<f64> {
        let sole = self.sole(f, r);
        if !sole.iter().all(|&c| self.in_map(c)) {
            return None;
        }
        let mut z = 0.0;
        let (lo, hi) = sole
            .iter()
            .fold((sole[0], sole[0]), |(lo, hi), &c| (lo.min(c), hi.max(c)));
        for (poly, h) in &self.surfaces {
            let (plo, phi) = poly
                .iter()
                .fold((poly[0], poly[0]), |(lo, hi), &c| (lo.min(c), hi.max(c)));
            if hi.x < plo.x || lo.x > phi.x || hi.y < plo.y || lo.y > phi.y {
                continue;
            }
            let inside = sole.iter().filter(|&&c| in_convex(c, poly)).count();
            if inside == 4 {
                z = f64::max(z, *h);
            } else if inside > 0 || convex_overlap(&sole, poly) {
                return None;
            }
        }
        let solids = self.foot_solids(f.p, f.yaw, z, r);
        let reach = solids[0].aabb().merged(&solids[1].aabb());
        for t in &self.things {
            if !reach.intersects(&t.aabb) {
                continue;
            }
            stats.collision_queries += 1;
            match &t.prism {
                // An upright box from the sole's level up: the sole's rectangle decides.
                Some((footprint, bottom)) if *bottom <= z + 2.0 * r.sole_radius => {
                    if in_convex(f.p, &foot_cspace(footprint, r.foot, f.yaw)) {
                        return None;
                    }
                }
                _ => {
                    if solids.iter().any(|s| overlaps(s, &t.solid)) {
                        return None;
                    }
                }
            }
        }
        Some(z)
    }

    /// The swing from `from` to `to` (footholds with their heights): the highest obstacle the
    /// swept foot and shank meet (0 when none), measured from the higher foothold.
    pub fn swing(&self, from: &Foot, to: &Foot, r: &Robot, stats: &mut Stats) -> f64 {
        let base = from.z.max(to.z);
        let z = base + r.swing_height;
        let len = from.p.dist(to.p);
        let n = (len / 0.05).ceil().max(1.0) as usize;
        let yaw = to.yaw;
        // The shank leans back by the angle under half the step at the CoG's height.
        let tilt = (len / 2.0).atan2(r.cog_height);
        // Only what the whole swept volume's box meets is looked at, tallest first; the
        // first overlap of each is its answer.
        let sweep = {
            let a = self.foot_solids(from.p, yaw, z, r)[0].aabb();
            let b = self.shank(to.p, yaw, z, tilt, r).aabb();
            let c = self.shank(from.p, yaw, z, tilt, r).aabb();
            a.merged(&b).merged(&c).loosened(r.foot.0)
        };
        let mut near: Vec<&Thing> = self
            .things
            .iter()
            .filter(|t| sweep.intersects(&t.aabb))
            .collect();
        near.retain(|t| t.top > base);
        if near.is_empty() {
            return 0.0;
        }
        near.sort_by(|a, b| b.top.total_cmp(&a.top));
        // The swept volume, sampled: the first obstacle met, tallest first, is the answer.
        // The swept volume, sampled: the solids at the origin and their boxes, moved to each
        // sample only where a box meets the obstacle's. The first obstacle met, tallest first,
        // is the answer.
        let [fa, fb] = self.foot_solids(v2(0.0, 0.0), yaw, z, r);
        let base_solids = [fa, fb, self.shank(v2(0.0, 0.0), yaw, z, tilt, r)];
        let base_boxes = base_solids.map(|s| s.aabb());
        for t in near {
            if t.top - base <= 0.0 {
                break;
            }
            let hit = (0..=n).any(|i| {
                let p = from.p + (to.p - from.p) * (i as f64 / n as f64);
                let shift = parry3d_f64::math::Vector::new(p.x, p.y, 0.0);
                base_solids.iter().zip(&base_boxes).any(|(s, bb)| {
                    Aabb::new(bb.mins + shift, bb.maxs + shift).intersects(&t.aabb) && {
                        stats.collision_queries += 1;
                        overlaps(&s.translated(shift), &t.solid)
                    }
                })
            });
            if hit {
                return t.top - base;
            }
        }
        0.0
    }
}

/// True when `p` lies in (or on) the counter-clockwise convex polygon `poly`.
fn in_convex(p: V2, poly: &[V2]) -> bool {
    let n = poly.len();
    (0..n).all(|k| (poly[(k + 1) % n] - poly[k]).cross(p - poly[k]) >= 0.0)
}
