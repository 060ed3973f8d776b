//! The motion between two rows of a joint trajectory as a drive plays it, and its exact
//! extremes: a cubic Hermite segment (PVT rows, and PT points with the slopes the drive gives
//! them), or a line (interpolated position); and the check of those extremes against a
//! joint's limits ([`beyond`]) that the Elmo bridge makes of what it is sent and the gait of
//! what it sends. Pure arithmetic.

/// A cubic `p(t) = c0 + c1 t + c2 t² + c3 t³` on `0..=h`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cubic {
    c: [f64; 4],
    h: f64,
}

/// The largest values a segment reaches: position range, speed, acceleration, each with the
/// time (from the segment's start, s) where it is reached.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Extremes {
    /// Lowest position and when.
    pub p_min: (f64, f64),
    /// Highest position and when.
    pub p_max: (f64, f64),
    /// Largest |velocity| and when.
    pub v: (f64, f64),
    /// Largest |acceleration| and when.
    pub a: (f64, f64),
}

impl Cubic {
    /// The Hermite cubic from position `p0` and velocity `v0` to `p1`, `v1` in `h` s.
    pub fn hermite(p0: f64, v0: f64, p1: f64, v1: f64, h: f64) -> Cubic {
        let d = p1 - p0;
        Cubic {
            c: [
                p0,
                v0,
                (3.0 * d / h - 2.0 * v0 - v1) / h,
                (-2.0 * d / h + v0 + v1) / (h * h),
            ],
            h,
        }
    }

    /// A straight line from `p0` to `p1` in `h` s (its velocity constant, no acceleration
    /// inside the segment).
    pub fn line(p0: f64, p1: f64, h: f64) -> Cubic {
        Cubic {
            c: [p0, (p1 - p0) / h, 0.0, 0.0],
            h,
        }
    }

    /// The segment's duration, s.
    pub fn duration(&self) -> f64 {
        self.h
    }

    /// Position and velocity at `t` s from the start.
    pub fn at(&self, t: f64) -> (f64, f64) {
        let [c0, c1, c2, c3] = self.c;
        (
            c0 + t * (c1 + t * (c2 + t * c3)),
            c1 + t * (2.0 * c2 + t * 3.0 * c3),
        )
    }

    /// Acceleration at `t`.
    pub fn acceleration(&self, t: f64) -> f64 {
        2.0 * self.c[2] + 6.0 * self.c[3] * t
    }

    /// The exact extremes over `0..=h`: the velocity is quadratic and the acceleration
    /// linear, so they peak at the ends or where their derivative vanishes; the position peaks
    /// at the ends or where the velocity does.
    pub fn extremes(&self) -> Extremes {
        let [_, c1, c2, c3] = self.c;
        let h = self.h;
        let inside = |t: f64| t > 0.0 && t < h;
        // Where v = 0: 3 c3 t² + 2 c2 t + c1 = 0 (and the ends).
        let mut stops = [0.0, h, f64::NAN, f64::NAN];
        let (qa, qb, qc) = (3.0 * c3, 2.0 * c2, c1);
        if qa.abs() > 1e-300 {
            let disc = qb * qb - 4.0 * qa * qc;
            if disc >= 0.0 {
                let r = disc.sqrt();
                stops[2] = (-qb - r) / (2.0 * qa);
                stops[3] = (-qb + r) / (2.0 * qa);
            }
        } else if qb.abs() > 1e-300 {
            stops[2] = -qc / qb;
        }
        let (mut p_min, mut p_max) = ((f64::INFINITY, 0.0), (f64::NEG_INFINITY, 0.0));
        for (i, &t) in stops.iter().enumerate() {
            if i >= 2 && !inside(t) {
                continue;
            }
            let p = self.at(t).0;
            if p < p_min.0 {
                p_min = (p, t);
            }
            if p > p_max.0 {
                p_max = (p, t);
            }
        }
        // |v| peaks at the ends or at the vertex of the parabola (a = 0).
        let mut v = (0.0f64, 0.0);
        let vertex = if c3.abs() > 1e-300 {
            -c2 / (3.0 * c3)
        } else {
            f64::NAN
        };
        for (i, &t) in [0.0, h, vertex].iter().enumerate() {
            if i == 2 && !inside(t) {
                continue;
            }
            let s = self.at(t).1.abs();
            if s > v.0 {
                v = (s, t);
            }
        }
        let (a0, a1) = (self.acceleration(0.0).abs(), self.acceleration(h).abs());
        let a = if a1 > a0 { (a1, h) } else { (a0, 0.0) };
        Extremes { p_min, p_max, v, a }
    }
}

