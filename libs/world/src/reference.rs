//! A reference for graders of the circle planners, sharing no code with them: the shortest
//! path among convex polygons by a visibility graph and Dijkstra. Among polygons inscribed in
//! the circles it is a lower bound of the optimum among the circles (and no way there means
//! no way at all); among polygons circumscribed about them, an upper bound (a way there is a
//! way among the circles).

/// A point.
pub type P = (f64, f64);

/// The regular `n`-gon inscribed in (`scale` = 1) or circumscribed about (`scale` =
/// 1/cos(π/n)) the circle of centre `c` and radius `r`, counter-clockwise.
pub fn polygon(c: P, r: f64, n: usize, scale: f64) -> Vec<P> {
    (0..n)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / n as f64;
            (c.0 + r * scale * a.cos(), c.1 + r * scale * a.sin())
        })
        .collect()
}

/// The polygons of `sides` sides inscribed in each circle (centre, radius) and circumscribed
/// about it.
pub fn inscribed_and_circumscribed(circles: &[(P, f64)], sides: usize) -> [Vec<Vec<P>>; 2] {
    let out = 1.0 / (std::f64::consts::PI / sides as f64).cos();
    [1.0, out].map(|scale| {
        circles
            .iter()
            .map(|&(c, r)| polygon(c, r, sides, scale))
            .collect()
    })
}

/// True when the segment a-b has a stretch of positive length strictly inside the convex,
/// counter-clockwise polygon (clipped against each side's half-plane).
pub fn enters(a: P, b: P, poly: &[P]) -> bool {
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

/// True when `x` lies strictly inside the convex, counter-clockwise polygon.
pub fn point_inside(x: P, poly: &[P]) -> bool {
    (0..poly.len()).all(|k| {
        let (p, q) = (poly[k], poly[(k + 1) % poly.len()]);
        (q.0 - p.0) * (x.1 - p.1) - (q.1 - p.1) * (x.0 - p.0) > 1e-9
    })
}

/// The shortest path from `s` to `g` among the polygons, or `None` when there is none.
///
/// A shortest path among convex polygons bends only at vertices where it touches its polygon
/// from outside (the reduced visibility graph): an edge into a vertex whose two neighbours on
/// its polygon lie strictly on either side of the edge's line is never needed, and is not
/// tried. A polygon whose bounding circle the segment misses is not clipped.
pub fn shortest(s: P, g: P, polys: &[Vec<P>]) -> Option<f64> {
    let inside = |x: P| polys.iter().any(|p| point_inside(x, p));
    // Each node, and the polygon and index it is a vertex of.
    let mut nodes: Vec<(P, Option<(usize, usize)>)> = vec![(s, None), (g, None)];
    for (i, p) in polys.iter().enumerate() {
        nodes.extend(
            p.iter()
                .enumerate()
                .filter(|(_, &v)| !inside(v))
                .map(|(k, &v)| (v, Some((i, k)))),
        );
    }
    // Each polygon's bounding circle.
    let circles: Vec<(P, f64)> = polys
        .iter()
        .map(|p| {
            let n = p.len() as f64;
            let c = (
                p.iter().map(|v| v.0).sum::<f64>() / n,
                p.iter().map(|v| v.1).sum::<f64>() / n,
            );
            let r = p
                .iter()
                .map(|v| (v.0 - c.0).hypot(v.1 - c.1))
                .fold(0.0, f64::max);
            (c, r)
        })
        .collect();
    let near = |a: P, b: P, (c, r): (P, f64)| {
        let d = (b.0 - a.0, b.1 - a.1);
        let l2 = d.0 * d.0 + d.1 * d.1;
        let t = if l2 > 0.0 {
            (((c.0 - a.0) * d.0 + (c.1 - a.1) * d.1) / l2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (a.0 + t * d.0 - c.0).hypot(a.1 + t * d.1 - c.1) < r + 1e-6
    };
    let n = nodes.len();
    let free = |i: usize, j: usize| {
        let (a, b) = (nodes[i].0, nodes[j].0);
        !polys
            .iter()
            .zip(&circles)
            .any(|(p, &c)| near(a, b, c) && enters(a, b, p))
    };
    // Whether the edge from `u` can bend at vertex `v` (it touches v's polygon there).
    let tangent = |u: usize, v: usize| match nodes[v].1 {
        None => true,
        Some((i, k)) => {
            let p = &polys[i];
            let (a, b) = (nodes[u].0, nodes[v].0);
            let side = |x: P| (b.0 - a.0) * (x.1 - a.1) - (b.1 - a.1) * (x.0 - a.0);
            let (l, r) = (
                side(p[(k + p.len() - 1) % p.len()]),
                side(p[(k + 1) % p.len()]),
            );
            !(l > 1e-12 && r < -1e-12 || l < -1e-12 && r > 1e-12)
        }
    };
    let dist = |i: usize, j: usize| {
        let (a, b) = (nodes[i].0, nodes[j].0);
        (a.0 - b.0).hypot(a.1 - b.1)
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
            if !done[v] && best[u] + dist(u, v) < best[v] && tangent(u, v) && free(u, v) {
                best[v] = best[u] + dist(u, v);
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_square_in_the_way_is_gone_round() {
        let square = vec![(1.0, -1.0), (3.0, -1.0), (3.0, 1.0), (1.0, 1.0)];
        let d = shortest((0.0, 0.0), (4.0, 0.0), &[square]).unwrap();
        let want = 2.0 * 2f64.sqrt() + 2.0;
        assert!((d - want).abs() < 1e-9, "{d}");
        // Walled in: no way.
        let ring: Vec<Vec<P>> = (0..12)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / 12.0;
                polygon((4.0 + a.cos(), a.sin()), 0.4, 8, 1.0)
            })
            .collect();
        assert_eq!(shortest((0.0, 0.0), (4.0, 0.0), &ring), None);
    }
}
