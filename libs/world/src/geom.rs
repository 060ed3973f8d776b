//! Plane geometry for the path planners: points, circles, segment distances, tangents.

use std::ops::{Add, Mul, Sub};

/// A point or vector in the plane, metres.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Deserialize, serde::Serialize)]
pub struct V2 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
}

/// `V2 { x, y }`.
pub const fn v2(x: f64, y: f64) -> V2 {
    V2 { x, y }
}

impl Add for V2 {
    type Output = V2;
    #[inline]
    fn add(self, o: V2) -> V2 {
        v2(self.x + o.x, self.y + o.y)
    }
}

impl Sub for V2 {
    type Output = V2;
    #[inline]
    fn sub(self, o: V2) -> V2 {
        v2(self.x - o.x, self.y - o.y)
    }
}

impl Mul<f64> for V2 {
    type Output = V2;
    #[inline]
    fn mul(self, k: f64) -> V2 {
        v2(self.x * k, self.y * k)
    }
}

impl V2 {
    /// Dot product.
    #[inline]
    pub fn dot(self, o: V2) -> f64 {
        self.x * o.x + self.y * o.y
    }

    /// The z of the cross product (positive: `o` is to the left of `self`).
    #[inline]
    pub fn cross(self, o: V2) -> f64 {
        self.x * o.y - self.y * o.x
    }

    /// Length.
    #[inline]
    pub fn norm(self) -> f64 {
        // Not `hypot`: twice as fast, and these lengths are far from overflowing.
        (self.x * self.x + self.y * self.y).sqrt()
    }

    /// Distance to `o`.
    #[inline]
    pub fn dist(self, o: V2) -> f64 {
        (self - o).norm()
    }

    /// Angle from the x axis, rad.
    #[inline]
    pub fn angle(self) -> f64 {
        self.y.atan2(self.x)
    }

    /// The unit vector at angle `a`.
    #[inline]
    pub fn polar(a: f64) -> V2 {
        v2(a.cos(), a.sin())
    }

    /// The least of each coordinate.
    #[inline]
    pub fn min(self, o: V2) -> V2 {
        v2(self.x.min(o.x), self.y.min(o.y))
    }

    /// The greatest of each coordinate.
    #[inline]
    pub fn max(self, o: V2) -> V2 {
        v2(self.x.max(o.x), self.y.max(o.y))
    }
}

/// A circle (an obstacle, usually already inflated).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Circle {
    /// Centre.
    pub c: V2,
    /// Radius.
    pub r: f64,
}

/// Distance from `p` to the segment `a`–`b`.
#[inline]
pub fn point_segment_distance(p: V2, a: V2, b: V2) -> f64 {
    let ab = b - a;
    let l2 = ab.dot(ab);
    if l2 == 0.0 {
        return p.dist(a);
    }
    let t = ((p - a).dot(ab) / l2).clamp(0.0, 1.0);
    p.dist(a + ab * t)
}

/// Tolerance of the geometric tests, m: a path tangent to a circle touches it, it does not
/// enter it (a micrometre: the tangent points of composed constructions carry rounding errors
/// of tens of nanometres).
pub const EPS: f64 = 1e-6;

impl Circle {
    /// True when `p` is strictly inside.
    #[inline]
    pub fn contains(&self, p: V2) -> bool {
        p.dist(self.c) < self.r - EPS
    }

    /// True when the segment `a`–`b` enters the circle's interior.
    #[inline]
    pub fn blocks(&self, a: V2, b: V2) -> bool {
        point_segment_distance(self.c, a, b) < self.r - EPS
    }

    /// The two tangent points seen from `p` (left one first, as seen from `p` looking at the
    /// centre), or `None` when `p` is not outside.
    #[inline]
    pub fn tangent_points(&self, p: V2) -> Option<[V2; 2]> {
        let d = p.dist(self.c);
        if d <= self.r {
            return None;
        }
        let phi = (p - self.c).angle();
        let beta = (self.r / d).acos();
        // phi points from c to p: seen from p towards c, phi - beta lies on the left.
        Some([
            self.c + V2::polar(phi - beta) * self.r,
            self.c + V2::polar(phi + beta) * self.r,
        ])
    }
}

/// The intersection of the line through `a1`, `a2` with the line through `b1`, `b2`; `None`
/// when they are parallel.
#[inline]
pub fn line_intersection(a1: V2, a2: V2, b1: V2, b2: V2) -> Option<V2> {
    let (da, db) = (a2 - a1, b2 - b1);
    let den = da.cross(db);
    if den.abs() < 1e-12 {
        return None;
    }
    let t = (b1 - a1).cross(db) / den;
    Some(a1 + da * t)
}

pub use stride_limits::angle::wrap;

/// Length of a polyline.
pub fn path_length(p: &[V2]) -> f64 {
    p.windows(2).map(|w| w[0].dist(w[1])).sum()
}

/// True when two convex polygons (corners in order) overlap (separating-axis test; touching
/// does not count).
pub fn convex_overlap(a: &[V2], b: &[V2]) -> bool {
    for poly in [a, b] {
        for i in 0..poly.len() {
            let e = poly[(i + 1) % poly.len()] - poly[i];
            let n = v2(-e.y, e.x);
            let (amin, amax) = project(a, n);
            let (bmin, bmax) = project(b, n);
            if amax <= bmin + EPS || bmax <= amin + EPS {
                return false;
            }
        }
    }
    true
}

