//! The geometry against dense sampling: the SSV distances (the notes' G1: the exact core
//! distance is never above the least sampled one, and the samples come within their spacing
//! of it; closest points lie on the solids at that distance; the gradient matches a finite
//! difference), boxes against the exact distance, and the foot's configuration space of a
//! footprint against placing the sole.

use proptest::prelude::*;
use stride_world::geom::{
    convex_hull, convex_overlap, foot_cspace, point_polygon_distance, point_segment_distance,
    rectangle, v2, V2,
};
use stride_world::ssv::{closest_cores, proximity, Core, Solid, P3, V3};

fn pt() -> impl Strategy<Value = P3> {
    (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0).prop_map(|(x, y, z)| P3::new(x, y, z))
}

fn core() -> impl Strategy<Value = Core> {
    prop_oneof![
        pt().prop_map(Core::Point),
        (pt(), pt()).prop_map(|(a, b)| Core::Segment(a, b)),
        (pt(), pt(), pt()).prop_map(|(a, b, c)| Core::Triangle(a, b, c)),
    ]
}

/// Points covering a core, and their spacing.
fn samples(c: &Core, n: usize) -> (Vec<P3>, f64) {
    match *c {
        Core::Point(p) => (vec![p], 0.0),
        Core::Segment(a, b) => (
            (0..=n)
                .map(|i| a + (b - a) * (i as f64 / n as f64))
                .collect(),
            (b - a).norm() / n as f64,
        ),
        Core::Triangle(a, b, c) => {
            let mut v = Vec::new();
            for i in 0..=n {
                for j in 0..=(n - i) {
                    let (u, w) = (i as f64 / n as f64, j as f64 / n as f64);
                    v.push(a + (b - a) * u + (c - a) * w);
                }
            }
            let longest = (b - a).norm().max((c - a).norm()).max((c - b).norm());
            (v, longest / n as f64)
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn core_distance_against_dense_sampling(a in core(), b in core()) {
        let (pa, pb) = closest_cores(&a, &b);
        let exact = (pa - pb).norm();
        let (sa, ha) = samples(&a, 24);
        let (sb, hb) = samples(&b, 24);
        let mut sampled = f64::INFINITY;
        for x in &sa {
            for y in &sb {
                sampled = sampled.min((x - y).norm());
            }
        }
        prop_assert!(exact <= sampled + 1e-9, "exact {exact} above sampled {sampled}");
        prop_assert!(sampled - exact <= ha + hb + 1e-9, "exact {exact}, sampled {sampled}, spacing {ha} {hb}");
        // The closest points lie on their cores: each is its own nearest point of its core.
        let (_, near_a) = closest_cores(&Core::Point(pa), &a);
        let (_, near_b) = closest_cores(&Core::Point(pb), &b);
        prop_assert!((near_a - pa).norm() < 1e-9, "{pa:?} is not on {a:?}");
        prop_assert!((near_b - pb).norm() < 1e-9, "{pb:?} is not on {b:?}");
    }

    #[test]
    fn signed_distance_closest_points_and_gradient(
        a in core(), b in core(), ra in 0.0f64..0.3, rb in 0.0f64..0.3,
        d in (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0),
    ) {
        let (sa, sb) = (Solid::Ssv { core: a, radius: ra }, Solid::Ssv { core: b, radius: rb });
        let pr = proximity(&sa, &sb);
        let (ca, cb) = closest_cores(&a, &b);
        prop_assert!((pr.distance - ((ca - cb).norm() - ra - rb)).abs() < 1e-12);
        prop_assert!(((pr.on_a - pr.on_b).norm() - pr.distance.abs()).abs() < 1e-9);
        // Where the cores are apart, moving the first solid a little along any direction
        // changes the distance by the gradient's share of the move.
        if (ca - cb).norm() > 1e-3 {
            let step = V3::new(d.0, d.1, d.2) * 1e-7;
            let moved = match a {
                Core::Point(p) => Core::Point(p + step),
                Core::Segment(p, q) => Core::Segment(p + step, q + step),
                Core::Triangle(p, q, r) => Core::Triangle(p + step, q + step, r + step),
            };
            let after = proximity(&Solid::Ssv { core: moved, radius: ra }, &sb).distance;
            let predicted = pr.distance + pr.gradient.dot(&step);
            prop_assert!((after - predicted).abs() < 1e-9, "{after} vs {predicted}");
        }
    }

    #[test]
    fn sphere_and_box_against_the_exact_distance(
        c in pt(), r in 0.0f64..0.3, yaw in -3.0f64..3.0,
        h in (0.05f64..0.8, 0.05f64..0.8, 0.05f64..0.8),
    ) {
        let half = V3::new(h.0, h.1, h.2);
        let centre = P3::new(0.1, -0.2, 0.3);
        let bx = Solid::Box { centre, yaw, half };
        let pr = proximity(&Solid::sphere(c, r), &bx);
        // The point in the box's frame.
        let q = c - centre;
        let (s, co) = yaw.sin_cos();
        let local = V3::new(co * q.x + s * q.y, -s * q.x + co * q.y, q.z);
        let out = V3::new(
            (local.x.abs() - half.x).max(0.0),
            (local.y.abs() - half.y).max(0.0),
            (local.z.abs() - half.z).max(0.0),
        );
        let inside = (local.x.abs() - half.x).max(local.y.abs() - half.y).max(local.z.abs() - half.z);
        let exact = if inside > 0.0 { out.norm() } else { inside } - r;
        prop_assert!((pr.distance - exact).abs() < 1e-6, "{} vs {exact}", pr.distance);
    }
}

/// A random convex polygon: the hull of a few points.
fn convex() -> impl Strategy<Value = Vec<V2>> {
    prop::collection::vec((-0.5f64..0.5, -0.5f64..0.5), 3..8).prop_filter_map(
        "a polygon with area",
        |pts| {
            let hull = convex_hull(pts.into_iter().map(|(x, y)| v2(x, y)).collect());
            let area: f64 = (0..hull.len())
                .map(|i| hull[i].cross(hull[(i + 1) % hull.len()]))
                .sum();
            (hull.len() >= 3 && area > 1e-3).then_some(hull)
        },
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(100))]

    /// The foot's configuration space of a footprint: over a dense grid of foot centres, a
    /// centre is inside it exactly when the turned sole overlaps the footprint (away from its
    /// border, where the overlap test's tolerance of a micrometre decides).
    #[test]
    fn foot_cspace_against_dense_sampling(poly in convex(), yaw in -3.2f64..3.2) {
        let size = (0.22, 0.12);
        let cs = foot_cspace(&poly, size, yaw);
        let border = |p: V2| {
            (0..cs.len())
                .map(|i| point_segment_distance(p, cs[i], cs[(i + 1) % cs.len()]))
                .fold(f64::INFINITY, f64::min)
        };
        let inside = |p: V2| point_polygon_distance(p, &cs) == 0.0;
        for i in 0..40 {
            for j in 0..40 {
                let p = v2(-1.0 + i as f64 * 0.05, -1.0 + j as f64 * 0.05);
                if border(p) < 1e-5 {
                    continue;
                }
                let sole = rectangle(p, yaw, size);
                prop_assert_eq!(inside(p), convex_overlap(&sole, &poly), "{:?}", p);
            }
        }
    }
}
