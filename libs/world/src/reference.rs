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
pub fn shortest(s: P, g: P, polys: &[Vec<P>]) -> Option<f64> {
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
