//! ZMP preview control on the cart-table model (Kajita et al., ICRA 2003), the default COM
//! pattern: the COM at constant height z_c is a cart driven by its jerk u, state
//! x = (x, ẋ, ẍ) sampled every T s,
//!
//! x⁺ = A x + B u,  A = [[1, T, T²/2], [0, 1, T], [0, 0, 1]],  B = (T³/6, T²/2, T),
//!
//! and its ZMP is the table's centre of pressure p = C x = x − (z_c / g) ẍ. The jerk is the
//! optimal preview servo of Katayama et al. (1985) as Kajita uses it: with the tracking
//! error's sum and the state's increment in an augmented system (Ã, B̃), the discrete
//! Riccati equation's solution P gives the integral gain G_i, the state gain G_x and the
//! preview gains G_p(j) for the next N references:
//!
//! u_k = −G_i Σ_{i ≤ k} (C x_i − p_ref,i) − G_x x_k − Σ_{j=1..N} G_p(j) p_ref,k+j.
//!
//! The Riccati equation is solved by its doubling iteration on nalgebra's 4 × 4 matrices. x and y are two independent carts with the same gains. The state
//! carries over from one reference to the next ([`Cart`]), so a new plan mid-walk continues
//! the COM's position, velocity and acceleration exactly.

use nalgebra::{Matrix3, Matrix4, RowVector3, Vector3, Vector4};
use serde::Deserialize;

use crate::GaitError;

/// The controller's parameters.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PreviewConfig {
    /// Control period T, s.
    pub period: f64,
    /// Preview horizon, s (N = horizon / T references ahead).
    pub horizon: f64,
    /// Weight of the ZMP tracking error's sum, Q_e.
    pub q_e: f64,
    /// Weight of the jerk, R.
    pub r: f64,
}

impl Default for PreviewConfig {
    /// Kajita's: T = 5 ms, Q_e = 1, R = 10⁻⁶; a 6 s horizon: three steps of the longest step
    /// time (T_max = 2 s; Kajita's 1.6 s saw two of 0.8 s).
    fn default() -> PreviewConfig {
        PreviewConfig {
            period: 0.005,
            horizon: 6.0,
            q_e: 1.0,
            r: 1e-6,
        }
    }
}

/// The stabilising solution of the discrete algebraic Riccati equation
/// P = Q + AᵀPA − AᵀPB (R + BᵀPB)⁻¹ BᵀPA for a single input (B a column, R a scalar), by
/// the structure-preserving doubling algorithm (quadratic convergence).
fn dare(
    a: &Matrix4<f64>,
    b: &Vector4<f64>,
    q: &Matrix4<f64>,
    r: f64,
) -> Result<Matrix4<f64>, GaitError> {
    // G = B R⁻¹ Bᵀ, H = Q, A_k = A.
    let mut ak = *a;
    let mut g = b * b.transpose() / r;
    let mut h = *q;
    for _ in 0..200 {
        // W = (I + G H)⁻¹, by LU with partial pivoting (I + G H is ill-conditioned: with
        // R = 10⁻⁶ the cofactor formula of a 4 × 4 inverse loses the gains' third digit).
        let w = (Matrix4::identity() + g * h)
            .lu()
            .try_inverse()
            .ok_or_else(|| GaitError::Parameter("the Riccati iteration is singular".into()))?;
        let aw = ak * w;
        let g_next = g + aw * g * ak.transpose();
        let h_next = h + ak.transpose() * h * w * ak;
        let a_next = aw * ak;
        let change = h_next
            .iter()
            .zip(h.iter())
            .map(|(n, o)| (n - o).abs() / (1.0 + n.abs()))
            .fold(0.0, f64::max);
        ak = a_next;
        g = g_next;
        h = h_next;
        if !change.is_finite() {
            break;
        }
        if change < 1e-14 {
            return Ok(h);
        }
    }
    Err(GaitError::Parameter(
        "the Riccati equation of the preview controller did not converge".into(),
    ))
}

/// Σ a_i b_i over the shorter of the two, in eight running sums (the additions of one sum
/// wait for each other; eight at once keep the processor's adders busy and let the compiler
/// use its vector registers).
#[inline]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for i in 0..8 {
            acc[i] += x[i] * y[i];
        }
    }
    let mut tail = 0.0;
    for (x, y) in ra.iter().zip(rb) {
        tail += x * y;
    }
    (acc[0] + acc[4]) + (acc[1] + acc[5]) + (acc[2] + acc[6]) + (acc[3] + acc[7]) + tail
}

