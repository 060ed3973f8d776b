//! Scenes: where a planner starts, where it goes, and what is in the way, as TOML files
//! (`config/scenes/`).
//!
//! ```toml
//! name = "archie-03"
//! description = "Archie, case 3 (thesis fig. 87)"
//! start = { x = 0.0, y = 0.0, yaw = 0.0 }
//! goal = { x = 4.0, y = 0.0 }
//!
//! [[obstacle]]
//! shape = "circle"
//! x = 1.0
//! y = 1.0
//! radius = 0.5
//! ```

use crate::geom::{convex_hull, v2, Circle, V2};

/// A pose in the plane.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pose {
    /// x, m.
    pub x: f64,
    /// y, m.
    pub y: f64,
    /// Heading, rad.
    #[serde(default)]
    pub yaw: f64,
    /// Height of the ground under it, m.
    #[serde(default)]
    pub z: f64,
}

impl Pose {
    /// The position.
    #[inline]
    pub fn p(&self) -> V2 {
        v2(self.x, self.y)
    }
}

/// An obstacle.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(tag = "shape", rename_all = "snake_case", deny_unknown_fields)]
pub enum Obstacle {
    /// An upright cylinder.
    Circle {
        /// Centre x, m.
        x: f64,
        /// Centre y, m.
        y: f64,
        /// Radius, m.
        radius: f64,
        /// Height, m (infinite when absent).
        #[serde(default)]
        height: Option<f64>,

        /// Height of its bottom, m (0 when absent; the top is base + height).
        #[serde(default)]
        base: f64,
    },
    /// An upright box.
    Box {
        /// Centre x, m.
        x: f64,
        /// Centre y, m.
        y: f64,
        /// Heading of its length, rad.
        #[serde(default)]
        yaw: f64,
        /// Length (along yaw), m.
        length: f64,
        /// Width, m.
        width: f64,
        /// Height, m (infinite when absent).
        #[serde(default)]
        height: Option<f64>,

        /// Height of its bottom, m (0 when absent; the top is base + height).
        #[serde(default)]
        base: f64,
    },
    /// An extruded convex polygon.
    Polygon {
        /// Corners, m (in any order: their convex hull is the footprint).
        points: Vec<[f64; 2]>,
        /// Height, m (infinite when absent).
        #[serde(default)]
        height: Option<f64>,

        /// Height of its bottom, m (0 when absent; the top is base + height).
        #[serde(default)]
        base: f64,
    },
    /// A sphere (LOLA's swept-sphere primitive of radius r around a point).
    Sphere {
        /// Centre, m.
        centre: [f64; 3],
        /// Radius, m.
        radius: f64,
    },
    /// A capsule: the points within `radius` of the segment a-b.
    Capsule {
        /// One end of the axis, m.
        a: [f64; 3],
        /// The other end, m.
        b: [f64; 3],
        /// Radius, m.
        radius: f64,
    },
    /// A rounded triangle: the points within `radius` of a triangle.
    RoundedTriangle {
        /// The triangle's corners, m.
        points: [[f64; 3]; 3],
        /// Radius, m.
        radius: f64,
    },
}

impl Obstacle {
    /// Every number that describes it (coordinates, sizes, heights).
    pub fn numbers(&self) -> Vec<f64> {
        match self {
            Obstacle::Circle {
                x,
                y,
                radius,
                height,
                base,
            } => [*x, *y, *radius, height.unwrap_or(0.0), *base].to_vec(),
            Obstacle::Box {
                x,
                y,
                yaw,
                length,
                width,
                height,
                base,
            } => [*x, *y, *yaw, *length, *width, height.unwrap_or(0.0), *base].to_vec(),
            Obstacle::Polygon {
                points,
                height,
                base,
            } => points
                .iter()
                .flatten()
                .copied()
                .chain([height.unwrap_or(0.0), *base])
                .collect(),
            Obstacle::Sphere { centre, radius } => {
                centre.iter().copied().chain([*radius]).collect()
            }
            Obstacle::Capsule { a, b, radius } => {
                a.iter().chain(b).copied().chain([*radius]).collect()
            }
            Obstacle::RoundedTriangle { points, radius } => {
                points.iter().flatten().copied().chain([*radius]).collect()
            }
        }
    }

