//! The swing foot's path: per axis, a C² cubic spline from lift-off to touch-down through
//! three via points at configured times, with zero velocity and zero acceleration at both
//! ends (the foot leaves and meets the ground without a jolt).
//!
//! Four end conditions and the via points over-determine a plain interpolating cubic spline,
//! so two free knots are added, in the middle of the first and the last interval, and their
//! positions solved for with the spline's second derivatives (the construction of Biagiotti
//! and Melchiorri's *Trajectory Planning for Automatic Machines and Robots*, §4.4.4).

use nalgebra::{DMatrix, DVector};
use serde::Deserialize;

use crate::GaitError;

/// A cubic spline of one axis, C² over its knots.
#[derive(Debug, Clone, PartialEq)]
pub struct Spline {
    t: Vec<f64>,
    q: Vec<f64>,
    /// Second derivatives at the knots.
    m: Vec<f64>,
    /// Velocity and acceleration before the first knot and after the last.
    ends: [[f64; 2]; 2],
    /// Each interval's cubic in the time from its first knot: c0 + c1 w + c2 w² + c3 w³.
    coef: Vec<[f64; 4]>,
}

impl Spline {
    /// The spline through `points` at `times` (strictly increasing, at least three), at rest
    /// with zero acceleration at the first and the last.
    pub fn at_rest(times: &[f64], points: &[f64]) -> Result<Spline, GaitError> {
        Spline::with_ends(times, points, [0.0, 0.0], [0.0, 0.0])
    }

    /// The spline through `points` at `times` (strictly increasing, at least three) with the
    /// velocity and acceleration `start` = [v, a] at the first and `end` at the last.
    pub fn with_ends(
        times: &[f64],
        points: &[f64],
        start: [f64; 2],
        end: [f64; 2],
    ) -> Result<Spline, GaitError> {
        let bad = |m: &str| Err(GaitError::Parameter(m.into()));
        if times.len() != points.len() || times.len() < 3 {
            return bad("a spline needs as many times as points, at least three");
        }
        if !times.windows(2).all(|w| w[0] < w[1]) || !times.iter().all(|t| t.is_finite()) {
            return bad("a spline's times must be finite and strictly increasing");
        }
        if !points
            .iter()
            .chain(&start)
            .chain(&end)
            .all(|p| p.is_finite())
        {
            return bad("a spline's points and end conditions must be finite");
        }
        // Knots: the first, a free one halfway to the second, the inner ones, a free one
        // halfway from the last but one, the last.
        let k = times.len();
        let mut t = vec![times[0], (times[0] + times[1]) / 2.0];
        t.extend_from_slice(&times[1..k - 1]);
        t.push((times[k - 2] + times[k - 1]) / 2.0);
        t.push(times[k - 1]);
        let mut q = vec![points[0], f64::NAN];
        q.extend_from_slice(&points[1..k - 1]);
        q.push(f64::NAN);
        q.push(points[k - 1]);
        let m = t.len() - 1; // knots 0..=m; M_0 and M_m given
        let (m0, mm) = (start[1], end[1]);
        let h: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
        // Unknowns: M_1..M_{m-1} (m - 1 of them), then q_1 and q_{m-1}.
        let n = m + 1;
        let (iq1, iqm) = (m - 1, m);
        let mut a = DMatrix::<f64>::zeros(n, n);
        let mut b = DVector::<f64>::zeros(n);
        // Adds c·q_j to row r: to the unknowns if q_j is free, else to the right-hand side.
        let add_q = |a: &mut DMatrix<f64>, b: &mut DVector<f64>, r: usize, j: usize, c: f64| {
            if j == 1 {
                a[(r, iq1)] += c;
            } else if j == m - 1 {
                a[(r, iqm)] += c;
            } else {
                b[r] -= c * q[j];
            }
        };
        // Continuity of the first derivative at knots 1..m-1:
        // h_{i-1} M_{i-1} + 2 (h_{i-1} + h_i) M_i + h_i M_{i+1}
        //   - 6 [(q_{i+1} - q_i) / h_i - (q_i - q_{i-1}) / h_{i-1}] = 0.
        for i in 1..m {
            let r = i - 1;
            if i > 1 {
                a[(r, i - 2)] += h[i - 1];
            } else {
                b[r] -= h[0] * m0;
            }
            a[(r, i - 1)] += 2.0 * (h[i - 1] + h[i]);
            if i + 1 < m {
                a[(r, i)] += h[i];
            } else {
                b[r] -= h[m - 1] * mm;
            }
            add_q(&mut a, &mut b, r, i + 1, -6.0 / h[i]);
            add_q(&mut a, &mut b, r, i, 6.0 / h[i] + 6.0 / h[i - 1]);
            add_q(&mut a, &mut b, r, i - 1, -6.0 / h[i - 1]);
        }
        // The start's velocity: (q_1 - q_0) / h_0 - h_0 (2 M_0 + M_1) / 6 = v_0.
        let r = m - 1;
        add_q(&mut a, &mut b, r, 1, 1.0 / h[0]);
        add_q(&mut a, &mut b, r, 0, -1.0 / h[0]);
        a[(r, 0)] += -h[0] / 6.0;
        b[r] += start[0] + h[0] * m0 / 3.0;
        // The end's: (q_m - q_{m-1}) / h_{m-1} + h_{m-1} (M_{m-1} + 2 M_m) / 6 = v_m.
        let r = m;
        add_q(&mut a, &mut b, r, m, 1.0 / h[m - 1]);
        add_q(&mut a, &mut b, r, m - 1, -1.0 / h[m - 1]);
        a[(r, m - 2)] += h[m - 1] / 6.0;
        b[r] += end[0] - h[m - 1] * mm / 3.0;
        let x = a
            .lu()
            .solve(&b)
            .filter(|x| x.iter().all(|v| v.is_finite()))
            .ok_or_else(|| GaitError::Parameter("the spline's system is singular".into()))?;
        q[1] = x[iq1];
        q[m - 1] = x[iqm];
        let mut mv = vec![0.0; m + 1];
        mv[0] = m0;
        mv[m] = mm;
        mv[1..m].copy_from_slice(&x.as_slice()[..m - 1]);
        // p = M_i u³/6h + M_{i+1} w³/6h + A u + B w (u = h − w, A = q_i/h − M_i h/6,
        // B = q_{i+1}/h − M_{i+1} h/6), expanded in w.
        let coef = (0..m)
            .map(|i| {
                let (hi, m0, m1) = (h[i], mv[i], mv[i + 1]);
                let a = q[i] / hi - m0 * hi / 6.0;
                let b = q[i + 1] / hi - m1 * hi / 6.0;
                [
                    q[i],
                    b - a - m0 * hi / 2.0,
                    m0 / 2.0,
                    (m1 - m0) / (6.0 * hi),
                ]
            })
            .collect();
        Ok(Spline {
            t,
            q,
            m: mv,
            ends: [start, end],
            coef,
        })
    }

