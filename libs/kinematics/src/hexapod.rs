//! The hexapod (a PhantomX Mark II: 18 AX-12A, three a leg): one leg's kinematics after its
//! thesis (eqs 3.2-3.10), the servo mapping of its Table 3.1 and the limits of its Table 3.2.
//!
//! Frames: the body frame has x forward, y left, z up, its origin at the body's centre. A leg
//! frame has its origin on the coxa axis at the leg's mount, x along the leg's outward
//! direction, z up. In a leg frame the leg's joints are, in the kinematic model:
//!
//! - α, the coxa's yaw, counter-clockwise seen from above (eq 3.2, as `atan2`);
//! - β, the femur's elevation above the horizontal;
//! - γ, the interior angle between femur and tibia at the knee (eqs 3.9-3.10).
//!
//! The inverse kinematics (eqs 3.3-3.8): d_p = √(x² + y²) − l_C, d_l = √(d_p² + z²), the foot's
//! angle below the horizontal δ = −atan2(z, d_p), ε by the law of cosines at the femur joint,
//! and β = ε − δ. The thesis prints β = δ + ε with z pointing down, where δ changes sign; it
//! prints eq 3.5 as δ = −atan(z / d_l), which is not the angle (its worked example: 33.78°
//! printed against 41.99°), and runs as printed only behind [`Faithful::eq_3_5`].
//!
//! Servo angles (degrees about the servo's centre) are s − 150 = o + a with Table 3.1's
//! per-leg signs and offsets ϕ, ψ, ω (in its Fig. 3.4 only, so configuration); the π in the
//! tibia's ω − π is 180°, which turns the interior knee angle into a deflection. The raw goal
//! is round(s · 1023 / 300). Table 3.1's α is positive away from the middle leg, so each leg
//! says which way that is. Mirrored legs give raw values mirrored about 511.5 (e.g. 410 and
//! 613 for a femur at ±29.8°), not equal ones.

use serde::Deserialize;

use crate::KinError;

/// A leg's link lengths, metres.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Links {
    /// Coxa: the coxa axis to the femur axis.
    pub coxa: f64,
    /// Femur: the femur axis to the knee axis.
    pub femur: f64,
    /// Tibia: the knee axis to the foot tip.
    pub tibia: f64,
}

/// A leg's joints in the kinematic model, radians (see the module's frames).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LegAngles {
    /// Coxa yaw, counter-clockwise seen from above, from the leg's outward direction.
    pub alpha: f64,
    /// Femur elevation above the horizontal.
    pub beta: f64,
    /// Interior knee angle between femur and tibia.
    pub gamma: f64,
}

/// The thesis's equations run as printed, each behind its own flag (all off: the corrected
/// forms).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Faithful {
    /// Eq 3.5 as printed, δ = −atan(z / d_l), instead of −atan2(z, d_p).
    pub eq_3_5: bool,
}

fn acos_checked(c: f64, what: impl FnOnce() -> String) -> Result<f64, KinError> {
    if (-1.0..=1.0).contains(&c) {
        Ok(c.acos())
    } else {
        Err(KinError::Unreachable(what()))
    }
}

impl Links {
    /// The joints that put the foot at `foot` (leg frame, metres), knee up. An error, never
    /// NaN, for a foot on the coxa axis or out of the leg's reach.
    pub fn ik(&self, foot: [f64; 3], faithful: Faithful) -> Result<LegAngles, KinError> {
        let [x, y, z] = foot;
        if !(x.is_finite() && y.is_finite() && z.is_finite()) {
            return Err(KinError::Unreachable(format!(
                "foot {foot:?} is not finite"
            )));
        }
        let h = x.hypot(y);
        if h < 1e-9 {
            return Err(KinError::Singular(
                "the foot is on the coxa axis: any coxa angle puts it there".into(),
            ));
        }
        let alpha = y.atan2(x);
        let dp = h - self.coxa;
        let dl = dp.hypot(z);
        let (lf, lt) = (self.femur, self.tibia);
        let reach = || {
            format!(
                "the foot is {dl:.4} m from the femur joint; the leg reaches from {:.4} to {:.4} m",
                (lf - lt).abs(),
                lf + lt
            )
        };
        if dl < 1e-9 {
            return Err(KinError::Singular("the foot is on the femur axis".into()));
        }
        let delta = if faithful.eq_3_5 {
            -(z / dl).atan()
        } else {
            -z.atan2(dp)
        };
        let eps = acos_checked((dl * dl + lf * lf - lt * lt) / (2.0 * dl * lf), reach)?;
        let gamma = acos_checked((lf * lf + lt * lt - dl * dl) / (2.0 * lf * lt), reach)?;
        Ok(LegAngles {
            alpha,
            beta: eps - delta,
            gamma,
        })
    }

