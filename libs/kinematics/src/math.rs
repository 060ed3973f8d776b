//! The legs' rigid-body types, nalgebra's: a pose is an isometry whose rotation is kept as a
//! 3 × 3 rotation matrix ([`Pose`]: the closed-form inverse kinematics reads its entries),
//! points are plain `[f64; 3]` as the messages carry them. [`Frame`] adds the few readings
//! the legs, the gait and the simulated world make of a pose.

pub use nalgebra::{Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};

/// A point or offset, m.
pub type V3 = [f64; 3];

/// A rigid pose: a frame's axes and origin in its parent.
pub type Pose = nalgebra::IsometryMatrix3<f64>;

/// Rotation about x by `t` rad.
pub fn rx(t: f64) -> Rotation3<f64> {
    Rotation3::from_axis_angle(&Vector3::x_axis(), t)
}

/// Rotation about y by `t` rad.
pub fn ry(t: f64) -> Rotation3<f64> {
    Rotation3::from_axis_angle(&Vector3::y_axis(), t)
}

/// Rotation about z by `t` rad.
pub fn rz(t: f64) -> Rotation3<f64> {
    Rotation3::from_axis_angle(&Vector3::z_axis(), t)
}

/// The pose with rotation `r` and origin `p`.
pub fn pose(r: Rotation3<f64>, p: V3) -> Pose {
    Pose::from_parts(Translation3::from(Vector3::from(p)), r)
}

/// A translation.
pub fn at(p: V3) -> Pose {
    Pose::translation(p[0], p[1], p[2])
}

/// Upright at `p` with heading `yaw`.
pub fn yawed(p: V3, yaw: f64) -> Pose {
    pose(rz(yaw), p)
}

/// What the legs read of a pose.
pub trait Frame {
    /// The origin, m.
    fn position(&self) -> V3;
    /// A point of this frame in the parent.
    fn apply(&self, q: &V3) -> V3;
    /// The heading of the frame's x axis in the parent's xy plane, rad.
    fn yaw(&self) -> f64;
    /// The difference to `o`: translation (m) and rotation (Frobenius norm of the difference
    /// of the matrices).
    fn distance(&self, o: &Pose) -> (f64, f64);
    /// Every number finite.
    fn is_finite(&self) -> bool;
}

impl Frame for Pose {
    fn position(&self) -> V3 {
        self.translation.vector.into()
    }

    fn apply(&self, q: &V3) -> V3 {
        (self.rotation * Vector3::from(*q) + self.translation.vector).into()
    }

    fn yaw(&self) -> f64 {
        let m = self.rotation.matrix();
        m[(1, 0)].atan2(m[(0, 0)])
    }

    fn distance(&self, o: &Pose) -> (f64, f64) {
        (
            (self.translation.vector - o.translation.vector).norm(),
            (self.rotation.matrix() - o.rotation.matrix()).norm(),
        )
    }

    fn is_finite(&self) -> bool {
        self.translation.vector.iter().all(|v| v.is_finite())
            && self.rotation.matrix().iter().all(|v| v.is_finite())
    }
}
