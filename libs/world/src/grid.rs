//! A 2.5-D elevation grid (one height per cell, `NaN` for unknown), as the KAIST planner's
//! mapper gives it (seed 004 §B.4: 0.05 m cells), made from a scene: the ground (flat, or an
//! elevation file), steppable surfaces at their heights, and obstacles at their tops. It
//! answers the feasibility questions of the notes' R-F1 (cells under a foot) and R-F2 (cells
//! in the body's swing ellipses), and gives the 2-D distance field around tall cells that the
//! obstacle-aware heuristic uses (R-S3).

use std::collections::BinaryHeap;

use crate::geom::{point_polygon_distance, v2, V2};
use crate::scene::Scene;
use crate::Least;

/// Margin around the scene's bounding box when it gives no map, m.
pub const MARGIN: f64 = 1.5;

/// How much longer than a straight line a way along 16-neighbour grid moves can be: the
/// directions are at most 26.57° apart, so 1/cos(13.28°).
pub const GRID_DETOUR: f64 = 1.0275;

/// The 16 moves of the distance fields: to the 8 neighbours and the 8 knight's moves.
const MOVES: [(i64, i64); 16] = [
    (1, 0),
    (-1, 0),
    (0, 1),
    (0, -1),
    (1, 1),
    (-1, -1),
    (1, -1),
    (-1, 1),
    (2, 1),
    (-2, -1),
    (1, 2),
    (-1, -2),
    (2, -1),
    (-2, 1),
    (1, -2),
    (-1, 2),
];

/// An elevation grid.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    /// Corner of cell (0, 0) (least x and y), m.
    pub origin: V2,
    /// Cell size, m.
    pub res: f64,
    /// Cells along x.
    pub nx: usize,
    /// Cells along y.
    pub ny: usize,
    /// Heights, row by row from the least y (`NaN`: unknown; infinite: an obstacle of no
    /// given height).
    pub h: Vec<f64>,
}

/// Why a scene's grid cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum GridError {
    /// The elevation file cannot be read.
    #[error("elevation file {path}: {error}")]
    Io {
        /// The file.
        path: String,
        /// What went wrong.
        error: std::io::Error,
    },
    /// The grid would be too large (or its extent is not finite).
    #[error("a map of {x:?} x {y:?} m at {res} m would have {cells:.0} cells, more than the {max} allowed")]
    TooLarge {
        /// Its x extent.
        x: [f64; 2],
        /// Its y extent.
        y: [f64; 2],
        /// Its resolution.
        res: f64,
        /// The cells it would have (infinite or NaN when the extent is not finite).
        cells: f64,
        /// [`Grid::MAX_CELLS`].
        max: usize,
    },
    /// The elevation file is malformed.
    #[error("elevation file {path}, line {line}: {why}")]
    Format {
        /// The file.
        path: String,
        /// Its line (1-based).
        line: usize,
        /// What is wrong.
        why: String,
    },
}

impl Grid {
    /// The most cells a grid may have (32 MB of heights: 100 m x 100 m at 0.05 m).
    pub const MAX_CELLS: usize = 4_000_000;

    /// The cells a grid over `x` × `y` at `res` would have (not finite for an extent that is
    /// not).
    pub fn cells_for(x: [f64; 2], y: [f64; 2], res: f64) -> f64 {
        let n = |a: f64, b: f64| ((b - a) / res).round().max(1.0);
        n(x[0], x[1]) * n(y[0], y[1])
    }

    /// Flat ground at height 0 over `x` × `y`; refused beyond [`Grid::MAX_CELLS`] cells or
    /// for an extent that is not finite.
    pub fn flat(x: [f64; 2], y: [f64; 2], res: f64) -> Result<Grid, GridError> {
        let cells = Grid::cells_for(x, y, res);
        if !(cells.is_finite() && res > 0.0 && cells <= Grid::MAX_CELLS as f64) {
            return Err(GridError::TooLarge {
                x,
                y,
                res,
                cells,
                max: Grid::MAX_CELLS,
            });
        }
        let n = |a: f64, b: f64| ((b - a) / res).round().max(1.0) as usize;
        let (nx, ny) = (n(x[0], x[1]), n(y[0], y[1]));
        Ok(Grid {
            origin: v2(x[0], y[0]),
            res,
            nx,
            ny,
            h: vec![0.0; nx * ny],
        })
    }