    /// Checks that it is made of finite numbers within `reach` m of the origin (sizes at
    /// most `reach` too): a mapper's glitch (an infinite or huge radius, a NaN centre) is
    /// refused, not planned around.
    pub fn check(&self, reach: f64) -> Result<(), String> {
        for v in self.numbers() {
            if !v.is_finite() {
                return Err(format!("{v} is not a finite number"));
            }
            if v.abs() > reach {
                return Err(format!("{v} is beyond the world's reach of {reach} m"));
            }
        }
        if let Obstacle::Polygon { points, .. } = self {
            if points.len() < 3 {
                return Err(format!("a polygon of {} points", points.len()));
            }
            if points.len() > Obstacle::MAX_POINTS {
                return Err(format!(
                    "a polygon of {} points, more than {}",
                    points.len(),
                    Obstacle::MAX_POINTS
                ));
            }
        }
        for (name, v) in self.sizes() {
            if v < 0.0 {
                return Err(format!("{name} {v}: a size is not negative"));
            }
        }
        Ok(())
    }

    /// The most corners of a polygon.
    pub const MAX_POINTS: usize = 64;

    /// Its sizes, by name (a negative one is refused, never taken as 0).
    fn sizes(&self) -> Vec<(&'static str, f64)> {
        let height = |h: &Option<f64>| h.map(|h| ("height", h));
        match self {
            Obstacle::Circle {
                radius, height: h, ..
            } => [Some(("radius", *radius)), height(h)]
                .into_iter()
                .flatten()
                .collect(),
            Obstacle::Box {
                length,
                width,
                height: h,
                ..
            } => [
                Some(("length", *length)),
                Some(("width", *width)),
                height(h),
            ]
            .into_iter()
            .flatten()
            .collect(),
            Obstacle::Polygon { height: h, .. } => height(h).into_iter().collect(),
            Obstacle::Sphere { radius, .. }
            | Obstacle::Capsule { radius, .. }
            | Obstacle::RoundedTriangle { radius, .. } => vec![("radius", *radius)],
        }
    }

    /// Its footprint as a convex polygon (counter-clockwise), or `None` for a circle or a
    /// sphere. Capsules and rounded triangles come as their hull circumscribed by a 16-gon per
    /// rounded end, so the polygon covers the shape.
    pub fn polygon(&self) -> Option<Vec<V2>> {
        match self {
            Obstacle::Circle { .. } | Obstacle::Sphere { .. } => None,
            Obstacle::Box {
                x,
                y,
                yaw,
                length,
                width,
                ..
            } => {
                let (d, s) = (
                    V2::polar(*yaw),
                    V2::polar(yaw + std::f64::consts::FRAC_PI_2),
                );
                let c = v2(*x, *y);
                Some(
                    [(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)]
                        .iter()
                        .map(|&(a, b)| c + d * (a * length / 2.0) + s * (b * width / 2.0))
                        .collect(),
                )
            }
            // Whatever the order of the corners (or a dent in them), their hull.
            Obstacle::Polygon { points, .. } => {
                Some(convex_hull(points.iter().map(|p| v2(p[0], p[1])).collect()))
            }
            Obstacle::Capsule { a, b, radius } => {
                Some(rounded_hull(&[v2(a[0], a[1]), v2(b[0], b[1])], *radius))
            }
            Obstacle::RoundedTriangle { points, radius } => {
                Some(rounded_hull(&points.map(|p| v2(p[0], p[1])), *radius))
            }
        }
    }

    /// Height of its bottom, m.
    pub fn bottom(&self) -> f64 {
        match self {
            Obstacle::Circle { base, .. }
            | Obstacle::Box { base, .. }
            | Obstacle::Polygon { base, .. } => *base,
            Obstacle::Sphere { centre, radius } => centre[2] - radius,
            Obstacle::Capsule { a, b, radius } => a[2].min(b[2]) - radius,
            Obstacle::RoundedTriangle { points, radius } => {
                points.iter().map(|p| p[2]).fold(f64::INFINITY, f64::min) - radius
            }
        }
    }