    /// The spline's knots: (time, position), the two free ones included.
    pub fn knots(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.t.iter().copied().zip(self.q.iter().copied())
    }

    /// Position, velocity and acceleration at `t` (outside the knots, continued with the end's
    /// velocity and acceleration: at rest, held).
    #[inline]
    pub fn eval(&self, t: f64) -> [f64; 3] {
        self.eval_in(self.interval(t), t)
    }

    /// The interval of the knots holding `t` (None before the first knot or after the last).
    #[inline]
    fn interval(&self, t: f64) -> Option<usize> {
        let last = self.t.len() - 1;
        if t < self.t[0] || t > self.t[last] {
            return None;
        }
        Some(self.t.partition_point(|&k| k <= t).clamp(1, last) - 1)
    }

    /// [`Spline::eval`] with `t`'s interval found ([`Spline::interval`] of this spline or of
    /// one with the same knots).
    #[inline]
    fn eval_in(&self, interval: Option<usize>, t: f64) -> [f64; 3] {
        let last = self.t.len() - 1;
        if let Some(i) = interval {
            let w = t - self.t[i];
            let [c0, c1, c2, c3] = self.coef[i];
            return [
                c0 + w * (c1 + w * (c2 + w * c3)),
                c1 + w * (2.0 * c2 + 3.0 * c3 * w),
                2.0 * c2 + 6.0 * c3 * w,
            ];
        }
        if t < self.t[0] {
            let [v, a] = self.ends[0];
            let d = t - self.t[0];
            return [self.q[0] + v * d + a * d * d / 2.0, v + a * d, a];
        }
        let [v, a] = self.ends[1];
        let d = t - self.t[last];
        [self.q[last] + v * d + a * d * d / 2.0, v + a * d, a]
    }
}

/// Where the swing's via points are: at which fraction of the swing's time, how far along
/// the way from lift-off to touch-down, and how high between the ground line and the apex.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Via {
    /// Fraction of the swing's duration (0 to 1).
    pub time: f64,
    /// Fraction of the horizontal way (0 to 1).
    pub along: f64,
    /// Fraction of the apex's height above the ground line (0 to 1).
    pub height: f64,
}

/// The swing's shape.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SwingConfig {
    /// The three via points.
    pub via: [Via; 3],
    /// Clearance above what the foot steps over (the higher end, or the plan's obstacle), m.
    pub clearance: f64,
}

impl Default for SwingConfig {
    /// A minimum-jerk-like path (the via points where a minimum-jerk motion of each axis is
    /// at a quarter, half and three quarters of its time: the least acceleration); 3 cm above
    /// what it clears.
    fn default() -> SwingConfig {
        SwingConfig {
            via: [
                Via {
                    time: 0.25,
                    along: 0.1,
                    height: 0.5,
                },
                Via {
                    time: 0.5,
                    along: 0.5,
                    height: 1.0,
                },
                Via {
                    time: 0.75,
                    along: 0.9,
                    height: 0.5,
                },
            ],
            clearance: 0.03,
        }
    }
}

