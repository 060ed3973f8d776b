//! The world the robot's planners work in, with no bus and no I/O beyond reading scene files:
//! scenes ([`scene`]: start, goal, obstacles, surfaces, an elevation map, as TOML files of
//! `config/scenes/`), plane geometry ([`geom`]), 2.5-D elevation grids and their distance
//! fields ([`grid`]), 3-D proximity of swept-sphere volumes on parry3d ([`ssv`]), and an
//! independent reference for graders of the circle planners ([`reference`]).

pub mod geom;
pub mod grid;
pub mod reference;
pub mod scene;
pub mod ssv;

use std::cmp::Ordering;

/// An entry of a least-cost-first `BinaryHeap`: a cost and an index, least cost first, then
/// least index (deterministic).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Least(pub f64, pub usize);

impl Eq for Least {}

impl Ord for Least {
    #[inline]
    fn cmp(&self, o: &Self) -> Ordering {
        o.0.total_cmp(&self.0).then(o.1.cmp(&self.1))
    }
}

impl PartialOrd for Least {
    #[inline]
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