/// A joint's limits on a motion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    /// Position range, rad.
    pub min: f64,
    /// Upper end.
    pub max: f64,
    /// Speed, rad/s.
    pub v: f64,
    /// Acceleration, rad/s².
    pub a: f64,
}

/// A quick test that the Hermite segment from `p0`, `v0` to `p1`, `v1` in `h` s stays
/// within `b`: true only when it surely does, so that a caller checking many segments needs
/// the exact [`Cubic::extremes`] only for the others. Positions are bounded by the ends
/// widened by 4/27 · h · (|v0| + |v1|) (the largest the Hermite basis's slope terms reach);
/// speeds (the ends and the parabola's vertex) and accelerations (the ends) are exact. NaN is
/// never within.
pub fn hermite_within(p0: f64, v0: f64, p1: f64, v1: f64, h: f64, b: &Bounds) -> bool {
    let slack = 4.0 / 27.0 * h * (v0.abs() + v1.abs());
    if !(p0.min(p1) - slack >= b.min && p0.max(p1) + slack <= b.max) {
        return false;
    }
    let d = p1 - p0;
    let c2 = (3.0 * d / h - 2.0 * v0 - v1) / h;
    let c3 = (-2.0 * d / h + v0 + v1) / (h * h);
    let mut v = v0.abs().max(v1.abs());
    if c3 != 0.0 {
        let t = -c2 / (3.0 * c3);
        if t > 0.0 && t < h {
            v = v.max((v0 - c2 * c2 / (3.0 * c3)).abs());
        }
    }
    let a = (2.0 * c2).abs().max((2.0 * c2 + 6.0 * c3 * h).abs());
    !(v.is_nan() || a.is_nan() || over(v, b.v) || over(a, b.a))
}

/// True past a limit, with a small margin so that a motion exactly at it (a stop at the
/// acceleration limit) is not refused for rounding. NaN is past every limit.
pub fn over(x: f64, limit: f64) -> bool {
    x.is_nan() || x > limit * (1.0 + 1e-9) + 1e-12
}

