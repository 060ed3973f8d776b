//! 3-D proximity between the robot's swept-sphere volumes (SSV: points, segments and triangles
//! grown by a radius, LOLA's model, seed 002 §3) and the world's obstacles, on `parry3d-f64`
//! and `nalgebra`.
//!
//! Between two SSVs the signed distance is the distance between their cores less both radii,
//! computed exactly (closest points of point, segment and triangle cores), so it is exact to
//! rounding, as the notes' G1 asks. Boxes and upright cylinders go through parry's contact
//! query (GJK/EPA; negative inside). Every answer carries the closest points and the gradient
//! of the distance with respect to a translation of the first shape. Bounding boxes cull.

use parry3d_f64::bounding_volume::{Aabb, BoundingVolume};
use parry3d_f64::math::{Isometry, Point, Vector};
use parry3d_f64::na::{Translation3, UnitQuaternion};
use parry3d_f64::query;
use parry3d_f64::shape::{Ball, Capsule, Cuboid, Cylinder, RoundShape, Shape, Triangle};

/// A point in space, m.
pub type P3 = Point<f64>;
/// A vector in space, m.
pub type V3 = Vector<f64>;

/// The core of an SSV.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Core {
    /// A point (the SSV is a sphere).
    Point(P3),
    /// A segment (a capsule).
    Segment(P3, P3),
    /// A triangle (a rounded triangle).
    Triangle(P3, P3, P3),
}

/// A solid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Solid {
    /// A swept-sphere volume: the points within `radius` of `core`.
    Ssv {
        /// Its core.
        core: Core,
        /// Its radius, m.
        radius: f64,
    },
    /// A box: centre, heading about z, half extents.
    Box {
        /// Centre, m.
        centre: P3,
        /// Heading of its x axis, rad.
        yaw: f64,
        /// Half extents, m.
        half: V3,
    },
    /// An upright cylinder: centre of its base circle at `base`, radius, height.
    Cylinder {
        /// Centre of its bottom, m.
        base: P3,
        /// Radius, m.
        radius: f64,
        /// Height, m.
        height: f64,
    },
}

/// A solid's shadow on the ground.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Footprint {
    /// An SSV's core, flattened, and its radius.
    Core(Core, f64),
    /// A turned rectangle: centre, the cosine and sine of its heading, half extents.
    Rect {
        /// Centre.
        c: crate::geom::V2,
        /// cos(yaw).
        cos: f64,
        /// sin(yaw).
        sin: f64,
        /// Half length and half width.
        half: (f64, f64),
    },
    /// A circle: centre and radius.
    Circle(crate::geom::V2, f64),
}

impl Footprint {
    /// The signed distance from `p`, m (negative inside).
    #[inline]
    pub fn distance(&self, p: crate::geom::V2) -> f64 {
        match *self {
            Footprint::Core(core, radius) => {
                let at = P3::new(p.x, p.y, 0.0);
                let (x, y) = closest_cores(&Core::Point(at), &core);
                (x - y).norm() - radius
            }
            Footprint::Rect { c, cos, sin, half } => {
                let q = p - c;
                let (lx, ly) = (
                    (cos * q.x + sin * q.y).abs() - half.0,
                    (-sin * q.x + cos * q.y).abs() - half.1,
                );
                if lx > 0.0 || ly > 0.0 {
                    let (x, y) = (lx.max(0.0), ly.max(0.0));
                    (x * x + y * y).sqrt()
                } else {
                    lx.max(ly)
                }
            }
            Footprint::Circle(c, r) => p.dist(c) - r,
        }
    }
}

/// How near two solids are.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Proximity {
    /// Signed distance, m (negative: overlap).
    pub distance: f64,
    /// The point of the first solid nearest the second.
    pub on_a: P3,
    /// The point of the second solid nearest the first.
    pub on_b: P3,
    /// The gradient of the distance with respect to a translation of the first solid (a unit
    /// vector pointing away from the second).
    pub gradient: V3,
}

impl Solid {
    /// A sphere.
    pub fn sphere(c: P3, radius: f64) -> Solid {
        Solid::Ssv {
            core: Core::Point(c),
            radius,
        }
    }

    /// A capsule.
    pub fn capsule(a: P3, b: P3, radius: f64) -> Solid {
        Solid::Ssv {
            core: Core::Segment(a, b),
            radius,
        }
    }

    /// A rounded triangle.
    pub fn rounded_triangle(a: P3, b: P3, c: P3, radius: f64) -> Solid {
        Solid::Ssv {
            core: Core::Triangle(a, b, c),
            radius,
        }
    }

