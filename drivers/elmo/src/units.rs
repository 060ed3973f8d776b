//! Joint units to drive units, each conversion checked against the width of the field it
//! goes into: positions (32-bit counts), PVT velocities (24 bits), the following-error
//! window and the quick-stop deceleration (unsigned 32 bits). A configuration whose limits
//! cannot be represented is refused when the master is made.

use stride_canopen::elmo::PVT_MAX_VELOCITY;

use crate::config::{JointConfig, Motion};

/// The conversions of one joint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Units {
    counts_per_rad: f64,
}

/// A value that does not fit its drive field.
#[derive(Debug, Clone, PartialEq)]
pub struct OutOfField {
    /// The value in drive units.
    pub counts: f64,
    /// The field.
    pub field: &'static str,
}

impl std::fmt::Display for OutOfField {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:.0} does not fit {}", self.counts, self.field)
    }
}

fn fits(v: f64, lo: f64, hi: f64, field: &'static str) -> Result<f64, OutOfField> {
    let r = v.round();
    if r.is_finite() && (lo..=hi).contains(&r) {
        Ok(r)
    } else {
        Err(OutOfField { counts: v, field })
    }
}

impl Units {
    /// The joint's units, once its configuration is shown to fit every field the master
    /// writes in `motion` mode; otherwise why not, in one line.
    pub fn of(j: &JointConfig, motion: Motion) -> Result<Units, String> {
        let k = j.counts_per_rad();
        if !(k.is_finite() && k != 0.0) {
            return Err(format!(
                "counts_per_rev {} and gear_ratio {} give no conversion to counts",
                j.counts_per_rev, j.gear_ratio
            ));
        }
        j.limits().check(&j.name)?;
        if !(j.max_acceleration > 0.0 && j.max_acceleration.is_finite()) {
            return Err(format!(
                "max_acceleration {} must be positive",
                j.max_acceleration
            ));
        }
        if !(j.tolerance > 0.0 && j.tolerance < j.max_position - j.min_position) {
            return Err(format!(
                "tolerance {} rad must be positive and less than the joint's range",
                j.tolerance
            ));
        }
        let u = Units { counts_per_rad: k };
        for p in [j.min_position, j.max_position] {
            u.position(p).map_err(|e| {
                format!("position limit {p} rad is {e}: fewer counts per radian needed")
            })?;
        }
        if motion == Motion::Pvt {
            u.velocity(j.max_velocity).map_err(|e| {
                format!(
                    "max_velocity {} rad/s is {e} (±{PVT_MAX_VELOCITY} counts/s): at most {:.3} \
                     rad/s with this encoder and gear, or use motion = \"pt\"",
                    j.max_velocity,
                    PVT_MAX_VELOCITY as f64 / k.abs()
                )
            })?;
        }
        let window = j.tolerance * k.abs();
        if window < 1.0 {
            return Err(format!(
                "tolerance {} rad is {window:.2} counts: less than one count",
                j.tolerance
            ));
        }
        u.magnitude(j.tolerance, "the following-error window (0x6065, 32 bits)")
            .map_err(|e| format!("tolerance {} rad is {e}", j.tolerance))?;
        u.magnitude(
            j.max_acceleration,
            "the quick-stop deceleration (0x6085, 32 bits)",
        )
        .map_err(|e| format!("max_acceleration {} rad/s² is {e}", j.max_acceleration))?;
        Ok(u)
    }

    /// Counts per joint radian.
    pub fn counts_per_rad(&self) -> f64 {
        self.counts_per_rad
    }

    /// A position in counts (32-bit signed).
    pub fn position(&self, rad: f64) -> Result<i32, OutOfField> {
        fits(
            rad * self.counts_per_rad,
            i32::MIN as f64,
            i32::MAX as f64,
            "a 32-bit position",
        )
        .map(|c| c as i32)
    }

    /// A PVT velocity in counts/s (24-bit signed).
    pub fn velocity(&self, rad_s: f64) -> Result<i32, OutOfField> {
        fits(
            rad_s * self.counts_per_rad,
            -(PVT_MAX_VELOCITY as f64),
            PVT_MAX_VELOCITY as f64,
            "the 24-bit PVT velocity",
        )
        .map(|c| c as i32)
    }

    /// A magnitude (window, deceleration) in counts for an unsigned 32-bit field, at least 1.
    pub fn magnitude(&self, x: f64, field: &'static str) -> Result<u32, OutOfField> {
        fits(x * self.counts_per_rad.abs(), 0.0, u32::MAX as f64, field).map(|c| c.max(1.0) as u32)
    }

    /// A position in counts as radians.
    pub fn rad(&self, counts: f64) -> f64 {
        counts / self.counts_per_rad
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn knee() -> JointConfig {
        JointConfig {
            name: "left_knee".into(),
            node: 4,
            counts_per_rev: 4096.0,
            gear_ratio: 120.0,
            min_position: 0.0,
            max_position: 2.3,
            max_velocity: 4.0,
            max_acceleration: 40.0,
            tolerance: 0.01,
        }
    }

    #[test]
    fn a_17_bit_encoder_at_gear_120_cannot_carry_6_rad_s_in_pvt() {
        // The finding: 131072 counts/rev x 120 / 2π = 2 503 314 counts/rad, so 4.7 rad/s is
        // 11.8 M counts/s, past the 24-bit field (8.39 M): refused at start, not a panic.
        let j = JointConfig {
            counts_per_rev: 131_072.0,
            max_velocity: 6.0,
            ..knee()
        };
        let e = Units::of(&j, Motion::Pvt).unwrap_err();
        assert!(
            e.contains("24-bit PVT velocity") && e.contains("3.351 rad/s"),
            "{e}"
        );
        // PT carries positions only: the same joint fits.
        assert!(Units::of(&j, Motion::Pt { period_ms: 10 }).is_ok());
        // And a velocity past the field is an error, never a wrapped number.
        let u = Units::of(&knee(), Motion::Pvt).unwrap();
        assert!(u.velocity(1e9).is_err() && u.velocity(f64::NAN).is_err());
        assert_eq!(u.velocity(1.0).unwrap(), 78228);
    }

    #[test]
    fn limits_that_do_not_fit_32_bits_are_refused() {
        let j = JointConfig {
            counts_per_rev: 1e9,
            ..knee()
        };
        assert!(Units::of(&j, Motion::Pt { period_ms: 10 })
            .unwrap_err()
            .contains("32-bit position"));
        let tiny = JointConfig {
            tolerance: 1e-6,
            ..knee()
        };
        assert!(Units::of(&tiny, Motion::Pvt)
            .unwrap_err()
            .contains("less than one count"));
        let none = JointConfig {
            gear_ratio: 0.0,
            ..knee()
        };
        assert!(Units::of(&none, Motion::Pvt).is_err());
        assert!(Units::of(&knee(), Motion::Pvt).is_ok());
    }
}
