//! Support polygons and the ZMP's margin in them: a sole is a rectangle about its footstep
//! (the sole's centre, as `stride.foot_t` gives it); in single support the polygon is the
//! stance sole, in double support the convex hull of both. The margin of a point is its
//! signed distance to the polygon's boundary: positive inside, negative outside.

use serde::Deserialize;

/// A point or vector in the ground plane, m.
pub type P2 = [f64; 2];

/// A sole's size, m.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sole {
    /// Along the foot.
    pub length: f64,
    /// Across the foot.
    pub width: f64,
}

/// A foot on the ground: its sole's centre and heading.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Pose2 {
    /// Sole centre, m.
    pub p: P2,
    /// Heading, rad.
    pub yaw: f64,
}

impl Pose2 {
    /// A point of the foot's frame (x along the foot, y to its left) in the ground frame.
    pub fn apply(&self, q: P2) -> P2 {
        let (s, c) = self.yaw.sin_cos();
        [
            self.p[0] + c * q[0] - s * q[1],
            self.p[1] + s * q[0] + c * q[1],
        ]
    }
}

impl Sole {
    /// The sole's corners on the ground, counter-clockwise.
    pub fn corners(&self, at: &Pose2) -> [P2; 4] {
        let (l, w) = (self.length / 2.0, self.width / 2.0);
        [[l, w], [-l, w], [-l, -w], [l, -w]].map(|q| at.apply(q))
    }
}

fn cross(o: P2, a: P2, b: P2) -> f64 {
    (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
}

/// The convex hull of `points`, counter-clockwise, without collinear points (Andrew's
/// monotone chain).
pub fn hull(points: &[P2]) -> Vec<P2> {
    let mut pts: Vec<P2> = points.to_vec();
    pts.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    pts.dedup();
    if pts.len() < 3 {
        return pts;
    }
    let mut lower: Vec<P2> = Vec::new();
    for &p in &pts {
        while lower.len() >= 2 && cross(lower[lower.len() - 2], lower[lower.len() - 1], p) <= 0.0 {
            lower.pop();
        }
        lower.push(p);
    }
    let mut upper: Vec<P2> = Vec::new();
    for &p in pts.iter().rev() {
        while upper.len() >= 2 && cross(upper[upper.len() - 2], upper[upper.len() - 1], p) <= 0.0 {
            upper.pop();
        }
        upper.push(p);
    }
    lower.pop();
    upper.pop();
    lower.extend(upper);
    lower
}

fn seg_dist(p: P2, a: P2, b: P2) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    ((p[0] - a[0] - t * dx).powi(2) + (p[1] - a[1] - t * dy).powi(2)).sqrt()
}

/// The signed distance of `p` to the boundary of the convex polygon `poly`
/// (counter-clockwise): positive inside, negative outside, 0 on it. A polygon of fewer than
/// three corners has no inside.
pub fn margin(poly: &[P2], p: P2) -> f64 {
    let n = poly.len();
    if n == 0 {
        return f64::NEG_INFINITY;
    }
    let d = (0..n)
        .map(|i| seg_dist(p, poly[i], poly[(i + 1) % n]))
        .fold(f64::INFINITY, f64::min);
    let inside = n >= 3 && (0..n).all(|i| cross(poly[i], poly[(i + 1) % n], p) >= 0.0);
    if inside {
        d
    } else {
        -d
    }
}

/// The support polygon of the feet on the ground: one sole, or the hull of two.
pub fn polygon(sole: &Sole, feet: &[Pose2]) -> Vec<P2> {
    let corners: Vec<P2> = feet.iter().flat_map(|f| sole.corners(f)).collect();
    hull(&corners)
}

#[cfg(test)]
mod tests {
    use super::*;

    const SOLE: Sole = Sole {
        length: 0.22,
        width: 0.06,
    };

    #[test]
    fn a_sole_centre_has_half_the_width_as_its_margin() {
        let f = Pose2 {
            p: [1.0, 2.0],
            yaw: 0.7,
        };
        let poly = polygon(&SOLE, &[f]);
        assert_eq!(poly.len(), 4);
        assert!((margin(&poly, f.p) - 0.03).abs() < 1e-12);
        // 4 cm to the foot's left is 1 cm outside.
        let out = f.apply([0.0, 0.04]);
        assert!((margin(&poly, out) + 0.01).abs() < 1e-12);
    }

    #[test]
    fn double_support_is_the_hull_of_both_soles() {
        let l = Pose2 {
            p: [0.0, 0.1],
            yaw: 0.0,
        };
        let r = Pose2 {
            p: [0.3, -0.1],
            yaw: 0.0,
        };
        let poly = polygon(&SOLE, &[l, r]);
        assert_eq!(poly.len(), 6);
        // The midpoint between the feet is inside, though on neither sole.
        let mid = [0.15, 0.0];
        assert!(margin(&poly, mid) > 0.02);
        assert!(margin(&polygon(&SOLE, &[l]), mid) < 0.0);
    }
}
