//! The simulated world of stride, with no bus and no I/O: what `stride-sim` runs.
//!
//! - [`body`]: Archie's body moved kinematically from its joints' true positions. One foot,
//!   the anchor, stays where it stands; the pelvis and the other foot follow from the legs'
//!   forward kinematics; a foot that the joints would push into the ground takes over as the
//!   anchor, set down level on the scene's surface. Each state gives the pelvis's pose, the
//!   feet and their contacts, the whole robot's centre of mass and its whole-body ZMP, and
//!   what went wrong: a foot or shank inside an obstacle, the ZMP outside the support polygon
//!   (a fall), a joint at its limit.
//! - [`hexapod`]: the hexapod's body moved kinematically from its 18 joints' true positions:
//!   level, resting on its lowest feet, its x, y and yaw the rigid fit of the anchored feet
//!   onto where they touched down. It gives the body's pose, the feet and their contacts, the
//!   static stability margin, and what went wrong: a foot inside an obstacle, the body's
//!   centre outside the support polygon (a fall), a joint at its limit.
//! - [`world`]: the scene as the body meets it (the ground's height, the obstacles' solids)
//!   and as perfect perception sees it (obstacles, an elevation grid), with seeded noise.
//! - [`noise`]: the seeded random numbers behind every noise, so a run repeats exactly.

pub mod body;
pub mod hexapod;
pub mod noise;
pub mod world;

/// A point or vector in space, m.
pub type V3 = [f64; 3];