    /// The same solid moved by `t`.
    #[inline]
    pub fn translated(&self, t: V3) -> Solid {
        match *self {
            Solid::Ssv { core, radius } => Solid::Ssv {
                core: match core {
                    Core::Point(p) => Core::Point(p + t),
                    Core::Segment(a, b) => Core::Segment(a + t, b + t),
                    Core::Triangle(a, b, c) => Core::Triangle(a + t, b + t, c + t),
                },
                radius,
            },
            Solid::Box { centre, yaw, half } => Solid::Box {
                centre: centre + t,
                yaw,
                half,
            },
            Solid::Cylinder {
                base,
                radius,
                height,
            } => Solid::Cylinder {
                base: base + t,
                radius,
                height,
            },
        }
    }

    /// Its bounding box.
    #[inline]
    pub fn aabb(&self) -> Aabb {
        match *self {
            Solid::Ssv { core, radius } => {
                let (lo, hi) = match core {
                    Core::Point(p) => (p, p),
                    Core::Segment(a, b) => (a.inf(&b), a.sup(&b)),
                    Core::Triangle(a, b, c) => (a.inf(&b).inf(&c), a.sup(&b).sup(&c)),
                };
                let r = V3::repeat(radius);
                Aabb::new(lo - r, hi + r)
            }
            Solid::Box { centre, yaw, half } => {
                Cuboid::new(half).compute_aabb(&Isometry::new(centre.coords, V3::z() * yaw))
            }
            Solid::Cylinder {
                base,
                radius,
                height,
            } => Aabb::new(
                base - V3::new(radius, radius, 0.0),
                base + V3::new(radius, radius, height),
            ),
        }
    }

    /// The height of its top, m.
    #[inline]
    pub fn top(&self) -> f64 {
        self.aabb().maxs.z
    }

    /// The signed distance from `p` to its footprint (its shadow on the ground), m.
    #[inline]
    pub fn footprint_distance(&self, p: crate::geom::V2) -> f64 {
        self.footprint().distance(p)
    }

    /// Its footprint (its shadow on the ground), ready for many distance queries.
    pub fn footprint(&self) -> Footprint {
        let flat = |q: P3| P3::new(q.x, q.y, 0.0);
        match *self {
            Solid::Ssv { core, radius } => Footprint::Core(
                match core {
                    Core::Point(a) => Core::Point(flat(a)),
                    Core::Segment(a, b) => Core::Segment(flat(a), flat(b)),
                    Core::Triangle(a, b, c) => Core::Triangle(flat(a), flat(b), flat(c)),
                },
                radius,
            ),
            Solid::Box { centre, yaw, half } => {
                let (sin, cos) = yaw.sin_cos();
                Footprint::Rect {
                    c: crate::geom::v2(centre.x, centre.y),
                    cos,
                    sin,
                    half: (half.x, half.y),
                }
            }
            Solid::Cylinder { base, radius, .. } => {
                Footprint::Circle(crate::geom::v2(base.x, base.y), radius)
            }
        }
    }

    /// The shape and pose parry needs.
    fn parry(&self) -> (Box<dyn Shape>, Isometry<f64>) {
        match *self {
            Solid::Ssv { core, radius } => match core {
                Core::Point(p) => (
                    Box::new(Ball::new(radius)),
                    Isometry::translation(p.x, p.y, p.z),
                ),
                Core::Segment(a, b) => (Box::new(Capsule::new(a, b, radius)), Isometry::identity()),
                Core::Triangle(a, b, c) => (
                    Box::new(RoundShape {
                        inner_shape: Triangle::new(a, b, c),
                        border_radius: radius,
                    }),
                    Isometry::identity(),
                ),
            },
            Solid::Box { centre, yaw, half } => (
                Box::new(Cuboid::new(half)),
                Isometry::new(centre.coords, V3::z() * yaw),
            ),
            Solid::Cylinder {
                base,
                radius,
                height,
            } => (
                Box::new(Cylinder::new(height / 2.0, radius)),
                // parry's cylinders stand along y: turned upright.
                Isometry::from_parts(
                    Translation3::from(base.coords + V3::z() * (height / 2.0)),
                    UnitQuaternion::from_axis_angle(&V3::x_axis(), std::f64::consts::FRAC_PI_2),
                ),
            ),
        }
    }
}

/// The cores and radii of two SSVs.
fn both_ssv<'a>(a: &'a Solid, b: &'a Solid) -> Option<(&'a Core, f64, &'a Core, f64)> {
    match (a, b) {
        (
            Solid::Ssv {
                core: ca,
                radius: ra,
            },
            Solid::Ssv {
                core: cb,
                radius: rb,
            },
        ) => Some((ca, *ra, cb, *rb)),
        _ => None,
    }
}