    /// Where the foot is (leg frame, metres) for the joints `a`.
    pub fn fk(&self, a: &LegAngles) -> [f64; 3] {
        // The tibia's elevation: the femur's, less the knee's deflection π − γ.
        let tau = a.beta - (std::f64::consts::PI - a.gamma);
        let d = self.femur * a.beta.cos() + self.tibia * tau.cos();
        let z = self.femur * a.beta.sin() + self.tibia * tau.sin();
        let h = self.coxa + d;
        [h * a.alpha.cos(), h * a.alpha.sin(), z]
    }
}

/// One leg of the hexapod, as its robot file gives it.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LegConfig {
    /// Its name, e.g. "lf".
    pub name: String,
    /// Its number in the thesis's Tables 3.1 and 3.2 (1 to 6).
    pub number: u8,
    /// The coxa axis's place on the body, metres, body frame.
    pub mount: [f64; 3],
    /// The leg's outward direction, degrees counter-clockwise from forward.
    pub yaw_deg: f64,
    /// Table 3.1's signs of α, β and γ in the servo angles a (±1 each).
    pub signs: [i8; 3],
    /// Table 3.1's offsets o, as multiples of ϕ, ψ and (ω − π) (−1, 0 or 1 each).
    pub offset_signs: [i8; 3],
    /// Table 3.1's α, positive away from the middle leg: 1 when that is counter-clockwise
    /// for this leg, −1 when clockwise (a middle leg: its forward).
    pub alpha_ccw: i8,
    /// Table 3.2: [min, max] of each servo angle o + a (coxa, femur, tibia), degrees.
    pub limits_deg: [[f64; 2]; 3],
    /// The servos' ids: coxa, femur, tibia.
    pub ids: [u8; 3],
}

/// The servo offsets of the thesis's Fig. 3.4 (not printed in its text), degrees.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Offsets {
    /// ϕ, the coxa's.
    pub phi_deg: f64,
    /// ψ, the femur's.
    pub psi_deg: f64,
    /// ω, the tibia's.
    pub omega_deg: f64,
}

/// A robot file of the hexapod (`config/robots/hexapod.toml`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HexapodConfig {
    /// The legs' link lengths (all legs alike).
    pub links: Links,
    /// The servos' mounting offsets.
    #[serde(default)]
    pub offsets: Offsets,
    /// Published equations run as printed.
    #[serde(default)]
    pub faithful: Faithful,
    /// The six legs.
    pub leg: Vec<LegConfig>,
}

/// A solved leg: its joints, its servo angles and raw goals.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LegSolution {
    /// The kinematic model's joints.
    pub angles: LegAngles,
    /// Servo angles about their centres (o + a), degrees: coxa, femur, tibia.
    pub servo_deg: [f64; 3],
    /// Raw AX-12A goal positions (0 to 1023 over 0° to 300°).
    pub raw: [u16; 3],
}

const JOINTS: [&str; 3] = ["coxa", "femur", "tibia"];

/// The hexapod's kinematics: its legs, checked.
#[derive(Debug, Clone, PartialEq)]
pub struct Hexapod {
    cfg: HexapodConfig,
}

impl Hexapod {
    /// Reads and checks a robot file.
    pub fn load(path: &std::path::Path) -> Result<Hexapod, KinError> {
        Hexapod::new(crate::read_toml(path)?)
    }

    /// Parses and checks a robot file's text.
    pub fn from_toml(text: &str) -> Result<Hexapod, KinError> {
        Hexapod::new(toml::from_str(text).map_err(|e| KinError::Config(e.to_string()))?)
    }

    /// Checks a configuration: six legs numbered 1 to 6 once each, positive finite links,
    /// signs of ±1 and offsets of −1, 0 or 1, limits within the servo's ±150°.
    pub fn new(cfg: HexapodConfig) -> Result<Hexapod, KinError> {
        let bad = |m: String| Err(KinError::Config(m));
        let l = cfg.links;
        if ![l.coxa, l.femur, l.tibia]
            .iter()
            .all(|v| v.is_finite() && *v > 0.0)
        {
            return bad(format!("link lengths must be positive: {l:?}"));
        }
        let mut numbers: Vec<u8> = cfg.leg.iter().map(|g| g.number).collect();
        numbers.sort_unstable();
        if numbers != [1, 2, 3, 4, 5, 6] {
            return bad(format!(
                "six legs numbered 1 to 6 expected, found {numbers:?}"
            ));
        }
        for g in &cfg.leg {
            let signs_ok = g.signs.iter().all(|s| s.abs() == 1) && g.alpha_ccw.abs() == 1;
            if !signs_ok || g.offset_signs.iter().any(|s| s.abs() > 1) {
                return bad(format!(
                    "leg {}: signs must be ±1 and offset signs −1, 0 or 1",
                    g.name
                ));
            }
            for (j, [lo, hi]) in g.limits_deg.iter().enumerate() {
                if !(-150.0 <= *lo && lo < hi && *hi <= 150.0) {
                    return bad(format!(
                        "leg {} {}: limits [{lo}, {hi}] must be ordered within ±150°",
                        g.name, JOINTS[j]
                    ));
                }
            }
            if !(g.mount.iter().all(|v| v.is_finite()) && g.yaw_deg.is_finite()) {
                return bad(format!("leg {}: mount and yaw must be finite", g.name));
            }
        }
        Ok(Hexapod { cfg })
    }

