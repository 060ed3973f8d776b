//! Leg kinematics of stride's robots, with no bus and no I/O beyond reading robot files:
//! Archie's 6-joint legs ([`archie`]: forward and inverse kinematics in one re-derived
//! convention, the thesis's DH tables, hand-written chain and joint pattern checked against it),
//! the hexapod's 3-DOF legs ([`hexapod`]: inverse and forward kinematics, the servo mapping
//! and joint limits of its thesis's Tables 3.1 and 3.2).
//!
//! Every solver returns an error, never NaN, for a target no leg reaches or a singular pose.

pub mod archie;
pub mod attitude;
pub mod hexapod;
pub mod math;

/// What a kinematic computation or a robot file can fail with.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum KinError {
    /// No joint angles put the foot there.
    #[error("unreachable: {0}")]
    Unreachable(String),
    /// The target is on a singularity, where the solution is not defined.
    #[error("singular: {0}")]
    Singular(String),
    /// A joint angle beyond its limit.
    #[error("{joint}: {value:.2}° beyond its limits [{min}°, {max}°]")]
    Limit {
        /// The joint.
        joint: String,
        /// Its angle, degrees.
        value: f64,
        /// Lower limit, degrees.
        min: f64,
        /// Upper limit, degrees.
        max: f64,
    },
    /// A robot file that cannot be read or does not make sense.
    #[error("{0}")]
    Config(String),
}

/// Reads a TOML robot file.
pub(crate) fn read_toml<T: serde::de::DeserializeOwned>(
    path: &std::path::Path,
) -> Result<T, KinError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| KinError::Config(format!("{}: {e}", path.display())))?;
    toml::from_str(&text).map_err(|e| KinError::Config(format!("{}: {e}", path.display())))
}