/// A swing foot's path: a spline per axis (x, y, z and the heading) over [0, duration].
#[derive(Debug, Clone, PartialEq)]
pub struct SwingPath {
    /// x, y, z and yaw.
    pub axes: [Spline; 4],
    /// The apex's height, m.
    pub apex: f64,
    /// The swing's duration, s.
    pub duration: f64,
}

/// A foot's place (x, y, z in m, yaw in rad).
pub type Place = [f64; 4];

impl SwingPath {
    /// The path from `from` to `to` over `duration` seconds, at rest at both ends, clearing
    /// `over` (the top of what it steps over, m; the ends' height when nothing) by the
    /// configured clearance.
    pub fn new(
        from: Place,
        to: Place,
        over: f64,
        duration: f64,
        cfg: &SwingConfig,
    ) -> Result<SwingPath, GaitError> {
        SwingPath::from_state([from, [0.0; 4], [0.0; 4]], to, over, duration, cfg)
    }

    /// The path from a foot in motion (`now`: place, velocity, acceleration) to `to`, where
    /// it arrives at rest `duration` seconds later: a swing retargeted midway continues with
    /// its position, velocity and acceleration. Its via points divide the remaining way.
    pub fn from_state(
        now: [Place; 3],
        to: Place,
        over: f64,
        duration: f64,
        cfg: &SwingConfig,
    ) -> Result<SwingPath, GaitError> {
        if !(duration.is_finite() && duration > 0.0) {
            return Err(GaitError::Parameter(format!(
                "a swing's duration must be positive, not {duration}"
            )));
        }
        if !(cfg.via.windows(2).all(|w| w[0].time < w[1].time)
            && cfg.via[0].time > 0.0
            && cfg.via[2].time < 1.0)
        {
            return Err(GaitError::Parameter(
                "the via points' times must be increasing, inside (0, 1)".into(),
            ));
        }
        if !over.is_finite() || !to.iter().all(|v| v.is_finite()) {
            return Err(GaitError::Parameter(
                "a swing's target and height must be finite".into(),
            ));
        }
        let from = now[0];
        let apex = from[2].max(to[2]).max(over) + cfg.clearance;
        let times: Vec<f64> = std::iter::once(0.0)
            .chain(cfg.via.iter().map(|v| v.time * duration))
            .chain(std::iter::once(duration))
            .collect();
        // The heading goes the short way round.
        let turn = (to[3] - from[3] + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
            - std::f64::consts::PI;
        let target = [to[0], to[1], to[2], from[3] + turn];
        let axis = |k: usize| -> Result<Spline, GaitError> {
            let mut pts = vec![from[k]];
            for v in &cfg.via {
                let ground = from[k] + v.along * (target[k] - from[k]);
                pts.push(if k == 2 {
                    ground + v.height * (apex - ground)
                } else {
                    ground
                });
            }
            pts.push(target[k]);
            Spline::with_ends(&times, &pts, [now[1][k], now[2][k]], [0.0, 0.0])
        };
        Ok(SwingPath {
            axes: [axis(0)?, axis(1)?, axis(2)?, axis(3)?],
            apex,
            duration,
        })
    }

    /// Place, velocity and acceleration of the foot at `t` seconds into the swing.
    #[inline]
    pub fn at(&self, t: f64) -> [Place; 3] {
        // The axes share their knots (the via points' times).
        let i = self.axes[0].interval(t);
        let e = self.axes.each_ref().map(|a| a.eval_in(i, t));
        [
            std::array::from_fn(|k| e[k][0]),
            std::array::from_fn(|k| e[k][1]),
            std::array::from_fn(|k| e[k][2]),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_spline_is_c2_through_its_points_with_its_end_conditions() {
        let times = [0.0, 0.2, 0.5, 0.7, 1.0];
        let pts = [0.0, 0.3, 0.1, 0.4, 0.2];
        let s = Spline::with_ends(&times, &pts, [0.5, -2.0], [0.1, 0.3]).unwrap();
        for (t, p) in times.iter().zip(pts) {
            assert!((s.eval(*t)[0] - p).abs() < 1e-12);
        }
        let e0 = s.eval(0.0);
        assert!(
            (e0[1] - 0.5).abs() < 1e-9 && (e0[2] + 2.0).abs() < 1e-9,
            "{e0:?}"
        );
        let e1 = s.eval(1.0);
        assert!(
            (e1[1] - 0.1).abs() < 1e-9 && (e1[2] - 0.3).abs() < 1e-9,
            "{e1:?}"
        );
        // Continuous position, velocity and acceleration at every knot.
        for (k, _) in s.knots() {
            let (a, b) = (s.eval(k - 1e-9), s.eval(k + 1e-9));
            assert!((a[0] - b[0]).abs() < 1e-8, "{k}");
            assert!((a[1] - b[1]).abs() < 1e-6, "{k}");
            assert!((a[2] - b[2]).abs() < 1e-5, "{k}");
        }
    }
}
