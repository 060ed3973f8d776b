//! The 3-D linear inverted pendulum (Archie's chapter 2.1, after Kajita et al.): the COM at
//! constant height z_c over a point foot, ẍ = (g / z_c)(x − p), with T_c = √(z_c / g).
//!
//! - Over a support period T_sup about a foot p (eqs 16-19), with C = cosh(T_sup / T_c) and
//!   S = sinh(T_sup / T_c): x_f = C x_i + T_c S ẋ_i + (1 − C) p, ẋ_f = (S / T_c)(x_i − p) + C ẋ_i.
//! - A walk primitive (eqs 10-14, 25-26) is the symmetric arc from (−x̄, v̄_x) to (x̄, v̄_x), from
//!   (ȳ, −v̄_y) to (ȳ, v̄_y): v̄_x = x̄ (C + 1) / (T_c S), v̄_y = ȳ (C − 1) / (T_c S); x̄ = s_x / 2 and
//!   ȳ = (−1)ⁿ s_y / 2 of the next step's walk parameters, turned by its heading.
//! - The modified foot placement (eqs 20-24) puts the foot where the step ends nearest the
//!   primitive's state: it minimises N = a (x^d − x_f)² + b (ẋ^d − ẋ_f)².
//! - Footsteps from walk parameters: eq 95 (straight), 96 (turning), 97-98 (Archie's, from the
//!   COM's ground track).
//!
//! The thesis gives no z_c, a, b or initial state: they are the caller's (the gait's config).
//! Eq 7's misprinted velocity line runs as printed behind [`Faithful::eq_7`].

use serde::Deserialize;

use crate::GaitError;

/// Standard gravity, m/s².
pub const G: f64 = 9.80665;

/// The thesis's equations run as printed, each behind its own flag.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Faithful {
    /// Eq 7's second line as printed: ẋ(t) = (x(0) / T_c) sinh(t / T_c) + (ẋ(0) / T_c) cosh(t / T_c).
    pub eq_7: bool,
}

/// The pendulum's and the foot placement's parameters.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LipmConfig {
    /// The COM's height above the ground, m.
    pub z_c: f64,
    /// The support period, s.
    pub t_sup: f64,
    /// Gravity, m/s².
    #[serde(default = "default_g")]
    pub g: f64,
    /// Weight of the terminal position's error (eq 22).
    pub a: f64,
    /// Weight of the terminal velocity's error (eq 22).
    pub b: f64,
    /// Published equations run as printed.
    #[serde(default)]
    pub faithful: Faithful,
}

fn default_g() -> f64 {
    G
}

/// A COM state in the plane: position (m) and velocity (m/s).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct State {
    /// Position, x and y.
    pub x: [f64; 2],
    /// Velocity, x and y.
    pub v: [f64; 2],
}

/// One step's walk parameters (eq 13): the step length s_x, the width s_y, the heading s_θ.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct WalkParam {
    /// Step length, m.
    pub sx: f64,
    /// Step width, m.
    pub sy: f64,
    /// Heading, rad.
    pub theta: f64,
}

/// The pendulum with its constants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pendulum {
    cfg: LipmConfig,
    tc: f64,
    c: f64,
    s: f64,
}

fn rot(theta: f64, v: [f64; 2]) -> [f64; 2] {
    let (s, c) = theta.sin_cos();
    [c * v[0] - s * v[1], s * v[0] + c * v[1]]
}

