//! The KAIST footstep planner's cost model (seed 004): the energy of a step (Eq. 7-10), the
//! coefficient sets of the thesis's simulation and real robot, the action set, and the
//! heuristics: the thesis's (Eq. 14) and an admissible energy bound (improved mode).
//!
//! Units (decision D1 of the notes): lengths in metres, angles in radians, energies as
//! `m·g × polynomial`, so one forward step of 0.3 m costs `mg · 4.4278` with a 0.2 m width.
//! A step's `l` is its forward advance, `w` the lateral foot separation, `θ` its yaw (D2).

use crate::geom::wrap;

/// Coefficients and limits of one robot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CostParams {
    /// E_length = mg(A·l⁴ + B·l + C).
    pub a: f64,
    /// See `a`.
    pub b: f64,
    /// See `a`; also the sidestep penalty E_side = mg·10·C.
    pub c: f64,
    /// E_width = mg·D·w².
    pub d: f64,
    /// Listed in Table 4.1 and used by no equation (kept for the record).
    pub e: f64,
    /// E_angle = mg·F·θ².
    pub f: f64,
    /// Robot mass, kg.
    pub mass: f64,
    /// Longest step, m.
    pub l_max: f64,
    /// The thesis's "optimal step length", m (not the cost's minimiser: see `cot_minimiser`).
    pub l_opt: f64,
    /// Widest step, m.
    pub w_max: f64,
    /// Narrowest step, m.
    pub w_min: f64,
    /// Largest yaw per step, rad.
    pub yaw_max: f64,
    /// Nominal width, m.
    pub w_nom: f64,
}

/// Standard gravity, m/s².
pub const G: f64 = 9.81;

impl CostParams {
    /// `kaist_sim`: Table 4.1 coefficients, DRC-HUBO+ (80 kg), Table 4.2 limits.
    pub fn kaist_sim() -> CostParams {
        CostParams {
            a: 44.0,
            b: 0.2112,
            c: 4.0,
            d: 0.2,
            e: 0.23,
            f: 0.4,
            mass: 80.0,
            l_max: 0.40,
            l_opt: 0.30,
            w_max: 0.35,
            w_min: 0.18,
            yaw_max: 15f64.to_radians(),
            w_nom: 0.20,
        }
    }

    /// `kaist_real`: the same coefficients, Gazelle (37 kg), Table 5.1 limits.
    pub fn kaist_real() -> CostParams {
        CostParams {
            mass: 37.0,
            l_max: 0.30,
            l_opt: 0.20,
            ..CostParams::kaist_sim()
        }
    }

    /// m·g, N.
    pub fn mg(&self) -> f64 {
        self.mass * G
    }

    /// A step's energy over m·g (Eq. 10): length, width, angle and sidestep terms.
    pub fn energy_mg(&self, l: f64, w: f64, theta: f64, sidestep: bool) -> f64 {
        let length = self.a * l.powi(4) + self.b * l + self.c;
        let width = self.d * w * w;
        let angle = self.f * theta * theta;
        let side = if sidestep { 10.0 * self.c } else { 0.0 };
        length + width + angle + side
    }

    /// The step length that minimises the cost of transport A·l³ + B + C/l: unconstrained, and
    /// within `l_max`.
    pub fn cot_minimiser(&self) -> (f64, f64) {
        let free = (self.c / (3.0 * self.a)).powf(0.25);
        (free, free.min(self.l_max))
    }
}

/// One action, in the stance foot's frame for a left stance (the right foot swings); mirrored
/// (y and yaw negated) for a right stance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Action {
    /// Forward advance of the swing foot past the stance foot, m.
    pub dx: f64,
    /// Lateral position of the swing foot, m (negative: to the right of a left stance).
    pub dy: f64,
    /// Yaw change, rad.
    pub dtheta: f64,
    /// Which subset it belongs to.
    pub subset: Subset,
}