fn project(p: &[V2], n: V2) -> (f64, f64) {
    p.iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), q| {
            let d = q.dot(n);
            (lo.min(d), hi.max(d))
        })
}

/// Distance from `c` to the convex polygon `poly` (0 inside).
#[inline]
pub fn point_polygon_distance(c: V2, poly: &[V2]) -> f64 {
    let inside = (0..poly.len()).all(|i| {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        (b - a).cross(c - a) >= 0.0
    });
    if inside {
        return 0.0;
    }
    (0..poly.len())
        .map(|i| point_segment_distance(c, poly[i], poly[(i + 1) % poly.len()]))
        .fold(f64::INFINITY, f64::min)
}

/// True when segments `a`–`b` and `c`–`d` cross.
#[inline]
pub fn segments_cross(a: V2, b: V2, c: V2, d: V2) -> bool {
    let d1 = (b - a).cross(c - a);
    let d2 = (b - a).cross(d - a);
    let d3 = (d - c).cross(a - c);
    let d4 = (d - c).cross(b - c);
    (d1 * d2 < 0.0) && (d3 * d4 < 0.0)
}

/// The rectangle of `size` (length along `yaw`, width) centred on `c`, counter-clockwise.
#[inline]
pub fn rectangle(c: V2, yaw: f64, size: (f64, f64)) -> [V2; 4] {
    let (d, s) = (V2::polar(yaw), v2(-yaw.sin(), yaw.cos()));
    let (l, w) = (size.0 / 2.0, size.1 / 2.0);
    [(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)].map(|(a, b)| c + d * (a * l) + s * (b * w))
}

/// An obstacle's footprint (a convex polygon, counter-clockwise) grown by a foot of `size`
/// turned to `yaw`: the places of the foot's centre at which its sole overlaps the footprint
/// (their Minkowski sum), counter-clockwise. A foothold check at that yaw is then a point test.
pub fn foot_cspace(footprint: &[V2], size: (f64, f64), yaw: f64) -> Vec<V2> {
    let foot = rectangle(v2(0.0, 0.0), yaw, size);
    let sums: Vec<V2> = footprint
        .iter()
        .flat_map(|&p| foot.iter().map(move |&q| p - q))
        .collect();
    convex_hull(sums)
}

/// The convex hull of a point set, counter-clockwise (Andrew's monotone chain).
pub fn convex_hull(mut pts: Vec<V2>) -> Vec<V2> {
    pts.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    pts.dedup_by(|a, b| a.dist(*b) < 1e-12);
    if pts.len() < 3 {
        return pts;
    }
    let half = |it: &mut dyn Iterator<Item = &V2>| {
        let mut h: Vec<V2> = Vec::new();
        for &p in it {
            while h.len() >= 2 && (h[h.len() - 1] - h[h.len() - 2]).cross(p - h[h.len() - 2]) <= 0.0
            {
                h.pop();
            }
            h.push(p);
        }
        h.pop();
        h
    };
    let mut lower = half(&mut pts.iter());
    lower.extend(half(&mut pts.iter().rev()));
    lower
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tangents_and_distances() {
        let c = Circle {
            c: v2(2.0, 0.0),
            r: 0.6,
        };
        let [left, right] = c.tangent_points(v2(0.0, 0.0)).unwrap();
        assert!(
            (left.x - 1.82).abs() < 1e-3 && (left.y - 0.5724).abs() < 1e-4,
            "{left:?}"
        );
        assert!((right.y + 0.5724).abs() < 1e-4, "{right:?}");
        assert!(c.blocks(v2(0.0, 0.0), v2(4.0, 0.0)));
        assert!(
            !c.blocks(v2(0.0, 0.6), v2(4.0, 0.6)),
            "tangent is not inside"
        );
        assert!(c.tangent_points(v2(2.1, 0.0)).is_none());
        let x = line_intersection(v2(0.0, 0.0), v2(1.0, 1.0), v2(0.0, 2.0), v2(2.0, 0.0)).unwrap();
        assert!((x.x - 1.0).abs() < 1e-12 && (x.y - 1.0).abs() < 1e-12);
        assert!((wrap(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
        assert!((wrap(-1.5 * std::f64::consts::PI) - 0.5 * std::f64::consts::PI).abs() < 1e-12);
    }

    #[test]
    fn polygons() {
        let sq = [v2(0.0, 0.0), v2(1.0, 0.0), v2(1.0, 1.0), v2(0.0, 1.0)];
        let moved = |dx: f64| sq.map(|p| p + v2(dx, 0.3));
        assert!(convex_overlap(&sq, &moved(0.5)));
        assert!(
            !convex_overlap(&sq, &moved(1.0)),
            "touching is not overlapping"
        );
        assert!(!convex_overlap(&sq, &moved(1.5)));
        assert_eq!(point_polygon_distance(v2(0.5, 0.5), &sq), 0.0);
        assert!((point_polygon_distance(v2(2.0, 0.5), &sq) - 1.0).abs() < 1e-12);
        assert!(segments_cross(
            v2(-1.0, 0.5),
            v2(2.0, 0.5),
            v2(0.5, -1.0),
            v2(0.5, 2.0)
        ));
        assert!(!segments_cross(
            v2(-1.0, 3.0),
            v2(2.0, 3.0),
            v2(0.5, -1.0),
            v2(0.5, 2.0)
        ));
    }
}