impl Pendulum {
    /// Checks the parameters: positive finite height, period, gravity and weights.
    pub fn new(cfg: LipmConfig) -> Result<Pendulum, GaitError> {
        for (name, v) in [
            ("z_c", cfg.z_c),
            ("t_sup", cfg.t_sup),
            ("g", cfg.g),
            ("a", cfg.a),
            ("b", cfg.b),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(GaitError::Parameter(format!(
                    "{name} must be positive and finite, not {v}"
                )));
            }
        }
        let tc = (cfg.z_c / cfg.g).sqrt();
        Ok(Pendulum {
            cfg,
            tc,
            c: (cfg.t_sup / tc).cosh(),
            s: (cfg.t_sup / tc).sinh(),
        })
    }

    /// The parameters.
    pub fn config(&self) -> &LipmConfig {
        &self.cfg
    }

    /// T_c = √(z_c / g), s.
    pub fn tc(&self) -> f64 {
        self.tc
    }

    /// C and S of eq 12: cosh and sinh of T_sup / T_c.
    pub fn cs(&self) -> (f64, f64) {
        (self.c, self.s)
    }

    /// One axis after `t` seconds about a foot at `p` from position `x` and velocity `v`
    /// (eqs 16-17; with p = 0, eqs 7-8): position, velocity, acceleration.
    pub fn advance(&self, x: f64, v: f64, p: f64, t: f64) -> [f64; 3] {
        self.advance_by(x, v, p, ((t / self.tc).cosh(), (t / self.tc).sinh()))
    }

    /// [`Pendulum::advance`] with cosh and sinh of t / T_c given (both axes share them).
    #[inline]
    fn advance_by(&self, x: f64, v: f64, p: f64, (ch, sh): (f64, f64)) -> [f64; 3] {
        let d = x - p;
        let pos = d * ch + self.tc * v * sh + p;
        let vel = if self.cfg.faithful.eq_7 {
            d / self.tc * sh + v / self.tc * ch
        } else {
            d / self.tc * sh + v * ch
        };
        [pos, vel, (pos - p) / (self.tc * self.tc)]
    }

    /// The terminal state of one support period about the foot `p` (eqs 18-19).
    pub fn step_end(&self, s: State, p: [f64; 2]) -> State {
        let a = self.advance(s.x[0], s.v[0], p[0], self.cfg.t_sup);
        let b = self.advance(s.x[1], s.v[1], p[1], self.cfg.t_sup);
        State {
            x: [a[0], b[0]],
            v: [a[1], b[1]],
        }
    }

    /// The walk primitive of step `n` from the next step's parameters `next` (eqs 13-14,
    /// 25-26): its terminal position (x̄, ȳ) relative to the foot and velocity (v̄_x, v̄_y).
    pub fn primitive(&self, n: usize, next: WalkParam) -> ([f64; 2], [f64; 2]) {
        let sign = if n.is_multiple_of(2) { 1.0 } else { -1.0 };
        let bar = [next.sx / 2.0, sign * next.sy / 2.0];
        let k = [
            (self.c + 1.0) / (self.tc * self.s),
            (self.c - 1.0) / (self.tc * self.s),
        ];
        (
            rot(next.theta, bar),
            rot(next.theta, [k[0] * bar[0], k[1] * bar[1]]),
        )
    }

    /// The modified foot placement of one axis (eq 24): the foot that brings the state
    /// (`xi`, `vi`) after T_sup nearest the target (`xd`, `vd`) in the weights a, b.
    pub fn foot_placement(&self, xi: f64, vi: f64, xd: f64, vd: f64) -> f64 {
        let (a, b, c, s, tc) = (self.cfg.a, self.cfg.b, self.c, self.s, self.tc);
        let d = a * (c - 1.0).powi(2) + b * (s / tc).powi(2);
        -(a * (c - 1.0) / d) * (xd - c * xi - tc * s * vi)
            - (b * s / (tc * d)) * (vd - (s / tc) * xi - c * vi)
    }
}

/// Footsteps from walk parameters (eq 96; eq 95 when every heading is 0): p⁽ⁿ⁾ = p⁽ⁿ⁻¹⁾ +
/// R(s_θ⁽ⁿ⁾)(s_x⁽ⁿ⁾, −(−1)ⁿ s_y⁽ⁿ⁾), for n = 1 to the parameters' count, from p⁽⁰⁾.
pub fn footsteps(params: &[WalkParam], p0: [f64; 2]) -> Vec<[f64; 2]> {
    let mut p = p0;
    let mut out = Vec::with_capacity(params.len());
    for (i, s) in params.iter().enumerate() {
        let n = i + 1;
        let sign = if n.is_multiple_of(2) { 1.0 } else { -1.0 };
        let d = rot(s.theta, [s.sx, -sign * s.sy]);
        p = [p[0] + d[0], p[1] + d[1]];
        out.push(p);
    }
    out
}

/// Archie's footsteps from the COM's ground track (eqs 97-98): c⁽ⁿ⁾ = c⁽ⁿ⁻¹⁾ + s_x (cos s_θ,
/// sin s_θ) and p⁽ⁿ⁾ = c⁽ⁿ⁾ + (−1)ⁿ s_y (sin s_θ, −cos s_θ): s_x is the COM's advance and s_y
/// the COM-to-foot offset. Returns (c⁽ⁿ⁾, p⁽ⁿ⁾) for n = 1 on, from c⁽⁰⁾.
pub fn footsteps_from_com(params: &[WalkParam], c0: [f64; 2]) -> Vec<([f64; 2], [f64; 2])> {
    let mut c = c0;
    params
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let n = i + 1;
            let sign = if n.is_multiple_of(2) { 1.0 } else { -1.0 };
            let (sn, cs) = s.theta.sin_cos();
            c = [c[0] + cs * s.sx, c[1] + sn * s.sx];
            (c, [c[0] + sign * s.sy * sn, c[1] - sign * s.sy * cs])
        })
        .collect()
}

/// One support period of a walk: the foot it stands on and the COM's states.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Support {
    /// Step number n (0: the first support, on p⁽⁰⁾).
    pub n: usize,
    /// The nominal footstep p⁽ⁿ⁾ (eq 95/96).
    pub nominal: [f64; 2],
    /// The foot placed (p*, eq 24; p⁽⁰⁾ for n = 0). It is the ZMP all through the period.
    pub foot: [f64; 2],
    /// The COM's state at the period's start.
    pub start: State,
    /// The COM's state at its end.
    pub end: State,
}