/// The preview controller's gains for one COM height.
#[derive(Debug, Clone, PartialEq)]
pub struct Preview {
    cfg: PreviewConfig,
    z_c: f64,
    g: f64,
    a: [[f64; 3]; 3],
    b: [f64; 3],
    c: [f64; 3],
    /// Integral gain G_i.
    gi: f64,
    /// State gain G_x.
    gx: [f64; 3],
    /// Preview gains G_p(1..=N).
    gp: Vec<f64>,
    /// Ã_cᵀ, X(1), X(N − 1) and B̃ / (R + B̃ᵀPB̃): G_p(j) = B̃ᵀ Ã_cᵀ^(j−2) X(1) / (R + B̃ᵀPB̃)
    /// for j ≥ 2, for the preview sums by recursion ([`Preview::preview_terms_recursive`]).
    act: Matrix4<f64>,
    x1: Vector4<f64>,
    xn: Vector4<f64>,
    bd: Vector4<f64>,
}

/// One cart (one axis) with the sum of its tracking errors.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Cart {
    /// Position, velocity, acceleration.
    pub x: [f64; 3],
    /// Σ (C x − p_ref) so far.
    pub err_sum: f64,
}

impl Preview {
    /// The gains for a COM at `z_c` m under gravity `g`.
    pub fn new(cfg: PreviewConfig, z_c: f64, g: f64) -> Result<Preview, GaitError> {
        for (name, v) in [
            ("period", cfg.period),
            ("horizon", cfg.horizon),
            ("q_e", cfg.q_e),
            ("r", cfg.r),
            ("z_c", z_c),
            ("g", g),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(GaitError::Parameter(format!(
                    "preview control: {name} must be positive and finite, not {v}"
                )));
            }
        }
        let n = (cfg.horizon / cfg.period).round() as usize;
        if n < 1 {
            return Err(GaitError::Parameter(
                "preview control: the horizon must be at least one period".into(),
            ));
        }
        let t = cfg.period;
        let a = [[1.0, t, t * t / 2.0], [0.0, 1.0, t], [0.0, 0.0, 1.0]];
        let b = [t * t * t / 6.0, t * t / 2.0, t];
        let c = [1.0, 0.0, -z_c / g];
        // Augmented system: (e_k, Δx_k) with e the tracking error.
        let (am, bm, cm) = (
            Matrix3::from_row_slice(&a.concat()),
            Vector3::from(b),
            RowVector3::from(c),
        );
        let mut at = Matrix4::zeros();
        at[(0, 0)] = 1.0;
        at.fixed_view_mut::<1, 3>(0, 1).copy_from(&(cm * am));
        at.fixed_view_mut::<3, 3>(1, 1).copy_from(&am);
        let bt = Vector4::new((cm * bm)[0], b[0], b[1], b[2]);
        let mut q = Matrix4::zeros();
        q[(0, 0)] = cfg.q_e;
        let p = dare(&at, &bt, &q, cfg.r)?;
        let denom = cfg.r + bt.dot(&(p * bt));
        // K = (R + B̃ᵀPB̃)⁻¹ B̃ᵀ P Ã = [G_i, G_x]
        let k = bt.transpose() * p * at / denom;
        let gi = k[0];
        let gx = [k[1], k[2], k[3]];
        // Ã_c = Ã − B̃ K; X(1) = −Ã_cᵀ P Ĩ; G_p(1) = −G_i; G_p(j) = B̃ᵀ X(j−1) / denom.
        let act = (at - bt * k).transpose();
        let x1 = -(act * p.column(0));
        let (mut x, mut xn) = (x1, x1);
        let mut gp = Vec::with_capacity(n);
        gp.push(-gi);
        for _ in 1..n {
            gp.push(bt.dot(&x) / denom);
            xn = x;
            x = act * x;
        }
        if !(gi.is_finite() && gx.iter().all(|v| v.is_finite()) && gp.iter().all(|v| v.is_finite()))
        {
            return Err(GaitError::Parameter(
                "preview control: the gains are not finite".into(),
            ));
        }
        Ok(Preview {
            cfg,
            z_c,
            g,
            a,
            b,
            c,
            gi,
            gx,
            gp,
            act,
            x1,
            xn,
            bd: bt / denom,
        })
    }

    /// The parameters.
    pub fn config(&self) -> &PreviewConfig {
        &self.cfg
    }

    /// The COM height the gains are for, m.
    pub fn z_c(&self) -> f64 {
        self.z_c
    }

    /// Gravity, m/s².
    pub fn g(&self) -> f64 {
        self.g
    }

    /// N: how many references ahead each tick reads.
    pub fn horizon_ticks(&self) -> usize {
        self.gp.len()
    }

    /// The preview gains G_p(1..=N).
    pub fn preview_gains(&self) -> &[f64] {
        &self.gp
    }

    /// The integral and state gains.
    pub fn gains(&self) -> (f64, [f64; 3]) {
        (self.gi, self.gx)
    }

    /// The cart-table ZMP of a state: x − (z_c / g) ẍ.
    pub fn zmp(&self, x: &[f64; 3]) -> f64 {
        self.c[0] * x[0] + self.c[2] * x[2]
    }

    /// One tick of one axis: `now` is p_ref,k and `ahead` holds p_ref,k+1 onwards (at least
    /// N of them; see [`Preview::horizon_ticks`]). Returns the jerk applied.
    #[inline]
    pub fn tick(&self, cart: &mut Cart, now: f64, ahead: &[f64]) -> f64 {
        self.tick_with(cart, now, dot(&self.gp, ahead))
    }

    /// [`Preview::tick`] with its preview term Σ G_p(j) p_ref,k+j given (see
    /// [`Preview::preview_terms`]).
    #[inline]
    pub fn tick_with(&self, cart: &mut Cart, now: f64, preview: f64) -> f64 {
        let x = cart.x;
        cart.err_sum += self.zmp(&x) - now;
        let u = -self.gi * cart.err_sum
            - (self.gx[0] * x[0] + self.gx[1] * x[1] + self.gx[2] * x[2])
            - preview;
        let a = &self.a;
        cart.x = [
            a[0][0] * x[0] + a[0][1] * x[1] + a[0][2] * x[2] + self.b[0] * u,
            x[1] + a[1][2] * x[2] + self.b[1] * u,
            x[2] + self.b[2] * u,
        ];
        u
    }

    /// Bumpless transfer: sets the cart's error sum so that its next tick (with the reference
    /// `now` and `ahead`) applies the jerk `u`: the controller takes over a cart in motion (a
    /// pendulum's, a pattern's before a new plan) from the jerk it has, and the error sum,
    /// a free state of the controller, carries the difference away over time.
    pub fn bumpless(&self, cart: &mut Cart, now: f64, ahead: &[f64], u: f64) {
        let x = cart.x;
        let preview = dot(&self.gp, ahead);
        let sum =
            -(u + self.gx[0] * x[0] + self.gx[1] * x[1] + self.gx[2] * x[2] + preview) / self.gi;
        cart.err_sum = sum - (self.zmp(&x) - now);
    }

    /// The preview terms Σ_{j=1..N} G_p(j) · reference[k + j] of the ticks k in `0..ticks`
    /// at once (`reference` holds at least `ticks + N` samples). A ZMP reference is made of
    /// straight runs (constant on a sole, a line across a double support): each run's share
    /// of a horizon comes from two running sums of the gains (Σ G_p(j) and Σ j G_p(j)), a
    /// few operations for each run in the horizon instead of N multiplications. Equal to the
    /// direct sums up to rounding; any reference works (a curved one makes short runs).
    pub fn preview_terms(&self, reference: &[f64], ticks: usize) -> Result<Vec<f64>, GaitError> {
        let n = self.gp.len();
        if reference.len() < ticks + n {
            return Err(GaitError::Parameter(format!(
                "preview control: {} references for {ticks} ticks and a horizon of {n}",
                reference.len()
            )));
        }
        // Running sums from j = 1: s0[m] = Σ_{j≤m} G_p(j), s1[m] = Σ_{j≤m} j G_p(j).
        let mut s0 = vec![0.0; n + 1];
        let mut s1 = vec![0.0; n + 1];
        for j in 1..=n {
            s0[j] = s0[j - 1] + self.gp[j - 1];
            s1[j] = s1[j - 1] + j as f64 * self.gp[j - 1];
        }
        // The runs: [first, last] with reference[i] = value + slope · (i − first).
        let end = ticks + n;
        let mut runs: Vec<(usize, usize, f64, f64)> = Vec::new();
        let mut a = 0;
        while a < end {
            let v = reference[a];
            let slope = if a + 1 < end {
                reference[a + 1] - v
            } else {
                0.0
            };
            let mut b = (a + 1).min(end - 1);
            while b + 1 < end {
                let want = v + slope * (b + 1 - a) as f64;
                if (reference[b + 1] - want).abs() > 1e-12 * (1.0 + want.abs()) {
                    break;
                }
                b += 1;
            }
            if !(v.is_finite() && slope.is_finite()) {
                return Err(GaitError::Parameter(
                    "preview control: a reference that is not finite".into(),
                ));
            }
            runs.push((a, b, v, slope));
            a = b + 1;
        }
        let mut out = Vec::with_capacity(ticks);
        let mut first = 0;
        for k in 0..ticks {
            // The horizon: reference indices k + 1 ..= k + n.
            while runs[first].1 < k + 1 {
                first += 1;
            }
            let mut sum = 0.0;
            for &(lo, hi, v, slope) in &runs[first..] {
                if lo > k + n {
                    break;
                }
                let (j0, j1) = (lo.max(k + 1) - k, hi.min(k + n) - k);
                // Σ_{j0..=j1} G_p(j) (v + slope (k + j − lo)).
                let base = v + slope * (k as f64 - lo as f64);
                sum += base * (s0[j1] - s0[j0 - 1]) + slope * (s1[j1] - s1[j0 - 1]);
            }
            out.push(sum);
        }
        Ok(out)
    }

    /// The preview terms of [`Preview::preview_terms`] for any reference (a curved one too) in
    /// a few operations a tick: with W_k = Σ_{j=2..N} Ã_cᵀ^(j−2) X(1) r_{k+j}, the term is
    /// −G_i r_{k+1} + B̃ᵀ W_k / (R + B̃ᵀPB̃), and W_k = X(1) r_{k+2} + Ã_cᵀ (W_{k+1} − X(N−1)
    /// r_{k+N+1}), run backward from the last tick (Ã_c is stable: rounding dies out).
    pub fn preview_terms_recursive(
        &self,
        reference: &[f64],
        ticks: usize,
    ) -> Result<Vec<f64>, GaitError> {
        let n = self.gp.len();
        if reference.len() < ticks + n {
            return Err(GaitError::Parameter(format!(
                "preview control: {} references for {ticks} ticks and a horizon of {n}",
                reference.len()
            )));
        }
        if reference[..ticks + n].iter().any(|v| !v.is_finite()) {
            return Err(GaitError::Parameter(
                "preview control: a reference that is not finite".into(),
            ));
        }
        let mut out = vec![0.0; ticks];
        if ticks == 0 {
            return Ok(out);
        }
        let gi = self.gi;
        if n < 2 {
            for (k, o) in out.iter_mut().enumerate() {
                *o = -gi * reference[k + 1];
            }
            return Ok(out);
        }
        // The last tick's W by Horner's rule, then back.
        let last = ticks - 1;
        let mut w = self.x1 * reference[last + n];
        for j in (2..n).rev() {
            w = self.x1 * reference[last + j] + self.act * w;
        }
        out[last] = -gi * reference[last + 1] + self.bd.dot(&w);
        for k in (0..last).rev() {
            w = self.x1 * reference[k + 2] + self.act * (w - self.xn * reference[k + n + 1]);
            out[k] = -gi * reference[k + 1] + self.bd.dot(&w);
        }
        Ok(out)
    }

    /// Runs one axis over a whole reference: from `cart`, a tick per reference sample
    /// `reference[k]` for k in `0..ticks`, reading ahead into the reference (which must hold
    /// at least `ticks + N` samples: pad it with its last value). Returns the states after
    /// each tick.
    pub fn run(
        &self,
        cart: &mut Cart,
        reference: &[f64],
        ticks: usize,
    ) -> Result<Vec<[f64; 3]>, GaitError> {
        let n = self.gp.len();
        if reference.len() < ticks + n {
            return Err(GaitError::Parameter(format!(
                "preview control: {} references for {ticks} ticks and a horizon of {n}",
                reference.len()
            )));
        }
        let mut out = Vec::with_capacity(ticks);
        for k in 0..ticks {
            self.tick(cart, reference[k], &reference[k + 1..k + 1 + n]);
            out.push(cart.x);
        }
        Ok(out)
    }
}