    /// Height of its top, m (infinite for an extruded shape of no given height).
    pub fn top(&self) -> f64 {
        match self {
            Obstacle::Circle { base, height, .. }
            | Obstacle::Box { base, height, .. }
            | Obstacle::Polygon { base, height, .. } => base + height.unwrap_or(f64::INFINITY),
            Obstacle::Sphere { centre, radius } => centre[2] + radius,
            Obstacle::Capsule { a, b, radius } => a[2].max(b[2]) + radius,
            Obstacle::RoundedTriangle { points, radius } => {
                points
                    .iter()
                    .map(|p| p[2])
                    .fold(f64::NEG_INFINITY, f64::max)
                    + radius
            }
        }
    }

    /// The smallest circle around its footprint (a circle for a circle; the circumscribed
    /// circle of a box; the centroid's farthest corner for a polygon): what a planner that only
    /// knows circles must avoid.
    pub fn bounding_circle(&self) -> Circle {
        match self {
            Obstacle::Circle { x, y, radius, .. } => Circle {
                c: v2(*x, *y),
                r: *radius,
            },
            Obstacle::Sphere { centre, radius } => Circle {
                c: v2(centre[0], centre[1]),
                r: *radius,
            },
            Obstacle::Box {
                x,
                y,
                length,
                width,
                ..
            } => Circle {
                c: v2(*x, *y),
                r: 0.5 * length.hypot(*width),
            },
            Obstacle::Polygon { .. }
            | Obstacle::Capsule { .. }
            | Obstacle::RoundedTriangle { .. } => {
                let pts = self.polygon().unwrap_or_default();
                let n = pts.len().max(1) as f64;
                let c = pts.iter().fold(v2(0.0, 0.0), |a, p| a + *p * (1.0 / n));
                let r = pts.iter().map(|p| c.dist(*p)).fold(0.0, f64::max);
                Circle { c, r }
            }
        }
    }
}

/// The convex hull of `pts` grown by `r`, each rounded end circumscribed by 16-gon arcs,
/// counter-clockwise.
fn rounded_hull(pts: &[V2], r: f64) -> Vec<V2> {
    let k = 16;
    let rr = r / (std::f64::consts::PI / k as f64).cos();
    let mut cloud = Vec::new();
    for p in pts {
        for i in 0..k {
            let t = std::f64::consts::TAU * (i as f64 + 0.5) / k as f64;
            cloud.push(*p + V2::polar(t) * rr);
        }
    }
    convex_hull(cloud)
}

/// A steppable surface: a convex polygon at a height.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Surface {
    /// What it is.
    #[serde(default)]
    pub name: String,
    /// Corners, counter-clockwise, m (3 to 8).
    pub points: Vec<[f64; 2]>,
    /// Height of its top, m.
    pub height: f64,
}

impl Surface {
    /// Its corners.
    pub fn polygon(&self) -> Vec<V2> {
        self.points.iter().map(|p| v2(p[0], p[1])).collect()
    }
}

/// The map: its extent, and an optional elevation grid file.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapSpec {
    /// x range, m.
    pub x: [f64; 2],
    /// y range, m.
    pub y: [f64; 2],
    /// Cell size, m (0.05 when absent).
    #[serde(default)]
    pub resolution: Option<f64>,
    /// Elevation file (CSV of heights in m, `nan` for unknown), relative to the scene file:
    /// one line per row of cells, the first line the row of greatest y (as an image shows
    /// it), one column per cell from the least x. Its size must match the extent and cell.
    #[serde(default)]
    pub elevation: Option<String>,
}

/// A scene.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Short name.
    pub name: String,
    /// What it is, where it comes from.
    #[serde(default)]
    pub description: String,
    /// What the seed's thesis reports for this scene, if anything (shown beside the
    /// benchmark's figures).
    #[serde(default)]
    pub reference: String,
    /// The robot's start (its centre of mass over the ground, between the feet).
    pub start: Pose,
    /// The goal.
    pub goal: Pose,
    /// Obstacles.
    #[serde(default)]
    pub obstacle: Vec<Obstacle>,
    /// Steppable surfaces.
    #[serde(default)]
    pub surface: Vec<Surface>,
    /// The robot's parameter set, for planners that have several (the KAIST planner:
    /// `kaist_sim`, the default, or `kaist_real`).
    #[serde(default)]
    pub params: Option<String>,
    /// The map's extent and elevation (when absent: the scene's bounding box and flat
    /// ground).
    #[serde(default)]
    pub map: Option<MapSpec>,
    /// The directory of the scene file (for the elevation file).
    #[serde(skip)]
    pub dir: std::path::PathBuf,
}

