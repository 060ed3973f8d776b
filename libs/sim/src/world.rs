//! The scene as the simulated body meets it and as perfect perception sees it.

use serde::Deserialize;
use stride_world::geom::{point_polygon_distance, v2, V2};
use stride_world::grid::{Grid, GridError};
use stride_world::scene::{MapSpec, Obstacle, Scene};

use crate::noise::Rng;
use crate::V3;

/// How far perception is from the truth: standard deviations of its noise.
#[derive(Debug, Clone, Copy, PartialEq, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PerceptionNoise {
    /// Of each obstacle's position (every coordinate), m.
    #[serde(default)]
    pub position: f64,
    /// Of each obstacle's size (radius, length, width), m.
    #[serde(default)]
    pub size: f64,
    /// Of each cell's height in the elevation map, m.
    #[serde(default)]
    pub height: f64,
}

/// The scene the body walks in.
#[derive(Debug, Clone)]
pub struct World {
    /// The scene.
    pub scene: Scene,
    /// The ground the feet stand on: the map and the surfaces (no obstacle).
    ground: Grid,
    /// What a perfect elevation sensor sees: the ground and the obstacles' tops.
    seen: Grid,
    /// Each obstacle's footprint (None: a circle, kept as its centre and radius).
    footprints: Vec<Option<Vec<V2>>>,
}

impl World {
    /// The world of a scene.
    pub fn new(scene: Scene) -> Result<World, GridError> {
        // The ground over the same extent as the seen map (which the obstacles widen): the
        // scene without its obstacles, on the scene's own extent.
        let (x, y, resolution) = Grid::extent_of(&scene);
        let bare = Scene {
            obstacle: Vec::new(),
            map: Some(MapSpec {
                x,
                y,
                resolution: Some(resolution),
                elevation: scene.map.as_ref().and_then(|m| m.elevation.clone()),
            }),
            ..scene.clone()
        };
        let ground = Grid::of_scene(&bare)?;
        let seen = Grid::of_scene(&scene)?;
        let footprints = scene.obstacle.iter().map(|o| o.polygon()).collect();
        Ok(World {
            scene,
            ground,
            seen,
            footprints,
        })
    }

    /// The ground's height at (x, y): the surface there, 0 off the map or where unknown.
    pub fn ground(&self, x: f64, y: f64) -> f64 {
        let h = self.ground.height(v2(x, y));
        if h.is_finite() {
            h
        } else {
            0.0
        }
    }

    /// The first obstacle that holds `p`, by its index in the scene.
    pub fn obstacle_at(&self, p: V3) -> Option<usize> {
        self.scene
            .obstacle
            .iter()
            .zip(&self.footprints)
            .position(|(o, poly)| {
                if p[2] < o.bottom() || p[2] > o.top() {
                    return false;
                }
                let q = v2(p[0], p[1]);
                match (o, poly) {
                    (_, Some(poly)) => point_polygon_distance(q, poly) == 0.0,
                    (Obstacle::Sphere { centre, radius }, None) => {
                        let d: f64 = (0..3).map(|k| (p[k] - centre[k]).powi(2)).sum();
                        d.sqrt() <= *radius
                    }
                    (o, None) => {
                        let c = o.bounding_circle();
                        c.c.dist(q) <= c.r
                    }
                }
            })
    }