    /// The grid of a scene: its map (or its bounding box grown by [`MARGIN`]) at its
    /// resolution (0.05 m by default), the elevation file or flat ground, then the surfaces,
    /// then the obstacles' tops over their footprints.
    pub fn of_scene(scene: &Scene) -> Result<Grid, GridError> {
        let (x, y, res) = Grid::extent_of(scene);
        let mut g = Grid::flat(x, y, res)?;
        if let Some(file) = scene.map.as_ref().and_then(|m| m.elevation.as_ref()) {
            let path = scene.dir.join(file);
            g.load_elevation(&path)?;
        }
        let bounds = |poly: &[V2]| {
            poly.iter()
                .fold((poly[0], poly[0]), |(lo, hi), &p| (lo.min(p), hi.max(p)))
        };
        for s in &scene.surface {
            let poly = s.polygon();
            let (lo, hi) = bounds(&poly);
            g.paint_in(
                lo,
                hi,
                |p| point_polygon_distance(p, &poly) == 0.0,
                |_| s.height,
            );
        }
        for o in &scene.obstacle {
            let top = o.top();
            match o.polygon() {
                Some(poly) => {
                    let (lo, hi) = bounds(&poly);
                    g.paint_in(
                        lo,
                        hi,
                        |p| point_polygon_distance(p, &poly) == 0.0,
                        |h| h.max(top),
                    )
                }
                None => {
                    let c = o.bounding_circle();
                    let r = v2(c.r, c.r);
                    g.paint_in(c.c - r, c.c + r, |p| c.contains(p), |h| h.max(top))
                }
            }
        }
        Ok(g)
    }

    /// The extent and cell of a scene's grid: its map (or its bounding box grown by
    /// [`MARGIN`]) and resolution (0.05 m by default).
    pub fn extent_of(scene: &Scene) -> ([f64; 2], [f64; 2], f64) {
        let res = scene
            .map
            .as_ref()
            .and_then(|m| m.resolution)
            .unwrap_or(0.05);
        let (x, y) = match &scene.map {
            Some(m) => (m.x, m.y),
            None => {
                let mut lo = scene.start.p().min(scene.goal.p());
                let mut hi = scene.start.p().max(scene.goal.p());
                for o in &scene.obstacle {
                    let c = o.bounding_circle();
                    lo = lo.min(c.c - v2(c.r, c.r));
                    hi = hi.max(c.c + v2(c.r, c.r));
                }
                for s in &scene.surface {
                    for p in s.polygon() {
                        lo = lo.min(p);
                        hi = hi.max(p);
                    }
                }
                (
                    [lo.x - MARGIN, hi.x + MARGIN],
                    [lo.y - MARGIN, hi.y + MARGIN],
                )
            }
        };
        (x, y, res)
    }