/// The signed distance between `a` and `b`, their closest points and its gradient.
#[inline]
pub fn proximity(a: &Solid, b: &Solid) -> Proximity {
    if let Some((ca, ra, cb, rb)) = both_ssv(a, b) {
        let (pa, pb) = closest_cores(ca, cb);
        let d = (pa - pb).norm();
        let g = if d > 1e-15 {
            (pa - pb) / d
        } else {
            // Cores touching: any direction will do; up is as good as any.
            V3::z()
        };
        return Proximity {
            distance: d - ra - rb,
            on_a: pa - g * ra,
            on_b: pb + g * rb,
            gradient: g,
        };
    }
    let (sa, ia) = a.parry();
    let (sb, ib) = b.parry();
    match query::contact(&ia, sa.as_ref(), &ib, sb.as_ref(), f64::MAX / 4.0) {
        Ok(Some(c)) => Proximity {
            distance: c.dist,
            on_a: c.point1,
            on_b: c.point2,
            gradient: -c.normal1.into_inner(),
        },
        // Every pair of these shapes is supported; far beyond any prediction is not reached.
        _ => Proximity {
            distance: f64::INFINITY,
            on_a: ia.translation.vector.into(),
            on_b: ib.translation.vector.into(),
            gradient: V3::z(),
        },
    }
}

/// True when `a` and `b` overlap (touching counts); cheaper than [`proximity`].
#[inline]
pub fn overlaps(a: &Solid, b: &Solid) -> bool {
    if let Some((ca, ra, cb, rb)) = both_ssv(a, b) {
        let (pa, pb) = closest_cores(ca, cb);
        return (pa - pb).norm() <= ra + rb;
    }
    let (sa, ia) = a.parry();
    let (sb, ib) = b.parry();
    query::intersection_test(&ia, sa.as_ref(), &ib, sb.as_ref()).unwrap_or(true)
}

/// The least signed distance from `a` to any of `others` whose bounding box comes within
/// `reach` of `a`'s (the rest are at least that far: `None` when all are).
#[inline]
pub fn nearest(a: &Solid, others: &[(Solid, Aabb)], reach: f64) -> Option<(usize, Proximity)> {
    let ba = a.aabb().loosened(reach);
    others
        .iter()
        .enumerate()
        .filter(|(_, (_, bb))| ba.intersects(bb))
        .map(|(i, (o, _))| (i, proximity(a, o)))
        .min_by(|x, y| x.1.distance.total_cmp(&y.1.distance))
}

/// The closest points of `p` and segment a-b.
fn point_segment(p: P3, a: P3, b: P3) -> P3 {
    let ab = b - a;
    let l = ab.norm_squared();
    if l < 1e-300 {
        return a;
    }
    a + ab * ((p - a).dot(&ab) / l).clamp(0.0, 1.0)
}