    /// The configuration.
    pub fn config(&self) -> &HexapodConfig {
        &self.cfg
    }

    /// The leg numbered `number` (1 to 6).
    pub fn leg(&self, number: u8) -> Option<&LegConfig> {
        self.cfg.leg.iter().find(|g| g.number == number)
    }

    fn leg_or_err(&self, number: u8) -> Result<&LegConfig, KinError> {
        self.leg(number)
            .ok_or_else(|| KinError::Config(format!("no leg {number}")))
    }

    /// A point of the body frame in the leg frame of `leg`.
    pub fn to_leg(leg: &LegConfig, p: [f64; 3]) -> [f64; 3] {
        let (s, c) = leg.yaw_deg.to_radians().sin_cos();
        let d = [
            p[0] - leg.mount[0],
            p[1] - leg.mount[1],
            p[2] - leg.mount[2],
        ];
        [c * d[0] + s * d[1], -s * d[0] + c * d[1], d[2]]
    }

    /// A point of the leg frame of `leg` in the body frame.
    pub fn to_body(leg: &LegConfig, p: [f64; 3]) -> [f64; 3] {
        let (s, c) = leg.yaw_deg.to_radians().sin_cos();
        [
            leg.mount[0] + c * p[0] - s * p[1],
            leg.mount[1] + s * p[0] + c * p[1],
            leg.mount[2] + p[2],
        ]
    }

    /// The servo angles o + a (degrees, coxa, femur, tibia) of joints `a` on `leg`.
    pub fn servo_deg(&self, leg: &LegConfig, a: &LegAngles) -> [f64; 3] {
        let o = self.cfg.offsets;
        let alpha_table = leg.alpha_ccw as f64 * a.alpha.to_degrees();
        let model = [alpha_table, a.beta.to_degrees(), a.gamma.to_degrees()];
        let offsets = [o.phi_deg, o.psi_deg, o.omega_deg - 180.0];
        std::array::from_fn(|j| {
            leg.offset_signs[j] as f64 * offsets[j] + leg.signs[j] as f64 * model[j]
        })
    }

    /// The joints (kinematic model) that servo angles `deg` of `leg` stand for: the inverse
    /// of [`Hexapod::servo_deg`], for forward kinematics from servo readings.
    pub fn angles_from_servo(&self, leg: &LegConfig, deg: [f64; 3]) -> LegAngles {
        let o = self.cfg.offsets;
        let offsets = [o.phi_deg, o.psi_deg, o.omega_deg - 180.0];
        let model: [f64; 3] = std::array::from_fn(|j| {
            (deg[j] - leg.offset_signs[j] as f64 * offsets[j]) / leg.signs[j] as f64
        });
        LegAngles {
            alpha: (model[0] / leg.alpha_ccw as f64).to_radians(),
            beta: model[1].to_radians(),
            gamma: model[2].to_radians(),
        }
    }

    /// Checks servo angles against Table 3.2 (and the servo's ±150°).
    pub fn check_limits(leg: &LegConfig, deg: [f64; 3]) -> Result<(), KinError> {
        for (j, (v, [lo, hi])) in deg.iter().zip(leg.limits_deg).enumerate() {
            if !(lo..=hi).contains(v) {
                return Err(KinError::Limit {
                    joint: format!("leg {} ({}) {}", leg.number, leg.name, JOINTS[j]),
                    value: *v,
                    min: lo,
                    max: hi,
                });
            }
        }
        Ok(())
    }

    /// The raw AX-12A goal of a servo angle about the centre: round((150 + deg) · 1023 / 300).
    pub fn raw(deg: f64) -> u16 {
        ((150.0 + deg) * 1023.0 / 300.0).round().clamp(0.0, 1023.0) as u16
    }

    /// Solves leg `number` for a foot at `foot` (body frame, metres): the joints, checked
    /// against the limits, with their servo angles and raw goals.
    pub fn solve(&self, number: u8, foot: [f64; 3]) -> Result<LegSolution, KinError> {
        let leg = self.leg_or_err(number)?;
        let angles = self
            .cfg
            .links
            .ik(Hexapod::to_leg(leg, foot), self.cfg.faithful)?;
        let servo_deg = self.servo_deg(leg, &angles);
        Hexapod::check_limits(leg, servo_deg)?;
        Ok(LegSolution {
            angles,
            servo_deg,
            raw: servo_deg.map(Hexapod::raw),
        })
    }

    /// Where the foot of leg `number` is (body frame) with servo angles `deg`.
    pub fn foot(&self, number: u8, deg: [f64; 3]) -> Result<[f64; 3], KinError> {
        let leg = self.leg_or_err(number)?;
        let a = self.angles_from_servo(leg, deg);
        Ok(Hexapod::to_body(leg, self.cfg.links.fk(&a)))
    }
}