/// The subsets of the action set (§B.1.3's proposal; the thesis's figures are lost).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Subset {
    /// Straight ahead.
    Forward,
    /// Forward while turning left.
    ForwardLeft,
    /// Forward while turning right.
    ForwardRight,
    /// Turning left on the spot.
    TurnLeft,
    /// Turning right on the spot.
    TurnRight,
    /// A step sideways, outwards.
    SideOut,
}

impl Action {
    /// True for a sidestep (decision D8): no advance and wider than nominal by over 2 cm.
    pub fn is_sidestep(&self, p: &CostParams) -> bool {
        self.dx == 0.0 && self.dy.abs() > p.w_nom + 0.02
    }

    /// Its energy over m·g.
    pub fn energy_mg(&self, p: &CostParams) -> f64 {
        p.energy_mg(
            self.dx,
            self.dy.abs(),
            self.dtheta.abs(),
            self.is_sidestep(p),
        )
    }
}

/// The default action set (§B.1.3's proposal table) for `p`, for a left stance.
pub fn actions(p: &CostParams) -> Vec<Action> {
    let mut out = Vec::new();
    let steps = |max: f64| {
        let n = (max / 0.05 + 1e-9).floor() as usize;
        (1..=n).map(|k| k as f64 * 0.05).collect::<Vec<f64>>()
    };
    for dx in steps(p.l_max) {
        out.push(Action {
            dx,
            dy: -p.w_nom,
            dtheta: 0.0,
            subset: Subset::Forward,
        });
    }
    for deg in [5.0f64, 10.0, 15.0] {
        let t = deg.to_radians().min(p.yaw_max);
        for dx in steps(p.l_max - 0.10) {
            // A right swing turns the body right more easily (outwards): both kept.
            out.push(Action {
                dx,
                dy: -p.w_nom,
                dtheta: t,
                subset: Subset::ForwardLeft,
            });
            out.push(Action {
                dx,
                dy: -p.w_nom,
                dtheta: -t,
                subset: Subset::ForwardRight,
            });
        }
        out.push(Action {
            dx: 0.0,
            dy: -p.w_nom,
            dtheta: t,
            subset: Subset::TurnLeft,
        });
        out.push(Action {
            dx: 0.0,
            dy: -p.w_nom,
            dtheta: -t,
            subset: Subset::TurnRight,
        });
    }
    let mut w = p.w_nom;
    while w + 0.05 <= p.w_max + 1e-9 {
        w += 0.05;
        out.push(Action {
            dx: 0.0,
            dy: -w,
            dtheta: 0.0,
            subset: Subset::SideOut,
        });
    }
    out
}

/// α (decision D4): the least energy per metre of progress of the robot's centre over the
/// action set, in units of m·g. A step moves the centre by half the foot's displacement
/// relative to the previous swing position (the feet alternate); for a forward step of length l
/// the centre advances by l.
pub fn alpha(p: &CostParams, acts: &[Action]) -> f64 {
    acts.iter()
        .filter(|a| a.dx > 0.0)
        .map(|a| a.energy_mg(p) / a.dx)
        .fold(f64::INFINITY, f64::min)
}

/// The thesis's heuristic (Eq. 14) over m·g: α·d + F·Δθ²/N, with N = max(1, ⌈|Δθ|/θ_max⌉)
/// (D5) and Δθ the wrapped difference between the heading and the bearing to the goal (D6).
pub fn h_thesis(p: &CostParams, alpha: f64, d: f64, heading: f64, bearing: f64) -> f64 {
    let dt = wrap(bearing - heading).abs();
    let n = (dt / p.yaw_max).ceil().max(1.0);
    alpha * d + p.f * dt * dt / n
}

