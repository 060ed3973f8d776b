//! Angles.

use std::f64::consts::{PI, TAU};

/// `a` wrapped to (−π, π].
#[inline]
pub fn wrap(a: f64) -> f64 {
    let w = (a + PI).rem_euclid(TAU) - PI;
    if w <= -PI {
        w + TAU
    } else {
        w
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_lands_in_the_half_open_turn() {
        assert_eq!(wrap(PI), PI);
        assert_eq!(wrap(-PI), PI);
        assert!((wrap(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap(0.5 + 4.0 * TAU) - 0.5).abs() < 1e-12);
        assert!((wrap(-0.5 - 4.0 * TAU) + 0.5).abs() < 1e-12);
        for k in -1000..1000 {
            let a = k as f64 * 0.0137;
            let w = wrap(a);
            assert!(w > -PI && w <= PI, "{a} -> {w}");
            assert!(((a - w) / TAU - ((a - w) / TAU).round()).abs() < 1e-9);
        }
        assert!(wrap(f64::NAN).is_nan());
    }
}