    fn load_elevation(&mut self, path: &std::path::Path) -> Result<(), GridError> {
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|error| GridError::Io {
            path: name.clone(),
            error,
        })?;
        let rows: Vec<&str> = text
            .lines()
            .filter(|l| !l.trim().is_empty() && !l.trim_start().starts_with('#'))
            .collect();
        let bad = |line: usize, why: String| GridError::Format {
            path: name.clone(),
            line,
            why,
        };
        if rows.len() != self.ny {
            return Err(bad(
                rows.len(),
                format!("{} rows; the map's extent needs {}", rows.len(), self.ny),
            ));
        }
        for (k, row) in rows.iter().enumerate() {
            let j = self.ny - 1 - k;
            let cells: Vec<&str> = row.split(',').map(str::trim).collect();
            if cells.len() != self.nx {
                return Err(bad(
                    k + 1,
                    format!(
                        "{} columns; the map's extent needs {}",
                        cells.len(),
                        self.nx
                    ),
                ));
            }
            for (i, c) in cells.iter().enumerate() {
                let v = if c.eq_ignore_ascii_case("nan") {
                    f64::NAN
                } else {
                    c.parse::<f64>()
                        .map_err(|e| bad(k + 1, format!("column {}: {e}", i + 1)))?
                };
                self.h[j * self.nx + i] = v;
            }
        }
        Ok(())
    }

    /// Sets every cell whose centre satisfies `inside` to `f(its height)`.
    pub fn paint(&mut self, inside: impl Fn(V2) -> bool, f: impl Fn(f64) -> f64) {
        for j in 0..self.ny {
            for i in 0..self.nx {
                if inside(self.centre(i, j)) {
                    let k = j * self.nx + i;
                    self.h[k] = f(self.h[k]);
                }
            }
        }
    }

    /// Like [`Grid::paint`], looking only at the cells whose centres lie in `lo`..`hi`.
    pub fn paint_in(
        &mut self,
        lo: V2,
        hi: V2,
        inside: impl Fn(V2) -> bool,
        f: impl Fn(f64) -> f64,
    ) {
        let i0 = (((lo.x - self.origin.x) / self.res - 0.5).ceil()).max(0.0) as usize;
        let j0 = (((lo.y - self.origin.y) / self.res - 0.5).ceil()).max(0.0) as usize;
        let i1 = ((hi.x - self.origin.x) / self.res - 0.5).floor();
        let j1 = ((hi.y - self.origin.y) / self.res - 0.5).floor();
        if i1 < 0.0 || j1 < 0.0 {
            return;
        }
        let (i1, j1) = (
            (i1 as usize).min(self.nx - 1),
            (j1 as usize).min(self.ny - 1),
        );
        for j in j0..=j1 {
            for i in i0..=i1 {
                if inside(self.centre(i, j)) {
                    let k = j * self.nx + i;
                    self.h[k] = f(self.h[k]);
                }
            }
        }
    }

    /// The centre of cell (i, j).
    #[inline]
    pub fn centre(&self, i: usize, j: usize) -> V2 {
        self.origin + v2((i as f64 + 0.5) * self.res, (j as f64 + 0.5) * self.res)
    }

    /// The cell holding `p`, if inside the map.
    #[inline]
    pub fn cell(&self, p: V2) -> Option<(usize, usize)> {
        let q = (p - self.origin) * (1.0 / self.res);
        if !(q.x >= 0.0 && q.y >= 0.0 && q.x.is_finite() && q.y.is_finite()) {
            return None;
        }
        let (i, j) = (q.x as usize, q.y as usize);
        (i < self.nx && j < self.ny).then_some((i, j))
    }

    /// True when `p` is on the map.
    #[inline]
    pub fn contains(&self, p: V2) -> bool {
        self.cell(p).is_some()
    }

    /// The height at `p` (`NaN` off the map or unknown).
    #[inline]
    pub fn height(&self, p: V2) -> f64 {
        self.cell(p)
            .map_or(f64::NAN, |(i, j)| self.h[j * self.nx + i])
    }

    /// The highest cell whose centre lies in the rectangle of `size` (length along `yaw`,
    /// width) centred on `c`, grown by `margin` on every side: `NaN` if one is unknown,
    /// `None` when part of the rectangle is off the map, `-inf` when no centre lies in it.
    #[inline]
    pub fn max_in_rect(&self, c: V2, yaw: f64, size: (f64, f64), margin: f64) -> Option<f64> {
        let (d, s) = (V2::polar(yaw), v2(-yaw.sin(), yaw.cos()));
        let (hl, hw) = (size.0 / 2.0 + margin, size.1 / 2.0 + margin);
        let ext = v2(
            (d.x * hl).abs() + (s.x * hw).abs(),
            (d.y * hl).abs() + (s.y * hw).abs(),
        );
        self.max_in_box(c - ext, c + ext, |p| {
            let r = p - c;
            r.dot(d).abs() <= hl && r.dot(s).abs() <= hw
        })
    }

    /// The highest cell whose centre lies in the ellipse with the segment a-b as its axis,
    /// grown by `along` at each end, `across` wide on each side (see [`Grid::max_in_rect`]).
    #[inline]
    pub fn max_in_ellipse(&self, a: V2, b: V2, along: f64, across: f64) -> Option<f64> {
        let c = (a + b) * 0.5;
        let len = a.dist(b);
        let d = if len > 1e-12 {
            (b - a) * (1.0 / len)
        } else {
            v2(1.0, 0.0)
        };
        let s = v2(-d.y, d.x);
        let (ra, rb) = (len / 2.0 + along, across);
        let ext = v2(
            ((ra * d.x).powi(2) + (rb * s.x).powi(2)).sqrt(),
            ((ra * d.y).powi(2) + (rb * s.y).powi(2)).sqrt(),
        );
        let (ia, ib) = (1.0 / (ra * ra), 1.0 / (rb * rb));
        self.max_in_box(c - ext, c + ext, |p| {
            let q = p - c;
            q.dot(d).powi(2) * ia + q.dot(s).powi(2) * ib <= 1.0
        })
    }

    fn max_in_box(&self, lo: V2, hi: V2, keep: impl Fn(V2) -> bool) -> Option<f64> {
        // Cells whose centres lie in [lo, hi]: from ceil((lo - o)/res - 0.5) to
        // floor((hi - o)/res - 0.5).
        let i0 = ((lo.x - self.origin.x) / self.res - 0.5).ceil();
        let j0 = ((lo.y - self.origin.y) / self.res - 0.5).ceil();
        let i1 = ((hi.x - self.origin.x) / self.res - 0.5).floor();
        let j1 = ((hi.y - self.origin.y) / self.res - 0.5).floor();
        // Written so that NaN bounds fail too.
        if !(i0 >= 0.0 && j0 >= 0.0 && i1 < self.nx as f64 && j1 < self.ny as f64) {
            return None;
        }
        let mut top = f64::NEG_INFINITY;
        if i1 < i0 || j1 < j0 {
            return Some(top);
        }
        for j in j0 as usize..=j1 as usize {
            let row = &self.h[j * self.nx..(j + 1) * self.nx];
            for (i, &h) in row
                .iter()
                .enumerate()
                .take(i1 as usize + 1)
                .skip(i0 as usize)
            {
                if (h > top || h.is_nan()) && keep(self.centre(i, j)) {
                    if h.is_nan() {
                        return Some(f64::NAN);
                    }
                    top = h;
                }
            }
        }
        Some(top)
    }

    /// Down a distance field from `p`: the cell [`Grid::way`] reaches once the distance has
    /// dropped by `ahead` (or the goal's), if `p` is on the map and reaches the goal.
    #[inline]
    pub fn descent(&self, field: &[f64], p: V2, ahead: f64) -> Option<V2> {
        let way = self.way(field, p, ahead);
        let k0 = *way.first()?;
        let k = way
            .iter()
            .copied()
            .find(|&k| field[k0] - field[k] >= ahead)
            .or(way.last().copied())?;
        (k != k0).then(|| self.centre(k % self.nx, k / self.nx))
    }

    /// Distances from every cell to `goal` along 16-connected moves (Euclidean lengths)
    /// through cells that `passable` accepts; infinite where no such path is. Row by row from
    /// the least y, as [`Grid::h`].
    pub fn distance_field(&self, goal: V2, passable: impl Fn(f64) -> bool) -> Vec<f64> {
        match self.cell(goal) {
            Some((gi, gj)) => self.distance_from(&[gj * self.nx + gi], passable),
            None => vec![f64::INFINITY; self.nx * self.ny],
        }
    }

    /// The cells from `from` down a distance field, each the steepest of the 16 moves (the
    /// largest drop per metre), to its zero or until the distance has dropped by `drop`; empty
    /// when `from` is off the map or cannot reach the zero.
    pub fn way(&self, field: &[f64], from: V2, drop: f64) -> Vec<usize> {
        let Some((i, j)) = self.cell(from) else {
            return Vec::new();
        };
        let mut k = j * self.nx + i;
        if !field[k].is_finite() {
            return Vec::new();
        }
        let mut out = vec![k];
        let top = field[k];
        while field[k] > 0.0 && top - field[k] < drop {
            let (ci, cj) = ((k % self.nx) as i64, (k / self.nx) as i64);
            // The steepest of the 16 moves: the largest drop per metre.
            let mut next = (0.0, k);
            for &(a, b) in &MOVES {
                let (x, y) = (ci + a, cj + b);
                if x >= 0 && y >= 0 && (x as usize) < self.nx && (y as usize) < self.ny {
                    let nk = y as usize * self.nx + x as usize;
                    let slope = (field[k] - field[nk]) / ((a * a + b * b) as f64).sqrt();
                    if slope > next.0 {
                        next = (slope, nk);
                    }
                }
            }
            if next.1 == k {
                break;
            }
            k = next.1;
            out.push(k);
        }
        out
    }

    /// Distances from every cell to the nearest of the cells `sources` along 16-connected
    /// moves through cells that `passable` accepts (see [`Grid::distance_field`]).
    pub fn distance_from(&self, sources: &[usize], passable: impl Fn(f64) -> bool) -> Vec<f64> {
        let mut dist = vec![f64::INFINITY; self.nx * self.ny];
        let moves: Vec<(i64, i64, f64)> = MOVES
            .iter()
            .map(|&(a, b)| (a, b, ((a * a + b * b) as f64).sqrt() * self.res))
            .collect();
        let mut heap = BinaryHeap::new();
        for &k in sources {
            dist[k] = 0.0;
            heap.push(Least(0.0, k));
        }
        while let Some(Least(d, k)) = heap.pop() {
            if d > dist[k] {
                continue;
            }
            let (i, j) = ((k % self.nx) as i64, (k / self.nx) as i64);
            for &(a, b, len) in &moves {
                let (ni, nj) = (i + a, j + b);
                if ni < 0 || nj < 0 || ni >= self.nx as i64 || nj >= self.ny as i64 {
                    continue;
                }
                let nk = nj as usize * self.nx + ni as usize;
                if !passable(self.h[nk]) {
                    continue;
                }
                if d + len < dist[nk] {
                    dist[nk] = d + len;
                    heap.push(Least(d + len, nk));
                }
            }
        }
        dist
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_and_heights() {
        let mut g = Grid::flat([0.0, 1.0], [0.0, 0.5], 0.05).unwrap();
        assert_eq!((g.nx, g.ny), (20, 10));
        g.paint(|p| p.x > 0.5, |_| 0.2);
        assert_eq!(g.height(v2(0.52, 0.1)), 0.2);
        assert_eq!(g.height(v2(0.48, 0.1)), 0.0);
        assert!(g.height(v2(1.2, 0.1)).is_nan());
        assert_eq!(
            g.max_in_rect(v2(0.25, 0.25), 0.0, (0.2, 0.1), 0.0),
            Some(0.0)
        );
        assert_eq!(
            g.max_in_rect(v2(0.45, 0.25), 0.0, (0.2, 0.1), 0.0),
            Some(0.2)
        );
        assert_eq!(
            g.max_in_rect(v2(0.40, 0.25), 0.3, (0.2, 0.1), 0.0),
            Some(0.0)
        );
        assert!(g
            .max_in_rect(v2(0.98, 0.25), 0.0, (0.2, 0.1), 0.0)
            .is_none());
        assert_eq!(
            g.max_in_ellipse(v2(0.3, 0.25), v2(0.7, 0.25), 0.0, 0.06),
            Some(0.2)
        );
        assert_eq!(
            g.max_in_ellipse(v2(0.1, 0.25), v2(0.4, 0.25), 0.0, 0.06),
            Some(0.0)
        );
        g.h[5 * 20 + 3] = f64::NAN;
        assert!(g
            .max_in_rect(v2(0.15, 0.27), 0.0, (0.2, 0.1), 0.0)
            .unwrap()
            .is_nan());
    }

    #[test]
    fn distance_field_goes_around_a_wall() {
        let mut g = Grid::flat([0.0, 4.0], [-2.0, 2.0], 0.05).unwrap();
        g.paint(|p| (1.5..1.8).contains(&p.x) && p.y.abs() < 1.0, |_| 1.0);
        let d = g.distance_field(v2(3.5, 0.0), |h| h < 0.15);
        let at = |p: V2| {
            let (i, j) = g.cell(p).unwrap();
            d[j * g.nx + i]
        };
        // Straight: 3.5 m in the open; behind the wall, at least around its end.
        let free = at(v2(3.0, 1.5));
        assert!((free - 0.5f64.hypot(1.5)).abs() < 0.06, "{free}");
        let around = v2(0.0, 0.0).dist(v2(1.5, 1.0)) + v2(1.8, 1.0).dist(v2(3.5, 0.0)) + 0.3;
        let got = at(v2(0.0, 0.0));
        assert!(
            got >= around * 0.98 && got < around * 1.05,
            "{got} vs {around}"
        );
        // The way down it: field moves only, each going down, round the wall to the goal, no
        // longer than the field says.
        let way = g.way(&d, v2(0.0, 0.0), f64::INFINITY);
        assert_eq!(d[*way.last().unwrap()], 0.0);
        let mut length = 0.0;
        for w in way.windows(2) {
            let (a, b) = (w[0], w[1]);
            let (da, db) = (
                (b % g.nx) as i64 - (a % g.nx) as i64,
                (b / g.nx) as i64 - (a / g.nx) as i64,
            );
            assert!(MOVES.contains(&(da, db)), "{da}, {db}");
            assert!(d[b] < d[a]);
            assert!(g.h[b] < 0.15, "through the wall");
            length += ((da * da + db * db) as f64).sqrt() * g.res;
        }
        assert!((length - got).abs() < 1e-9, "{length} vs {got}");
        // Steepest first: out in the open it heads straight for the goal.
        let open = g.way(&d, v2(2.5, 0.0), 0.3);
        let (a, b) = (open[0], open[1]);
        assert_eq!((b % g.nx, b / g.nx), (a % g.nx + 1, a / g.nx));
    }
}