/// Why a scene file cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// Reading the file.
    #[error("{path}: {error}")]
    Io {
        /// The file.
        path: String,
        /// What went wrong.
        error: std::io::Error,
    },
    /// Its TOML.
    #[error("{path}: {error}")]
    Toml {
        /// The file.
        path: String,
        /// What went wrong.
        error: toml::de::Error,
    },
    /// Read, but not a valid scene.
    #[error("{path}: {why}")]
    Invalid {
        /// The file.
        path: String,
        /// What is wrong.
        why: String,
    },
}

impl Scene {
    /// The farthest from the origin a scene file's numbers may be, m.
    pub const REACH: f64 = 10_000.0;

    /// Checks every number of the scene (start, goal, obstacles, surfaces, map) is finite and
    /// within `reach` m of the origin; the error names the first that is not.
    pub fn check_reach(&self, reach: f64) -> Result<(), String> {
        let bad = |what: String, v: f64| -> Result<(), String> {
            if !v.is_finite() {
                Err(format!("{what}: {v} is not a finite number"))
            } else if v.abs() > reach {
                Err(format!(
                    "{what}: {v} is beyond the world's reach of {reach} m"
                ))
            } else {
                Ok(())
            }
        };
        for (what, p) in [("start", &self.start), ("goal", &self.goal)] {
            for v in [p.x, p.y, p.z, p.yaw] {
                bad(what.into(), v)?;
            }
        }
        for (i, o) in self.obstacle.iter().enumerate() {
            o.check(reach).map_err(|e| format!("obstacle {i}: {e}"))?;
        }
        for s in &self.surface {
            for v in s.points.iter().flatten().chain([&s.height]) {
                bad(format!("surface {}", s.name), *v)?;
            }
        }
        if let Some(m) = &self.map {
            for v in m.x.iter().chain(&m.y).chain(&m.resolution) {
                bad("map".into(), *v)?;
            }
        }
        Ok(())
    }

    /// The largest scene file read, bytes (its obstacles and surfaces size what is built of
    /// it).
    pub const MAX_FILE: u64 = 8 << 20;

    /// The most obstacles a scene may hold.
    pub const MAX_OBSTACLES: usize = 10_000;

    /// Reads a scene file (refused before it is read when larger than [`Scene::MAX_FILE`]).
    pub fn load(path: &std::path::Path) -> Result<Scene, SceneError> {
        let p = path.display().to_string();
        let len = std::fs::metadata(path)
            .map_err(|error| SceneError::Io {
                path: p.clone(),
                error,
            })?
            .len();
        if len > Scene::MAX_FILE {
            return Err(SceneError::Invalid {
                path: p,
                why: format!(
                    "{len} bytes, more than the {} MB a scene may take",
                    Scene::MAX_FILE >> 20
                ),
            });
        }
        let text = std::fs::read_to_string(path).map_err(|error| SceneError::Io {
            path: p.clone(),
            error,
        })?;
        let mut scene: Scene = toml::from_str(&text).map_err(|error| SceneError::Toml {
            path: p.clone(),
            error,
        })?;
        scene.dir = path.parent().map(|d| d.to_path_buf()).unwrap_or_default();
        scene
            .check()
            .map_err(|why| SceneError::Invalid { path: p, why })?;
        Ok(scene)
    }

    /// Reads a scene from TOML text (an elevation file is looked for in `dir`).
    pub fn parse(text: &str, dir: &std::path::Path) -> Result<Scene, SceneError> {
        let mut scene: Scene = toml::from_str(text).map_err(|error| SceneError::Toml {
            path: "<text>".into(),
            error,
        })?;
        scene.dir = dir.to_path_buf();
        scene.check().map_err(|why| SceneError::Invalid {
            path: "<text>".into(),
            why,
        })?;
        Ok(scene)
    }

