//! The KAIST footstep planner's cost model (seed 004): the energy of a step (Eq. 7-10), the
//! coefficient sets of the thesis's simulation and real robot, the action set, and the
//! heuristics: the thesis's (Eq. 14) and an admissible energy bound (improved mode).
//!
//! Units (decision D1 of the notes): lengths in metres, angles in radians, energies as
//! `m·g × polynomial`, so one forward step of 0.3 m costs `mg · 4.4278` with a 0.2 m width.
//! A step's `l` is its forward advance, `w` the lateral foot separation, `θ` its yaw (D2).

pub mod search;

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

    /// A set by name: `kaist_sim` or `kaist_real`.
    pub fn named(name: &str) -> Option<CostParams> {
        match name {
            "kaist_sim" => Some(CostParams::kaist_sim()),
            "kaist_real" => Some(CostParams::kaist_real()),
            _ => None,
        }
    }

    /// The set a scene asks for (`kaist_sim` when it names none).
    pub fn of_scene(scene: &crate::scene::Scene) -> Result<CostParams, String> {
        let name = scene.params.as_deref().unwrap_or("kaist_sim");
        CostParams::named(name).ok_or_else(|| {
            format!(
                "scene {}: unknown parameter set {name:?} (kaist_sim or kaist_real)",
                scene.name
            )
        })
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
        for dx in steps(p.l_max - TURN_SHORTENING) {
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

/// How much shorter than `l_max` a step that turns is (§B.1.3's proposal: turning steps reach
/// 0.10 m less far), m.
pub const TURN_SHORTENING: f64 = 0.10;

/// The improved heuristic over m·g: a lower bound of the energy of every step sequence that
/// brings the robot's centre to within `tolerance` of the goal. `d` and `bearing` are the
/// goal's distance and direction from the stance foot, `yaw` the stance foot's heading,
/// `centre_d` the goal's distance from the robot's centre.
///
/// Why it is a lower bound (the notes' §B.3.2, made exact for this action model). Number the
/// feet S₀ (the stance) and S₁ … S_M (the steps) and let u_k = S_k − S_{k−1}. The centre ends
/// at c_M = S₀ + u₁ + … + u_{M−1} + u_M/2, which must lie within the tolerance of the goal, so
/// along the bearing β it must have moved d − tolerance. Each u_k is the step's advance dx_k
/// along the stance's heading ψ_{k−1}, plus ±w sideways; the sideways parts alternate, so
/// along β they add at most λ = w_max/2 plus a drift of w_nom·θ_max per turning step. Along β,
/// step k advances dx_k·cos(ψ_{k−1} − β) ≤ l_max·cos δ_k, where δ_k = max(0, |ψ₀ − β| −
/// (k−1)·θ_max) is the least heading error the steps can have reached (no step turns more than
/// θ_max, and going backwards never helps; a turning step reaches `TURN_SHORTENING` less far
/// but drifts). M_min is the least M whose steps can cover the distance so (the last one
/// counting half). Every step pays C; the steps must turn at least |ψ₀ − β| − 90° to make any
/// progress, so by convexity Σ F·θ² ≥ F·Θ²/M; and Σ A·dx⁴ ≥ A·L⁴/M³, with L the distance less
/// the largest drift. A sidestep pays 10·C extra for at most w_max − w_nom sideways, more
/// than that is worth here. The brute-force test (`tests/kaist_admissibility.rs`, the notes'
/// R-H3) checks the bound against exact costs.
pub fn h_improved(
    p: &CostParams,
    d: f64,
    bearing: f64,
    yaw: f64,
    centre_d: f64,
    tolerance: f64,
) -> f64 {
    if centre_d < tolerance {
        return 0.0;
    }
    let need = d - tolerance - p.w_max / 2.0;
    let delta = wrap(yaw - bearing).abs();
    let drift = p.w_nom * p.yaw_max;
    let l_turn = p.l_max - TURN_SHORTENING;
    let mut reach = 0.0;
    let mut m = 0u32;
    while m < 10_000 {
        m += 1;
        let dk = (delta - f64::from(m - 1) * p.yaw_max).max(0.0);
        let step = if dk > 0.0 {
            let c = dk.cos().max(0.0);
            (p.l_max * c).max(l_turn * c + drift)
        } else {
            p.l_max
        };
        if reach + step / 2.0 >= need {
            break;
        }
        reach += step;
    }
    let m_min = f64::from(m);
    let turn = if need > 0.0 {
        (delta - std::f64::consts::FRAC_PI_2).max(0.0)
    } else {
        0.0
    };
    // Past M_min the sum grows (C outweighs what another step saves), but a few more are
    // looked at anyway.
    (0..6)
        .map(|k| {
            let m = m_min + k as f64;
            let l = (need - m * drift).max(0.0);
            m * p.c + p.f * turn * turn / m + p.b * l + p.a * l.powi(4) / m.powi(3)
        })
        .fold(f64::INFINITY, f64::min)
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
        // Straight at the goal: the thesis's is α·d.
        assert!((h_thesis(&p, al, 4.0, 0.0, 0.0) - al * 4.0).abs() < 1e-12);
        // The bound: 4 m ahead of the stance foot takes at least 10 steps.
        let h = h_improved(&p, 4.0, 0.0, 0.0, 4.0, 0.1);
        assert!(h > 10.0 * p.c && h < al * 4.0, "{h}");
        // At the goal: nothing left to pay; near it, one step.
        assert_eq!(h_improved(&p, 0.15, 3.0, 0.0, 0.05, 0.1), 0.0);
        assert_eq!(h_improved(&p, 0.15, 3.0, 0.0, 0.15, 0.1), p.c);
        // A goal behind needs the turn: at least 7 steps before any progress.
        let h = h_improved(&p, 1.0, std::f64::consts::PI, 0.0, 1.0, 0.1);
        assert!(h >= 7.0 * p.c, "{h}");
        // Farther is dearer, and a turn adds.
        let ahead = |d: f64, b: f64| h_improved(&p, d, b, 0.0, d, 0.1);
        assert!(ahead(3.0, 0.0) > ahead(2.0, 0.0));
        assert!(ahead(3.0, 1.5) > ahead(3.0, 0.0));
    }
}
