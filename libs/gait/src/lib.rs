//! Walking patterns, with no bus and no I/O:
//!
//! - [`preview`]: ZMP preview control on the cart-table model (Kajita 2003), the default COM
//!   generator;
//! - [`lipm`]: the linear inverted pendulum's walk primitives and modified foot placement
//!   (Archie's eqs 9-26 and 95-98, after Kajita);
//! - [`timeline`]: footsteps laid out in time (LOLA's step time rule) and their ZMP reference;
//! - [`swing`]: the swing foot's C² splines through three via points;
//! - [`support`]: support polygons and the ZMP's margin in them;
//! - [`pattern`]: COM, ZMP and swing patterns from footsteps, one interface for both
//!   generators, checked and stretched in time until the ZMP keeps its margin;
//! - [`archie`]: Archie's joint trajectories from a pattern, checked against the joints'
//!   limits, and the whole body's ZMP under a pattern (the second stage of preview control);
//! - [`hexapod`]: the hexapod's wave and tripod gaits and its sensing lift, as servo goals
//!   and moving speeds;
//! - [`walker`]: the walk in step with a replanning planner (step numbers, late plans,
//!   in-place steps, stops).

pub mod archie;
pub mod controller;
pub mod hexapod;
pub mod lipm;
pub mod pattern;
pub mod preview;
pub mod rows;
pub mod support;
pub mod swing;
pub mod timeline;
pub mod walker;

/// What a pattern computation can fail with.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GaitError {
    /// A parameter out of its domain (a non-positive height or period, a NaN).
    #[error("{0}")]
    Parameter(String),
    /// A plan that cannot be walked as it is (not finite, too far for a placement).
    #[error("{0}")]
    Plan(String),
    /// The ZMP leaves its margin in the support polygon whatever the step times.
    #[error("{0}")]
    Zmp(String),
    /// A joint beyond its position, velocity or acceleration limit.
    #[error("{0}")]
    Limit(String),
}

/// A figure for a message, short whatever its size: three decimals, or three significant
/// digits and an exponent beyond a million (a refused plan's 1e300 m step is not printed in
/// 300 digits).
pub fn short(x: f64) -> String {
    if x.is_finite() && x.abs() < 1e6 {
        format!("{x:.3}")
    } else {
        format!("{x:.3e}")
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn huge_figures_are_printed_short() {
        assert_eq!(super::short(0.25), "0.250");
        assert_eq!(super::short(1e300), "1.000e300");
        assert_eq!(super::short(-2.5e9), "-2.500e9");
        assert_eq!(super::short(f64::NAN), "NaN");
    }
}