    fn check(&self) -> Result<(), String> {
        if self.obstacle.len() > Scene::MAX_OBSTACLES {
            return Err(format!(
                "{} obstacles, more than the {} a scene may hold",
                self.obstacle.len(),
                Scene::MAX_OBSTACLES
            ));
        }
        self.check_reach(Scene::REACH)?;
        for (i, s) in self.surface.iter().enumerate() {
            if !(3..=8).contains(&s.points.len()) {
                return Err(format!(
                    "surface {} has {} corners (3 to 8)",
                    i + 1,
                    s.points.len()
                ));
            }
            let q = s.polygon();
            let n = q.len();
            if (0..n).any(|k| (q[(k + 1) % n] - q[k]).cross(q[(k + 2) % n] - q[(k + 1) % n]) < 0.0)
            {
                return Err(format!(
                    "surface {} is not convex and counter-clockwise",
                    i + 1
                ));
            }
        }
        if let Some(m) = &self.map {
            if !(m.x[0] < m.x[1] && m.y[0] < m.y[1]) {
                return Err("the map's x and y ranges must be increasing".into());
            }
            if m.resolution.is_some_and(|r| r.is_nan() || r <= 0.0) {
                return Err("the map's resolution must be positive".into());
            }
        }
        Ok(())
    }

    /// Every obstacle as a circle (see [`Obstacle::bounding_circle`]).
    pub fn circles(&self) -> Vec<Circle> {
        self.obstacle
            .iter()
            .map(Obstacle::bounding_circle)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(obstacles: &str) -> Result<Scene, SceneError> {
        Scene::parse(
            &format!(
                "name = \"t\"\nstart = {{ x = 0.0, y = 0.0 }}\ngoal = {{ x = 1.0, y = 0.0 }}\n{obstacles}"
            ),
            std::path::Path::new("."),
        )
    }

    /// D10 of the reliability findings: a radius of -0.5 was taken as 0 and published.
    #[test]
    fn a_negative_size_is_refused_not_taken_as_zero() {
        for (o, what) in [
            (
                "shape = \"circle\"\nx = 1.0\ny = 0.0\nradius = -0.5",
                "radius -0.5",
            ),
            (
                "shape = \"box\"\nx = 1.0\ny = 0.0\nlength = 1.0\nwidth = -0.1",
                "width -0.1",
            ),
            (
                "shape = \"sphere\"\ncentre = [1.0, 0.0, 0.0]\nradius = -1.0",
                "radius -1",
            ),
            (
                "shape = \"circle\"\nx = 1.0\ny = 0.0\nradius = 0.5\nheight = -2.0",
                "height -2",
            ),
        ] {
            let e = scene(&format!("[[obstacle]]\n{o}\n"))
                .unwrap_err()
                .to_string();
            assert!(e.contains(what) && e.contains("not negative"), "{e}");
        }
        assert!(
            scene("[[obstacle]]\nshape = \"circle\"\nx = 1.0\ny = 0.0\nradius = 0.0\n").is_ok()
        );
    }

    /// D10: a scene of 1e6 obstacles (68 MB) reached 2.7 GB in stride-sim before its
    /// refusal. Too many obstacles are refused at the check, a file too large before it is
    /// read.
    #[test]
    fn a_scene_too_large_is_refused_before_anything_is_built_of_it() {
        let many: String = (0..=Scene::MAX_OBSTACLES)
            .map(|i| {
                format!(
                    "[[obstacle]]\nshape = \"circle\"\nx = {}.0\ny = 5.0\nradius = 0.1\n",
                    i % 100
                )
            })
            .collect();
        let e = scene(&many).unwrap_err().to_string();
        assert!(e.contains("obstacles, more than"), "{e}");
        let dir = tempfile::tempdir().unwrap();
        let big = dir.path().join("big.toml");
        let f = std::fs::File::create(&big).unwrap();
        f.set_len(Scene::MAX_FILE + 1).unwrap();
        let e = Scene::load(&big).unwrap_err().to_string();
        assert!(e.contains("more than the 8 MB"), "{e}");
    }
}