/// The closest points of segments p1-q1 and p2-q2 (Ericson, Real-Time Collision Detection
/// §5.1.9).
fn segment_segment(p1: P3, q1: P3, p2: P3, q2: P3) -> (P3, P3) {
    let (d1, d2, r) = (q1 - p1, q2 - p2, p1 - p2);
    let (a, e, f) = (d1.norm_squared(), d2.norm_squared(), d2.dot(&r));
    let eps = 1e-300;
    let (s, t);
    if a <= eps && e <= eps {
        return (p1, p2);
    }
    if a <= eps {
        s = 0.0;
        t = (f / e).clamp(0.0, 1.0);
    } else {
        let c = d1.dot(&r);
        if e <= eps {
            t = 0.0;
            s = (-c / a).clamp(0.0, 1.0);
        } else {
            let b = d1.dot(&d2);
            let denom = a * e - b * b;
            let mut s0 = if denom > 1e-15 * a * e {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let mut t0 = (b * s0 + f) / e;
            if t0 < 0.0 {
                t0 = 0.0;
                s0 = (-c / a).clamp(0.0, 1.0);
            } else if t0 > 1.0 {
                t0 = 1.0;
                s0 = ((b - c) / a).clamp(0.0, 1.0);
            }
            s = s0;
            t = t0;
        }
    }
    (p1 + d1 * s, p2 + d2 * t)
}

/// The point of triangle a-b-c nearest `p` (Ericson §5.1.5).
fn point_triangle(p: P3, a: P3, b: P3, c: P3) -> P3 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

/// Where segment p-q crosses triangle a-b-c, if it does.
fn segment_pierces(p: P3, q: P3, a: P3, b: P3, c: P3) -> Option<P3> {
    let n = (b - a).cross(&(c - a));
    let (dp, dq) = ((p - a).dot(&n), (q - a).dot(&n));
    if dp * dq > 0.0 || (dp == 0.0 && dq == 0.0) {
        return None;
    }
    let x = p + (q - p) * (dp / (dp - dq));
    let inside = |u: P3, v: P3| (v - u).cross(&(x - u)).dot(&n) >= 0.0;
    (inside(a, b) && inside(b, c) && inside(c, a)).then_some(x)
}

/// The closest points of a segment and a triangle.
fn segment_triangle(p: P3, q: P3, t: [P3; 3]) -> (P3, P3) {
    if let Some(x) = segment_pierces(p, q, t[0], t[1], t[2]) {
        return (x, x);
    }
    let mut best = {
        let y = point_triangle(p, t[0], t[1], t[2]);
        (p, y)
    };
    let mut consider = |u: P3, v: P3| {
        if (u - v).norm_squared() < (best.0 - best.1).norm_squared() {
            best = (u, v);
        }
    };
    consider(q, point_triangle(q, t[0], t[1], t[2]));
    for k in 0..3 {
        let (u, v) = segment_segment(p, q, t[k], t[(k + 1) % 3]);
        consider(u, v);
    }
    best
}

/// The closest points of two cores.
#[inline]
pub fn closest_cores(a: &Core, b: &Core) -> (P3, P3) {
    use Core::*;
    match (*a, *b) {
        (Point(p), Point(q)) => (p, q),
        (Point(p), Segment(u, v)) => (p, point_segment(p, u, v)),
        (Segment(..), Point(_)) => {
            let (y, x) = closest_cores(b, a);
            (x, y)
        }
        (Point(p), Triangle(u, v, w)) => (p, point_triangle(p, u, v, w)),
        (Triangle(..), Point(_)) => {
            let (y, x) = closest_cores(b, a);
            (x, y)
        }
        (Segment(p, q), Segment(u, v)) => segment_segment(p, q, u, v),
        (Segment(p, q), Triangle(u, v, w)) => segment_triangle(p, q, [u, v, w]),
        (Triangle(..), Segment(..)) => {
            let (y, x) = closest_cores(b, a);
            (x, y)
        }
        (Triangle(a0, a1, a2), Triangle(b0, b1, b2)) => {
            let (ta, tb) = ([a0, a1, a2], [b0, b1, b2]);
            let mut best: Option<(P3, P3)> = None;
            let mut consider = |u: P3, v: P3| {
                if best.is_none_or(|(x, y)| (u - v).norm_squared() < (x - y).norm_squared()) {
                    best = Some((u, v));
                }
            };
            for k in 0..3 {
                let (u, v) = segment_triangle(ta[k], ta[(k + 1) % 3], tb);
                consider(u, v);
                let (v, u) = segment_triangle(tb[k], tb[(k + 1) % 3], ta);
                consider(u, v);
            }
            best.expect("six candidates")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(x: f64, y: f64, z: f64) -> P3 {
        P3::new(x, y, z)
    }

    #[test]
    fn simple_cases() {
        let a = Solid::sphere(p(0.0, 0.0, 0.0), 0.5);
        let b = Solid::capsule(p(2.0, -1.0, 0.0), p(2.0, 1.0, 0.0), 0.25);
        let pr = proximity(&a, &b);
        assert!((pr.distance - 1.25).abs() < 1e-12);
        assert!((pr.gradient - V3::new(-1.0, 0.0, 0.0)).norm() < 1e-12);
        assert!((pr.on_a - p(0.5, 0.0, 0.0)).norm() < 1e-12);
        // A triangle pierced by a segment: cores touch, the SSVs overlap by both radii.
        let t =
            Solid::rounded_triangle(p(-1.0, -1.0, 0.0), p(1.0, -1.0, 0.0), p(0.0, 1.0, 0.0), 0.1);
        let s = Solid::capsule(p(0.0, 0.0, -1.0), p(0.0, 0.0, 1.0), 0.05);
        assert!((proximity(&t, &s).distance + 0.15).abs() < 1e-12);
        // A sphere above a box, and inside it.
        let bx = Solid::Box {
            centre: p(0.0, 0.0, 0.5),
            yaw: 0.3,
            half: V3::new(0.5, 0.5, 0.5),
        };
        let above = proximity(&Solid::sphere(p(0.0, 0.0, 2.0), 0.25), &bx);
        assert!((above.distance - 0.75).abs() < 1e-9, "{above:?}");
        assert!((above.gradient - V3::z()).norm() < 1e-9);
        let inside = proximity(&Solid::sphere(p(0.0, 0.0, 0.8), 0.1), &bx);
        assert!((inside.distance + 0.3).abs() < 1e-6, "{inside:?}");
        // An upright cylinder stands on its base.
        let cy = Solid::Cylinder {
            base: p(3.0, 0.0, 0.0),
            radius: 0.5,
            height: 1.0,
        };
        assert!((cy.top() - 1.0).abs() < 1e-12);
        let side = proximity(&Solid::sphere(p(4.0, 0.0, 0.5), 0.1), &cy);
        assert!((side.distance - 0.4).abs() < 1e-6, "{side:?}");
    }
}