/// The improved heuristic (§B.3.2) over m·g: with d' = max(0, d - tolerance) and at least
/// M_min = max(⌈d'/l_max⌉, ⌈|Δθ|/θ_max⌉) steps, the least of M·C + F·Δθ²/M over M ≥ M_min.
/// It keeps only the terms every step pays whatever it does (the constant C, and the turn
/// spread evenly), so it is a lower bound of any plan's cost: admissible.
pub fn h_improved(p: &CostParams, d: f64, tolerance: f64, heading: f64, bearing: f64) -> f64 {
    let dp = (d - tolerance).max(0.0);
    let dt = if dp > 0.0 {
        wrap(bearing - heading).abs()
    } else {
        0.0
    };
    let m_min = ((dp / p.l_max).ceil()).max((dt / p.yaw_max).ceil());
    if m_min <= 0.0 {
        return 0.0;
    }
    // M·C + F·Δθ²/M is convex in M, least at sqrt(F/C)·Δθ: never above M_min here.
    let m_best = ((p.f / p.c).sqrt() * dt).max(m_min);
    let at = |m: f64| m * p.c + p.f * dt * dt / m;
    at(m_min)
        .min(at(m_best.ceil()))
        .min(at(m_best.floor().max(m_min)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn golden_costs_r_c1() {
        let p = CostParams::kaist_sim();
        let close = |a: f64, b: f64| (a - b).abs() < 1e-4;
        assert!(
            close(p.energy_mg(0.30, 0.20, 0.0, false), 4.4278),
            "{}",
            p.energy_mg(0.30, 0.20, 0.0, false)
        );
        assert!(close(p.energy_mg(0.40, 0.18, 0.0, false), 5.2174));
        assert!(close(
            p.energy_mg(0.0, 0.20, 15f64.to_radians(), false),
            4.0354
        ));
        assert!(close(p.energy_mg(0.0, 0.35, 0.0, true), 44.0245));
    }

    #[test]
    fn cot_minimiser_r_c2() {
        let (free, within) = CostParams::kaist_sim().cot_minimiser();
        assert!((free - 0.417).abs() < 1e-3 && (within - 0.40).abs() < 1e-12);
        // Not the thesis's "optimal step length": that stays its own parameter.
        assert_ne!(within, CostParams::kaist_sim().l_opt);
        let (_, real) = CostParams::kaist_real().cot_minimiser();
        assert!((real - 0.30).abs() < 1e-12);
    }

    #[test]
    fn action_set_and_alpha() {
        let p = CostParams::kaist_sim();
        let acts = actions(&p);
        assert_eq!(
            acts.iter().filter(|a| a.subset == Subset::Forward).count(),
            8
        );
        assert!(acts.iter().all(|a| a.dx >= 0.0), "no backward steps");
        assert!(acts
            .iter()
            .filter(|a| a.subset == Subset::SideOut)
            .all(|a| a.is_sidestep(&p)));
        // The least energy per metre is the longest forward step: 5.2238 / 0.40.
        let al = alpha(&p, &acts);
        assert!(
            (al - p.energy_mg(0.40, 0.20, 0.0, false) / 0.40).abs() < 1e-12,
            "{al}"
        );
    }

    #[test]
    fn heuristics() {
        let p = CostParams::kaist_sim();
        let al = alpha(&p, &actions(&p));
        // Straight at the goal: the thesis's is α·d; the improved one counts the steps' C.
        assert!((h_thesis(&p, al, 4.0, 0.0, 0.0) - al * 4.0).abs() < 1e-12);
        assert!((h_improved(&p, 4.0, 0.1, 0.0, 0.0) - 10.0 * p.c).abs() < 1e-12);
        // Inside the tolerance: nothing left to pay.
        assert_eq!(h_improved(&p, 0.05, 0.1, 0.0, 3.0), 0.0);
        // A goal behind adds the turn, spread over at least 12 steps of 15 degrees.
        let h = h_improved(&p, 1.0, 0.1, 0.0, std::f64::consts::PI);
        assert!(
            (h - (12.0 * p.c + p.f * std::f64::consts::PI.powi(2) / 12.0)).abs() < 1e-9,
            "{h}"
        );
    }
}
