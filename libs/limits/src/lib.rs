//! The one check every bridge (Elmo drives, Dynamixel servos, Arduino boards) makes of the
//! set-points it is sent: every joint named is one of its own and named once, the arrays
//! agree in length, and each value is finite and within the joint's position and velocity
//! limits. A command that fails anywhere is refused whole ([`Reject`] says which joint and
//! which limit, by how much); nothing is clipped. With it the pure arithmetic of joint motion
//! the gait, the masters and the tools share: segments and their extremes ([`curve`]), the
//! minimum-jerk move ([`moves`]) and angles ([`angle`]).

pub mod angle;
pub mod curve;
pub mod moves;

/// Why a command was refused (nothing of it is applied).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Reject {
    /// A joint the bridge does not drive.
    #[error("unknown joint {0}")]
    UnknownJoint(String),
    /// A joint named twice in one command.
    #[error("joint {0} named twice")]
    DuplicateJoint(String),
    /// A mode the bridge does not take for that joint.
    #[error("joint {joint}: {what}")]
    Mode {
        /// The joint.
        joint: String,
        /// What the bridge takes instead.
        what: String,
    },
    /// Beyond a limit (or not a finite number).
    #[error("joint {joint}: {what}")]
    Limit {
        /// The joint.
        joint: String,
        /// Which limit, by how much.
        what: String,
    },
    /// The command's arrays do not fit together.
    #[error("malformed command: {0}")]
    Malformed(String),
}

/// A joint's limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// Lowest position, rad (or m).
    pub min_position: f64,
    /// Highest position.
    pub max_position: f64,
    /// Largest speed, rad/s (`INFINITY`: none).
    pub max_velocity: f64,
}

impl Limits {
    /// Checks that the limits themselves make sense: finite, ordered, a positive speed.
    pub fn check(&self, joint: &str) -> Result<(), String> {
        if !(self.min_position.is_finite()
            && self.max_position.is_finite()
            && self.min_position < self.max_position)
        {
            return Err(format!(
                "joint {joint}: position limits [{}, {}] must be finite and ordered",
                self.min_position, self.max_position
            ));
        }
        if self.max_velocity.is_nan() || self.max_velocity <= 0.0 {
            return Err(format!(
                "joint {joint}: max_velocity {} must be positive",
                self.max_velocity
            ));
        }
        Ok(())
    }

    /// A position within the limits.
    pub fn position(&self, joint: &str, p: f64) -> Result<(), Reject> {
        if p.is_finite() && (self.min_position..=self.max_position).contains(&p) {
            return Ok(());
        }
        Err(Reject::Limit {
            joint: joint.to_owned(),
            what: format!(
                "position {p:.4} rad outside [{}, {}]",
                self.min_position, self.max_position
            ),
        })
    }

    /// A velocity within the speed limit.
    pub fn velocity(&self, joint: &str, v: f64) -> Result<(), Reject> {
        if v.is_finite() && v.abs() <= self.max_velocity {
            return Ok(());
        }
        Err(Reject::Limit {
            joint: joint.to_owned(),
            what: format!("velocity {v:.4} rad/s beyond {}", self.max_velocity),
        })
    }
}

/// The bridge's joint of each name in `names`, by `find` (its index); every name must be
/// known and appear once.
pub fn columns(
    names: &[String],
    mut find: impl FnMut(&str) -> Option<usize>,
) -> Result<Vec<usize>, Reject> {
    let mut out = Vec::with_capacity(names.len());
    for (k, name) in names.iter().enumerate() {
        if names[..k].contains(name) {
            return Err(Reject::DuplicateJoint(name.clone()));
        }
        out.push(find(name).ok_or_else(|| Reject::UnknownJoint(name.clone()))?);
    }
    Ok(out)
}

/// Checks that each array has one element per joint named.
pub fn lengths(joints: usize, arrays: &[(&str, usize)]) -> Result<(), Reject> {
    for (what, n) in arrays {
        if *n != joints {
            return Err(Reject::Malformed(format!("{joints} joints but {n} {what}")));
        }
    }
    Ok(())
}

/// A set-point command checked whole: the joints (by `find`), then for each its position and,
/// where given, its velocity against `limits` of that joint. Returns each name's joint.
pub fn check_setpoints<'a>(
    names: &[String],
    positions: &[f64],
    velocities: Option<&[f64]>,
    find: impl FnMut(&str) -> Option<usize>,
    limits: impl Fn(usize) -> &'a Limits,
) -> Result<Vec<usize>, Reject> {
    let mut arrays = vec![("positions", positions.len())];
    if let Some(v) = velocities {
        arrays.push(("velocities", v.len()));
    }
    lengths(names.len(), &arrays)?;
    let cols = columns(names, find)?;
    for (k, &j) in cols.iter().enumerate() {
        let l = limits(j);
        l.position(&names[k], positions[k])?;
        if let Some(v) = velocities {
            l.velocity(&names[k], v[k])?;
        }
    }
    Ok(cols)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(n: &[&str]) -> Vec<String> {
        n.iter().map(|s| s.to_string()).collect()
    }

    const L: Limits = Limits {
        min_position: -1.0,
        max_position: 1.0,
        max_velocity: 2.0,
    };

    fn find(n: &str) -> Option<usize> {
        ["a", "b", "c"].iter().position(|x| *x == n)
    }

    #[test]
    fn a_joint_named_twice_is_refused() {
        let e = check_setpoints(&names(&["a", "a"]), &[0.7, -0.7], None, find, |_| &L);
        assert_eq!(e, Err(Reject::DuplicateJoint("a".into())));
    }

    #[test]
    fn set_points_are_refused_whole_with_the_joint_and_the_limit() {
        assert_eq!(
            check_setpoints(
                &names(&["b", "a"]),
                &[0.5, 0.0],
                Some(&[0.0, 1.0]),
                find,
                |_| &L
            ),
            Ok(vec![1, 0])
        );
        let e = check_setpoints(&names(&["a", "b"]), &[0.5, 1.5], None, find, |_| &L);
        assert_eq!(
            e.unwrap_err().to_string(),
            "joint b: position 1.5000 rad outside [-1, 1]"
        );
        for bad in [f64::NAN, f64::INFINITY] {
            assert!(check_setpoints(&names(&["a"]), &[bad], None, find, |_| &L).is_err());
            assert!(check_setpoints(&names(&["a"]), &[0.0], Some(&[bad]), find, |_| &L).is_err());
        }
        assert_eq!(
            check_setpoints(&names(&["z"]), &[0.0], None, find, |_| &L),
            Err(Reject::UnknownJoint("z".into()))
        );
        assert!(matches!(
            check_setpoints(&names(&["a", "b"]), &[0.0], None, find, |_| &L),
            Err(Reject::Malformed(_))
        ));
        assert!(L.check("a").is_ok());
        assert!(Limits {
            min_position: 1.0,
            ..L
        }
        .check("a")
        .is_err());
        assert!(Limits {
            max_velocity: f64::NAN,
            ..L
        }
        .check("a")
        .is_err());
    }
}
