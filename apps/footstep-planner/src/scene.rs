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

use crate::geom::{v2, Circle, V2};

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
}

impl Pose {
    /// The position.
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
    },
    /// An extruded convex polygon.
    Polygon {
        /// Corners, counter-clockwise, m.
        points: Vec<[f64; 2]>,
        /// Height, m (infinite when absent).
        #[serde(default)]
        height: Option<f64>,
    },
}

impl Obstacle {
    /// Its footprint as a convex polygon (counter-clockwise), or `None` for a circle.
    pub fn polygon(&self) -> Option<Vec<V2>> {
        match self {
            Obstacle::Circle { .. } => None,
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
            Obstacle::Polygon { points, .. } => {
                Some(points.iter().map(|p| v2(p[0], p[1])).collect())
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
            Obstacle::Polygon { points, .. } => {
                let n = points.len().max(1) as f64;
                let c = points
                    .iter()
                    .fold(v2(0.0, 0.0), |a, p| a + v2(p[0], p[1]) * (1.0 / n));
                let r = points
                    .iter()
                    .map(|p| c.dist(v2(p[0], p[1])))
                    .fold(0.0, f64::max);
                Circle { c, r }
            }
        }
    }
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
    /// The robot's start (its centre of mass over the ground, between the feet).
    pub start: Pose,
    /// The goal.
    pub goal: Pose,
    /// Obstacles.
    #[serde(default)]
    pub obstacle: Vec<Obstacle>,
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
}

impl Scene {
    /// Reads a scene file.
    pub fn load(path: &std::path::Path) -> Result<Scene, SceneError> {
        let p = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|error| SceneError::Io {
            path: p.clone(),
            error,
        })?;
        toml::from_str(&text).map_err(|error| SceneError::Toml { path: p, error })
    }

    /// Every obstacle as a circle (see [`Obstacle::bounding_circle`]).
    pub fn circles(&self) -> Vec<Circle> {
        self.obstacle
            .iter()
            .map(Obstacle::bounding_circle)
            .collect()
    }
}