    /// The horizontal distance from `p` to the nearest obstacle that spans its height (a
    /// sphere: the distance in space), 0 inside one, infinite when none does.
    pub fn clearance(&self, p: V3) -> f64 {
        let q = v2(p[0], p[1]);
        self.scene
            .obstacle
            .iter()
            .zip(&self.footprints)
            .filter(|(o, _)| p[2] >= o.bottom() && p[2] <= o.top())
            .map(|(o, poly)| match (o, poly) {
                (_, Some(poly)) => point_polygon_distance(q, poly),
                (Obstacle::Sphere { centre, radius }, None) => {
                    let d: f64 = (0..3).map(|k| (p[k] - centre[k]).powi(2)).sum();
                    (d.sqrt() - radius).max(0.0)
                }
                (o, None) => {
                    let c = o.bounding_circle();
                    (c.c.dist(q) - c.r).max(0.0)
                }
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// Adds an obstacle to the scene (one that appears during a run).
    pub fn add(&mut self, obstacle: Obstacle) -> Result<(), GridError> {
        let mut scene = self.scene.clone();
        scene.obstacle.push(obstacle);
        *self = World::new(scene)?;
        Ok(())
    }

    /// The scene's obstacles as a perception with `noise` sees them.
    pub fn perceived_obstacles(&self, noise: &PerceptionNoise, rng: &mut Rng) -> Vec<Obstacle> {
        let mut obstacles = Vec::with_capacity(self.scene.obstacle.len());
        for o in &self.scene.obstacle {
            let mut o = o.clone();
            let mut p = |v: f64| v + rng.normal(noise.position);
            match &mut o {
                Obstacle::Circle { x, y, .. } | Obstacle::Box { x, y, .. } => {
                    *x = p(*x);
                    *y = p(*y);
                }
                Obstacle::Polygon { points, .. } => {
                    for q in points.iter_mut() {
                        *q = [p(q[0]), p(q[1])];
                    }
                }
                Obstacle::Sphere { centre, .. } => *centre = centre.map(&mut p),
                Obstacle::Capsule { a, b, .. } => {
                    *a = a.map(&mut p);
                    *b = b.map(&mut p);
                }
                Obstacle::RoundedTriangle { points, .. } => {
                    *points = points.map(|q| q.map(&mut p));
                }
            }
            let mut s = |v: f64| (v + rng.normal(noise.size)).max(0.0);
            match &mut o {
                Obstacle::Circle { radius, .. }
                | Obstacle::Sphere { radius, .. }
                | Obstacle::Capsule { radius, .. }
                | Obstacle::RoundedTriangle { radius, .. } => *radius = s(*radius),
                Obstacle::Box { length, width, .. } => {
                    *length = s(*length);
                    *width = s(*width);
                }
                Obstacle::Polygon { .. } => {}
            }
            obstacles.push(o);
        }
        obstacles
    }

    /// The elevation grid a perfect sensor sees (ground and obstacles' tops), each cell's height
    /// with `noise`; obstacles of no given height stand 2 m tall.
    pub fn perceived_elevation(&self, noise: &PerceptionNoise, rng: &mut Rng) -> Grid {
        let mut g = self.seen.clone();
        for h in &mut g.h {
            if h.is_infinite() {
                *h = 2.0;
            }
            if h.is_finite() {
                *h += rng.normal(noise.height);
            }
        }
        g
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(text: &str) -> Scene {
        Scene::parse(text, std::path::Path::new(".")).unwrap()
    }

    const TEXT: &str = r#"
        name = "t"
        start = { x = 0.0, y = 0.0 }
        goal = { x = 3.0, y = 0.0 }
        [[obstacle]]
        shape = "circle"
        x = 1.0
        y = 0.0
        radius = 0.2
        height = 0.5
        [[obstacle]]
        shape = "box"
        x = 2.0
        y = 1.0
        length = 0.4
        width = 0.2
        [[surface]]
        points = [[2.5, -0.5], [3.5, -0.5], [3.5, 0.5], [2.5, 0.5]]
        height = 0.1
    "#;

    #[test]
    fn the_ground_is_the_surfaces_and_obstacles_hold_their_volume() {
        let w = World::new(scene(TEXT)).unwrap();
        assert_eq!(w.ground(0.0, 0.0), 0.0);
        assert_eq!(w.ground(1.0, 0.0), 0.0, "an obstacle is not ground");
        assert!((w.ground(3.0, 0.0) - 0.1).abs() < 1e-12);
        assert_eq!(w.ground(40.0, 0.0), 0.0, "off the map: level");
        assert_eq!(w.obstacle_at([1.1, 0.0, 0.3]), Some(0));
        assert_eq!(w.obstacle_at([1.1, 0.0, 0.6]), None, "above its top");
        assert_eq!(w.obstacle_at([1.25, 0.0, 0.3]), None);
        assert_eq!(w.obstacle_at([2.15, 1.05, 1.5]), Some(1));
        assert_eq!(w.obstacle_at([2.15, 1.15, 1.5]), None);
        assert!((w.clearance([1.5, 0.0, 0.3]) - 0.3).abs() < 1e-9);
        assert_eq!(w.clearance([1.1, 0.0, 0.3]), 0.0);
        assert!((w.clearance([2.0, 1.5, 0.3]) - 0.4).abs() < 1e-9);
        // Above the cylinder's top only the box counts: its corner (1.8, 0.9).
        assert!((w.clearance([1.5, 0.0, 0.6]) - 0.3f64.hypot(0.9)).abs() < 1e-9);
    }

    #[test]
    fn perfect_perception_is_the_scene_and_noise_repeats_with_its_seed() {
        let w = World::new(scene(TEXT)).unwrap();
        let none = PerceptionNoise::default();
        assert_eq!(
            w.perceived_obstacles(&none, &mut Rng::new(1)),
            w.scene.obstacle
        );
        let noisy = PerceptionNoise {
            position: 0.01,
            size: 0.01,
            height: 0.005,
        };
        let a = w.perceived_obstacles(&noisy, &mut Rng::new(3));
        assert_eq!(a, w.perceived_obstacles(&noisy, &mut Rng::new(3)));
        assert_ne!(a, w.scene.obstacle);
        let g = w.perceived_elevation(&none, &mut Rng::new(1));
        let top = g.height(v2(1.0, 0.0));
        assert!((top - 0.5).abs() < 1e-12, "{top}");
        assert_eq!(g.height(v2(2.0, 1.0)), 2.0, "no given height: 2 m");
    }
}