impl Support {
    /// The COM's position, velocity and acceleration at `t` seconds into the period.
    pub fn at(&self, p: &Pendulum, t: f64) -> [[f64; 2]; 3] {
        let cs = ((t / p.tc).cosh(), (t / p.tc).sinh());
        let a = p.advance_by(self.start.x[0], self.start.v[0], self.foot[0], cs);
        let b = p.advance_by(self.start.x[1], self.start.v[1], self.foot[1], cs);
        [[a[0], b[0]], [a[1], b[1]], [a[2], b[2]]]
    }
}

/// The walk of Kajita's algorithm as the thesis follows it: from the initial COM state and
/// p* = p⁽⁰⁾, integrate one period, take the next nominal footstep, the walk primitive of the
/// parameters after it, its target state, and the modified foot placement; repeat for every
/// parameter (the parameter after the last is a stop: all zero, the last heading kept).
pub fn walk(p: &Pendulum, params: &[WalkParam], p0: [f64; 2], initial: State) -> Vec<Support> {
    let nominal = footsteps(params, p0);
    let mut out = Vec::with_capacity(params.len() + 1);
    let mut state = initial;
    let mut foot = p0;
    for n in 0..=params.len() {
        let end = p.step_end(state, foot);
        out.push(Support {
            n,
            nominal: if n == 0 { p0 } else { nominal[n - 1] },
            foot,
            start: state,
            end,
        });
        if n == params.len() {
            break;
        }
        state = end;
        // Step n + 1 stands on the placement computed for the nominal p⁽ⁿ⁺¹⁾, with the
        // primitive of the parameters after it.
        let m = n + 1;
        let next = params.get(m).copied().unwrap_or(WalkParam {
            theta: params[n].theta,
            ..Default::default()
        });
        let (bar, vbar) = p.primitive(m, next);
        let target = [nominal[n][0] + bar[0], nominal[n][1] + bar[1]];
        foot = [
            p.foot_placement(state.x[0], state.v[0], target[0], vbar[0]),
            p.foot_placement(state.x[1], state.v[1], target[1], vbar[1]),
        ];
    }
    out
}

/// Kajita's algorithm over footsteps rather than walk parameters: `nominal[0]` is the first
/// support foot p⁽⁰⁾, `nominal[n]` the planned footstep p⁽ⁿ⁾ with its heading. The walk
/// primitive of step n ends halfway to the next footstep, in the heading of that footstep:
/// (x̄, ȳ) = R(θ)ᵀ (p⁽ⁿ⁺¹⁾ − p⁽ⁿ⁾) / 2, which is eqs 13 and 25 for footsteps made by eqs
/// 95-96; after the last footstep the primitive is a stop (0, 0).
///
/// The first support's foot stands where it is, but its ZMP point is placed by eq 24 too,
/// from the initial state towards its own primitive: over a support of T_sup ≫ T_c the
/// pendulum multiplies the initial state's distance from the walk's orbit by about e^(T_sup/T_c)
/// (150 for Archie), so a state a millimetre off at the start would move the next footstep
/// by decimetres; moved by about that millimetre, the ZMP starts the walk on its orbit. The
/// pattern's margin check keeps it inside the sole.
pub fn walk_footsteps(p: &Pendulum, nominal: &[([f64; 2], f64)], initial: State) -> Vec<Support> {
    let (c, s) = p.cs();
    let tc = p.tc();
    let k = [(c + 1.0) / (tc * s), (c - 1.0) / (tc * s)];
    // The foot of step n placed from the state at its support's start: the nominal
    // footstep's primitive, from the one after.
    let place = |n: usize, state: State| {
        let (pn, _) = nominal[n];
        let (bar, vbar) = match nominal.get(n + 1) {
            Some(&(next, theta)) => {
                let d = [(next[0] - pn[0]) / 2.0, (next[1] - pn[1]) / 2.0];
                let local = rot(-theta, d);
                (d, rot(theta, [k[0] * local[0], k[1] * local[1]]))
            }
            None => ([0.0, 0.0], [0.0, 0.0]),
        };
        let target = [pn[0] + bar[0], pn[1] + bar[1]];
        [
            p.foot_placement(state.x[0], state.v[0], target[0], vbar[0]),
            p.foot_placement(state.x[1], state.v[1], target[1], vbar[1]),
        ]
    };
    let mut out = Vec::with_capacity(nominal.len());
    let mut state = initial;
    for (n, &(at, _)) in nominal.iter().enumerate() {
        let foot = place(n, state);
        let end = p.step_end(state, foot);
        out.push(Support {
            n,
            nominal: at,
            foot,
            start: state,
            end,
        });
        state = end;
    }
    out
}