/// What of a segment's extremes `e` lies beyond `b`, in words: its position range, its speed,
/// then the acceleration `acc` (the segment's own, `e.a`, or what the caller's interpolation
/// makes of it), each with its time, `t0` being the segment's start (s). None when it is all
/// within.
pub fn beyond(e: &Extremes, acc: (f64, f64), b: &Bounds, t0: f64) -> Option<String> {
    if !(e.p_min.0 >= b.min - 1e-12 && e.p_max.0 <= b.max + 1e-12) {
        let low = e.p_min.0.is_nan() || e.p_min.0 < b.min - 1e-12;
        let (p, dt) = if low { e.p_min } else { e.p_max };
        return Some(format!(
            "position {p:.4} rad at {:.3} s outside [{}, {}]",
            t0 + dt,
            b.min,
            b.max
        ));
    }
    if over(e.v.0, b.v) {
        return Some(format!(
            "velocity {:.3} rad/s at {:.3} s beyond {}",
            e.v.0,
            t0 + e.v.1,
            b.v
        ));
    }
    if over(acc.0, b.a) {
        return Some(format!(
            "acceleration {:.1} rad/s² at {:.3} s beyond {}",
            acc.0,
            t0 + acc.1,
            b.a
        ));
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The extremes by dense sampling, to hold the exact ones against.
    fn sampled(c: &Cubic) -> (f64, f64, f64, f64) {
        let n = 20_000;
        let (mut lo, mut hi, mut v, mut a) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64, 0.0f64);
        for i in 0..=n {
            let t = c.duration() * i as f64 / n as f64;
            let (p, vel) = c.at(t);
            lo = lo.min(p);
            hi = hi.max(p);
            v = v.max(vel.abs());
            a = a.max(c.acceleration(t).abs());
        }
        (lo, hi, v, a)
    }

    #[test]
    fn zero_velocity_rows_1_ms_apart_need_750_rad_s() {
        // The finding: rows 0 and 0.5 rad 1 ms apart, both at rest: the cubic peaks at
        // 1.5 x 0.5 / 0.001 = 750 rad/s halfway, and accelerates at 6 x 0.5 / 0.001² at the
        // ends.
        let c = Cubic::hermite(0.0, 0.0, 0.5, 0.0, 0.001);
        let e = c.extremes();
        assert!((e.v.0 - 750.0).abs() < 1e-9, "{e:?}");
        assert!((e.v.1 - 0.0005).abs() < 1e-12);
        assert!((e.a.0 - 3.0e6).abs() < 1e-3);
        assert_eq!((e.p_min.0, e.p_max.0), (0.0, 0.5));
    }

    #[test]
    fn overshoot_between_rows_is_found() {
        // Leaving 0 at 2 rad/s and arriving at 0.1 at rest in 0.2 s overshoots 0.1.
        let c = Cubic::hermite(0.0, 2.0, 0.1, 0.0, 0.2);
        let e = c.extremes();
        assert!(e.p_max.0 > 0.1 + 1e-3, "{e:?}");
        let (_, hi, _, _) = sampled(&c);
        assert!((e.p_max.0 - hi).abs() < 1e-7);
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(2000))]
        #[test]
        fn exact_extremes_match_dense_sampling(
            p0 in -2.0..2.0f64, p1 in -2.0..2.0f64, v0 in -5.0..5.0f64, v1 in -5.0..5.0f64,
            h in 0.001..0.3f64,
        ) {
            let c = Cubic::hermite(p0, v0, p1, v1, h);
            let (end_p, end_v) = c.at(h);
            proptest::prop_assert!((end_p - p1).abs() < 1e-9 && (end_v - v1).abs() < 1e-6);
            let e = c.extremes();
            let (lo, hi, v, a) = sampled(&c);
            // Sampling never exceeds the exact figures, and comes close to them.
            let tol = |x: f64| 1e-9 * (1.0 + x.abs());
            proptest::prop_assert!(lo >= e.p_min.0 - tol(lo) && hi <= e.p_max.0 + tol(hi));
            proptest::prop_assert!(v <= e.v.0 + tol(v) && a <= e.a.0 + tol(a));
            proptest::prop_assert!((e.p_min.0 - lo).abs() < 1e-6 * (1.0 + lo.abs()));
            proptest::prop_assert!((e.p_max.0 - hi).abs() < 1e-6 * (1.0 + hi.abs()));
            proptest::prop_assert!((e.v.0 - v).abs() < 1e-4 * (1.0 + v));
            proptest::prop_assert!((e.a.0 - a).abs() < 1e-9 * (1.0 + a));
        }

        #[test]
        fn the_quick_test_passes_only_what_the_exact_extremes_pass(
            p0 in -1.05..1.05f64, p1 in -1.05..1.05f64, v0 in -3.2..3.2f64,
            v1 in -3.2..3.2f64, h in 0.001..0.3f64,
        ) {
            let b = Bounds { min: -1.0, max: 1.0, v: 3.0, a: 60.0 };
            let e = Cubic::hermite(p0, v0, p1, v1, h).extremes();
            let exact = beyond(&e, e.a, &b, 0.0).is_none();
            if hermite_within(p0, v0, p1, v1, h, &b) {
                proptest::prop_assert!(exact, "{e:?}");
            }
        }
    }

    #[test]
    fn the_quick_test_passes_smooth_rows_and_refuses_nan() {
        let b = Bounds {
            min: -1.0,
            max: 1.0,
            v: 3.0,
            a: 60.0,
        };
        // A sine's rows 10 ms apart, well inside.
        let f = |t: f64| (0.5 * (3.0 * t).sin(), 1.5 * (3.0 * t).cos());
        let passed = (0..100)
            .filter(|&i| {
                let (t0, t1) = (i as f64 * 0.01, (i + 1) as f64 * 0.01);
                let ((p0, v0), (p1, v1)) = (f(t0), f(t1));
                hermite_within(p0, v0, p1, v1, 0.01, &b)
            })
            .count();
        assert_eq!(passed, 100);
        assert!(!hermite_within(f64::NAN, 0.0, 0.0, 0.0, 0.01, &b));
        assert!(!hermite_within(0.0, 0.0, 0.0, f64::NAN, 0.01, &b));
    }
}
