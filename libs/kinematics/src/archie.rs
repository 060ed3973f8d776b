//! Archie's legs (TU Wien's cost-oriented humanoid, 6 joints a leg) in one re-derived
//! convention, with the thesis's material checked against it.
//!
//! # The convention
//!
//! The pelvis frame has x forward, y left, z up, its origin at the pelvis centre (the middle
//! of the hip bar, the thesis's COM). A leg, from the pelvis down (`s` = +1 left, −1 right):
//!
//! - the hip joint H at (0, s·a6/2, d6): the three hip axes meet there (links 4 and 5 of the
//!   DH tables have zero a and d); the bar hangs d6 below it;
//! - hip yaw about z, hip roll about x, hip pitch about y;
//! - the thigh, d3 further out along the pitch axis (0, s·d3, 0), then a3 down to the knee;
//! - knee pitch about y; the shank, a2 down to the ankle pitch axis; ankle pitch about y;
//! - a1 down to the ankle roll axis (the ankle's two axes do not meet); ankle roll about x;
//! - the sole `sole` below that: the sole frame (x along the foot) is the leg's end.
//!
//! All angles are right-handed about those axes, zero with the legs straight and the feet
//! flat: a knee bends positive, a thigh lifted forward is a negative hip pitch.
//!
//! # The thesis's tables and script
//!
//! The symbolic DH tables 3 and 4 with the numbers of `Stepping.sce` (cm to m: a1 = 12,
//! a2 = 26, a3 = 31, d3 = 7.5, a6 = 18, d6 = 5, the sole 3.5 below the ankle roll axis) give
//! this geometry only with one quarter turn they do not print: +π/2 on DH joint 5 (the hip
//! roll; without it the yaw axis lies horizontal and the bar points forward), a base frame
//! with x up, y right and z forward (the ankle roll axis) 3.5 cm above the sole, and the DH
//! angles (θ1..θ6) = (θ0, −θ1, −θ2, −θ3, θ4 + π/2, θ5) of the script's right (support) leg,
//! (−θ11, θ10, θ9, θ8, −θ7 + π/2, −θ6) of its left (swing) leg ([`dh_frames`] checks it).
//! "Joint 6 is the COM" holds only for frame 6 moved half of a6 along its x: frame 6 itself
//! is the bar's end under the other hip. Eqs 31-36 agree with neither table (they need two
//! unprinted offsets).
//!
//! `Stepping.sce`'s hand-written chain (eqs 38-40, [`scilab_chain`], repaired as
//! documented there) is exact only with an upright pelvis (the support leg's pitches summing
//! to 0, its rolls summing to 0 or no hip yaw, and the swing hip's yaw undoing the support's);
//! elsewhere it is off by centimetres. Its joint pattern (eqs 41-54, [`joint_pattern`]) keeps
//! the pelvis upright, where the chain is exact.

use serde::Deserialize;
use stride_limits::angle::wrap;

use nalgebra::{Matrix3, Matrix6, Rotation3, Vector3, Vector6};

use crate::math::{at as pose_at, pose, rx, ry, rz, yawed, Frame, Pose, V3};
use crate::KinError;

/// The legs' dimensions, m.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Links {
    /// Ankle pitch axis to ankle roll axis.
    pub a1: f64,
    /// Shank: knee to ankle pitch axis.
    pub a2: f64,
    /// Thigh: hip joint to knee.
    pub a3: f64,
    /// The thigh's offset out from the hip joint, along the pitch axis.
    pub d3: f64,
    /// Between the hip joints.
    pub a6: f64,
    /// The hip joints above the bar (the pelvis centre).
    pub d6: f64,
    /// The ankle roll axis above the sole.
    pub sole: f64,
}

impl Links {
    /// `Stepping.sce`'s numbers (cm to m).
    pub const SCRIPT: Links = Links {
        a1: 0.12,
        a2: 0.26,
        a3: 0.31,
        d3: 0.075,
        a6: 0.18,
        d6: 0.05,
        sole: 0.035,
    };

    fn check(&self) -> Result<(), KinError> {
        let l = [
            self.a1, self.a2, self.a3, self.d3, self.a6, self.d6, self.sole,
        ];
        if l.iter().all(|v| v.is_finite() && *v >= 0.0) && self.a2 > 0.0 && self.a3 > 0.0 {
            Ok(())
        } else {
            Err(KinError::Config(format!(
                "Archie's links must be finite, not negative, shank and thigh positive: {self:?}"
            )))
        }
    }
}

/// A leg.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Leg {
    /// The left leg.
    Left,
    /// The right leg.
    Right,
}

impl Leg {
    /// +1 for the left leg, −1 for the right.
    pub fn sign(self) -> f64 {
        match self {
            Leg::Left => 1.0,
            Leg::Right => -1.0,
        }
    }

    /// "left" or "right".
    pub fn name(self) -> &'static str {
        match self {
            Leg::Left => "left",
            Leg::Right => "right",
        }
    }
}

/// The joints of a leg, in order from the pelvis.
pub const JOINTS: [&str; 6] = [
    "hip_yaw",
    "hip_roll",
    "hip_pitch",
    "knee",
    "ankle_pitch",
    "ankle_roll",
];

/// A leg's six joint angles, rad, in [`JOINTS`] order.
pub type Q = [f64; 6];

/// Points of a leg (pelvis frame, m): the hip joint, the knee, the ankle pitch axis, the
/// ankle roll axis, the sole.
pub type LegPoints = [V3; 5];

/// The hip joint of a leg, pelvis frame.
pub fn hip(links: &Links, leg: Leg) -> V3 {
    [0.0, leg.sign() * links.a6 / 2.0, links.d6]
}

/// Forward kinematics: the sole frame of `leg` in the pelvis frame.
pub fn fk(links: &Links, leg: Leg, q: &Q) -> Pose {
    fk_points(links, leg, q).0
}

/// Forward kinematics with the leg's points on the way (for the links' masses).
pub fn fk_points(links: &Links, leg: Leg, q: &Q) -> (Pose, LegPoints) {
    fk_points_sc(
        links,
        leg,
        &q.map(|a| {
            let (s, c) = a.sin_cos();
            [s, c]
        }),
    )
}

/// [`fk_points`] from each joint's sine and cosine.
fn fk_points_sc(links: &Links, leg: Leg, sc: &[[f64; 2]; 6]) -> (Pose, LegPoints) {
    let rx = |[s, c]: [f64; 2]| Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c);
    let ry = |[s, c]: [f64; 2]| Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c);
    let rz = |[s, c]: [f64; 2]| Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0);
    let s = leg.sign();
    let h = Vector3::from(hip(links, leg));
    let r_hip = rz(sc[0]) * rx(sc[1]) * ry(sc[2]);
    let top = h + r_hip * Vector3::new(0.0, s * links.d3, 0.0);
    let knee = top + r_hip * Vector3::new(0.0, 0.0, -links.a3);
    let r_shank = r_hip * ry(sc[3]);
    let pitch = knee + r_shank * Vector3::new(0.0, 0.0, -links.a2);
    let r_link = r_shank * ry(sc[4]);
    let roll = pitch + r_link * Vector3::new(0.0, 0.0, -links.a1);
    let r_foot = r_link * rx(sc[5]);
    let sole = roll + r_foot * Vector3::new(0.0, 0.0, -links.sole);
    (
        pose(Rotation3::from_matrix_unchecked(r_foot), sole.into()),
        [
            h.into(),
            knee.into(),
            pitch.into(),
            roll.into(),
            sole.into(),
        ],
    )
}

/// A cosine a rounding error past ±1 (a straight knee) brought back to it; further out, left
/// as it is for the caller to refuse.
fn snap(c: f64) -> f64 {
    if c.abs() > 1.0 && c.abs() < 1.0 + 1e-12 {
        c.signum()
    } else {
        c
    }
}

/// Inverse kinematics in closed form: the joints that put the sole of `leg` at `sole`
/// (pelvis frame), the knee bent forward (positive). From the foot up, the hip joint's place
/// in the foot frame fixes the ankle roll (the thigh's offset d3 keeps its distance from the
/// roll axis), then the knee and the ankle pitch (two links in the pitch plane above the
/// ankle's a1); the hip's yaw, roll and pitch are what rotation is left. An error, never NaN,
/// for a sole out of reach or a hip roll of ±90° (where yaw and pitch are one).
pub fn ik(links: &Links, leg: Leg, sole: &Pose) -> Result<Q, KinError> {
    ik_sc(links, leg, sole).map(|(q, _)| q)
}

/// [`ik`], with each joint's sine and cosine as the solution found them (no trigonometry
/// beyond the angles' own).
fn ik_sc(links: &Links, leg: Leg, sole: &Pose) -> Result<(Q, [[f64; 2]; 6]), KinError> {
    if !sole.is_finite() {
        return Err(KinError::Unreachable(format!(
            "{} foot: not finite",
            leg.name()
        )));
    }
    let s = leg.sign();
    let h = Vector3::from(hip(links, leg));
    let r_f = sole.rotation.matrix();
    // The ankle roll axis's point, and the hip joint seen from it in the foot frame.
    let a = sole.translation.vector + r_f * Vector3::new(0.0, 0.0, links.sole);
    let r = r_f.transpose() * (h - a);
    let y0 = -s * links.d3;
    let yz2 = r[1] * r[1] + r[2] * r[2] - links.d3 * links.d3;
    let out_of_reach = |what: &str| {
        KinError::Unreachable(format!(
            "{} foot: the hip joint is {:.4} m from the ankle ({what})",
            leg.name(),
            r.norm()
        ))
    };
    if yz2 < 0.0 {
        return Err(out_of_reach(
            "closer to the roll axis than the thigh's offset",
        ));
    }
    let z = yz2.sqrt();
    let q5 = wrap(z.atan2(y0) - r[2].atan2(r[1]));
    // q5 = atan2(z, y0) − atan2(r_z, r_y), both vectors of length ρ (z² + y0² = r_y² + r_z²).
    let rho2 = r[1] * r[1] + r[2] * r[2];
    let sc5 = if rho2 > 1e-24 {
        [(z * r[1] - y0 * r[2]) / rho2, (y0 * r[1] + z * r[2]) / rho2]
    } else {
        let (s, c) = q5.sin_cos();
        [s, c]
    };
    // The pitch plane: X = −a2 sin q4 − a3 sin(q3 + q4), Z − a1 = a2 cos q4 + a3 cos(q3 + q4).
    let (x, zp) = (r[0], z - links.a1);
    let (a2, a3) = (links.a2, links.a3);
    let c3 = snap((x * x + zp * zp - a2 * a2 - a3 * a3) / (2.0 * a2 * a3));
    if !(-1.0..=1.0).contains(&c3) {
        return Err(out_of_reach(&format!(
            "the knee reaches from {:.4} to {:.4} m",
            (a3 - a2).abs(),
            a2 + a3
        )));
    }
    let q3 = c3.acos();
    let s3 = (1.0 - c3 * c3).max(0.0).sqrt();
    let (k1, k2) = (a2 + a3 * c3, a3 * s3);
    let q4 = wrap((-x).atan2(zp) - k2.atan2(k1));
    // q4 = atan2(−x, zp) − atan2(k2, k1).
    let norms = (x * x + zp * zp).sqrt() * (k1 * k1 + k2 * k2).sqrt();
    let [s4, c4] = if norms > 1e-12 {
        [(-x * k1 - zp * k2) / norms, (zp * k1 - x * k2) / norms]
    } else {
        let (s, c) = q4.sin_cos();
        [s, c]
    };
    let (s34, c34) = (s3 * c4 + c3 * s4, c3 * c4 - s3 * s4);
    // The hip: Rz(q0) Rx(q1) Ry(q2) = R_f Rx(−q5) Ry(−(q3 + q4)).
    let [s5, c5] = sc5;
    let rx5 = Matrix3::new(1.0, 0.0, 0.0, 0.0, c5, s5, 0.0, -s5, c5);
    let ry34 = Matrix3::new(c34, 0.0, -s34, 0.0, 1.0, 0.0, s34, 0.0, c34);
    let m = r_f * rx5 * ry34;
    let sb = m[(2, 1)];
    let cb = (1.0 - sb * sb).sqrt();
    if !(-1.0..=1.0).contains(&sb) || cb < 1e-9 {
        return Err(KinError::Singular(format!(
            "{} hip roll at ±90°: yaw and pitch turn about one axis",
            leg.name()
        )));
    }
    let q1 = sb.asin();
    let q0 = (-m[(0, 1)]).atan2(m[(1, 1)]);
    let q2 = (-m[(2, 0)]).atan2(m[(2, 2)]);
    // m = Rz(q0) Rx(q1) Ry(q2): m01 = −s0 c1, m11 = c0 c1, m20 = −c1 s2, m22 = c1 c2.
    let sc = [
        [-m[(0, 1)] / cb, m[(1, 1)] / cb],
        [sb, cb],
        [-m[(2, 0)] / cb, m[(2, 2)] / cb],
        [s3, c3],
        [s4, c4],
        sc5,
    ];
    Ok(([q0, q1, q2, q3, q4, q5], sc))
}

/// The difference of two poses as a 6-vector: translation (m) and rotation vector (rad) of
/// `target` seen from `at`.
fn pose_error(at: &Pose, target: &Pose) -> Vector6<f64> {
    let dp = target.translation.vector - at.translation.vector;
    // The rotation vector of r (axis · angle), from its skew part sin θ · axis and its trace
    // by atan2: exact near the identity, where the solver ends (an angle by acos is not).
    let r = (target.rotation * at.rotation.inverse()).into_inner();
    let v = Vector3::new(
        r[(2, 1)] - r[(1, 2)],
        r[(0, 2)] - r[(2, 0)],
        r[(1, 0)] - r[(0, 1)],
    ) / 2.0;
    let (sin, cos) = (v.norm(), (r.trace() - 1.0) / 2.0);
    let w = if sin < 1e-12 {
        v
    } else {
        v * (sin.atan2(cos) / sin)
    };
    Vector6::new(dp[0], dp[1], dp[2], w[0], w[1], w[2])
}

/// Inverse kinematics by damped least squares from `q0` (the fallback of [`solve`]): the
/// Jacobian by central differences, the step Jᵀ (J Jᵀ + λ² I)⁻¹ e, until the pose is met to
/// 1e-12 m; an error when it is not within 200 iterations.
pub fn ik_dls(links: &Links, leg: Leg, sole: &Pose, q0: &Q) -> Result<Q, KinError> {
    let mut q = *q0;
    let lambda2 = 1e-6;
    for _ in 0..200 {
        let e = pose_error(&fk(links, leg, &q), sole);
        if e.norm() < 1e-12 {
            return Ok(q.map(wrap));
        }
        let mut j = Matrix6::<f64>::zeros();
        for k in 0..6 {
            let h = 1e-7;
            let (mut qp, mut qm) = (q, q);
            qp[k] += h;
            qm[k] -= h;
            // The error's change: −(d pose / d q_k).
            let ep = pose_error(&fk(links, leg, &qp), sole);
            let em = pose_error(&fk(links, leg, &qm), sole);
            j.set_column(k, &(-(ep - em) / (2.0 * h)));
        }
        // (J Jᵀ + λ² I) y = e; Δq = Jᵀ y.
        let jjt = j * j.transpose() + Matrix6::identity() * lambda2;
        let y = jjt.lu().solve(&e).ok_or_else(|| {
            KinError::Singular(format!("{} leg: the Jacobian is singular", leg.name()))
        })?;
        let dq = j.transpose() * y;
        for (k, qk) in q.iter_mut().enumerate() {
            *qk += dq[k];
        }
        if !q.iter().all(|v| v.is_finite()) {
            break;
        }
    }
    Err(KinError::Unreachable(format!(
        "{} foot: damped least squares did not meet the pose",
        leg.name()
    )))
}

/// Inverse kinematics, checked: the closed form; where it has no answer for a singular pose,
/// damped least squares from `near` (the last solution). Either way the answer's forward
/// kinematics must meet the pose within 1e-9 m and 1e-9 rad.
pub fn solve(links: &Links, leg: Leg, sole: &Pose, near: &Q) -> Result<Q, KinError> {
    solve_points(links, leg, sole, near).map(|(q, _)| q)
}

/// [`solve`], with the leg's points of the check's forward kinematics (see [`fk_points`]).
pub fn solve_points(
    links: &Links,
    leg: Leg,
    sole: &Pose,
    near: &Q,
) -> Result<(Q, LegPoints), KinError> {
    // The check's forward kinematics from the sines and cosines the closed form found with
    // its angles (the numeric fallback's from its angles).
    let (q, (at, points)) = match ik_sc(links, leg, sole) {
        Ok((q, sc)) => (q, fk_points_sc(links, leg, &sc)),
        Err(KinError::Singular(_)) => {
            let q = ik_dls(links, leg, sole, near)?;
            (q, fk_points(links, leg, &q))
        }
        Err(e) => return Err(e),
    };
    let (dp, dr) = at.distance(sole);
    if dp < 1e-9 && dr < 1e-9 {
        Ok((q, points))
    } else {
        Err(KinError::Unreachable(format!(
            "{} foot: the solution misses the pose by {dp:.2e} m, {dr:.2e} rad",
            leg.name()
        )))
    }
}

/// The highest the pelvis centre stands (upright, level) with the feet's ankles `length`
/// apart along x and `width` apart across, the pelvis over either foot or halfway (where a
/// double support's COM goes), `ahead` in front of where it would be over the ankles (the
/// ZMP's point on the sole lies ahead of the ankle), every leg's joints accepted by `fits`
/// (a least knee bend, the joints' limits): the height of the worst double support of a step
/// of that length. By a scan from the top, then bisection.
pub fn max_pelvis_height(
    links: &Links,
    length: f64,
    width: f64,
    ahead: f64,
    fits: impl Fn(Leg, &Q) -> bool,
) -> f64 {
    let ok = |z: f64| {
        [0.0, 0.5, 1.0].iter().all(|&f| {
            // The right ankle at the origin, the left `length` ahead and `width` to the left;
            // the pelvis a share f of the way from the right foot to the left, and ahead.
            let pelvis = [f * length + ahead, f * width, z];
            [(Leg::Left, [length, width]), (Leg::Right, [0.0, 0.0])]
                .iter()
                .all(|&(leg, at)| {
                    let sole = pose_at([at[0] - pelvis[0], at[1] - pelvis[1], -z]);
                    ik(links, leg, &sole).is_ok_and(|q| fits(leg, &q))
                })
        })
    };
    // From the top down to the first height that works, then bisection above it (the legs'
    // reach bounds the heights from above: just above the first that works, none do).
    let top = links.a3 + links.a2 + links.a1 + links.sole;
    let step = 0.005;
    let mut z = top;
    while z > 0.0 && !ok(z) {
        z -= step;
    }
    if z <= 0.0 {
        return 0.0;
    }
    let (mut lo, mut hi) = (z, z + step);
    for _ in 0..60 {
        let mid = (lo + hi) / 2.0;
        if ok(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// The DH frames of Table 4 (`Leg::Right`) or Table 3 (`Leg::Left`) with the script's
/// numbers, the quarter turn on joint 5 and the base frame found for them, for the DH angles
/// `theta` (θ1..θ6; see [`dh_angles`]): frames 0 to 6 in the frame of that leg's sole (x
/// forward, y left, z up, below the ankle roll axis). Frame 6 is the bar's end under the
/// other hip; the pelvis centre is frame 6 moved half of a6 along its x (Table 4's −a6 makes
/// the right leg's x6 point right).
pub fn dh_frames(links: &Links, leg: Leg, theta: &Q) -> [Pose; 7] {
    let half = std::f64::consts::FRAC_PI_2;
    // (a, α, d) of each link; Table 3's α1, α4 and a6 differ from Table 4's in sign.
    let s = leg.sign();
    let table = [
        (links.a1, s * half, 0.0),
        (links.a2, 0.0, 0.0),
        (links.a3, 0.0, -links.d3),
        (0.0, -s * half, 0.0),
        (0.0, -half, 0.0),
        (s * links.a6, 0.0, links.d6),
    ];
    let offsets = [0.0, 0.0, 0.0, 0.0, half, 0.0];
    // Base (both legs): x0 up, y0 right, z0 forward (the ankle roll axis), the ankle roll
    // axis's height above the sole.
    let base = pose(
        Rotation3::from_matrix_unchecked(Matrix3::new(
            0.0, 0.0, 1.0, 0.0, -1.0, 0.0, 1.0, 0.0, 0.0,
        )),
        [0.0, 0.0, links.sole],
    );
    let mut frames = [base; 7];
    for i in 0..6 {
        let (a, alpha, d) = table[i];
        let th = theta[i] + offsets[i];
        let step = pose(rz(th), [0.0; 3])
            * pose_at([0.0, 0.0, d])
            * pose_at([a, 0.0, 0.0])
            * pose(rx(alpha), [0.0; 3]);
        frames[i + 1] = frames[i] * step;
    }
    frames
}

/// The DH angles θ1..θ6 of `leg` for its joints `q`, from the ankle roll up (the base's
/// axes turn the rolls around; Table 3's α1 and α4 turn the left leg's pitches too).
pub fn dh_angles(leg: Leg, q: &Q) -> Q {
    match leg {
        Leg::Right => [-q[5], q[4], q[3], q[2], -q[1], q[0]],
        Leg::Left => [-q[5], -q[4], -q[3], -q[2], -q[1], q[0]],
    }
}

/// The pelvis frame in the frame of `leg`'s sole from its DH frames: frame 6 moved half of a6
/// along its x toward the middle, turned to x forward, y left, z up.
pub fn dh_pelvis(links: &Links, leg: Leg, frames: &[Pose; 7]) -> Pose {
    frames[6]
        * pose(
            Rotation3::from_matrix_unchecked(Matrix3::new(
                0.0, -1.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, -1.0,
            )),
            [-leg.sign() * links.a6 / 2.0, 0.0, 0.0],
        )
}

/// The script's angles θ0..θ11 (right, support leg: θ0 ankle roll to θ5 hip yaw; left,
/// swing leg: θ6 hip yaw to θ11 ankle roll) as the legs' joints (left, right).
pub fn from_script(theta: &[f64; 12]) -> (Q, Q) {
    let t = theta.map(wrap);
    let right = [t[5], -t[4], -t[3], -t[2], -t[1], -t[0]];
    let left = [-t[6], t[7], -t[8], -t[9], -t[10], t[11]];
    (left, right)
}

/// `Stepping.sce`'s chain (eqs 38-40 as the script codes them) for its angles θ0..θ11: the
/// points x0..x12 (the right ankle roll axis up the right leg, across the bar, down the left
/// leg to its sole), metres, in the right sole's frame. Repaired where the print is damaged:
/// y6 rebuilt from y61 and eq 39; y9's `+` for `*`; y10's a9 for a10; y11's `v` for `y`, its
/// lost θ0 and `(i,i,1)`; y12's θ1 for θ11 and its duplicated tail; z10 to z12's lost `−`;
/// z11's lost θ8 and θ10; z12's `)`.
pub fn scilab_chain(links: &Links, theta: &[f64; 12]) -> [V3; 13] {
    let (s, c) = (f64::sin, f64::cos);
    let [t0, t1, t2, t3, t4, t5, t6, t7, t8, t9, t10, t11] = *theta;
    let (a1, a2, a3, a6, d3, d6) = (links.a1, links.a2, links.a3, links.a6, links.d3, links.d6);
    // The swing leg mirrors the support leg: a9 = a3, a10 = a2, a11 = a1, a12 = the sole.
    let (a9, a10, a11, a12) = (a3, a2, a1, links.sole);
    let p123 = t1 + t2 + t3;
    let (x0, y0, z0) = (0.0, 0.0, links.sole);
    let x1 = x0;
    let x2 = x0 + a2 * s(t1);
    let x3 = x2 + a3 * s(t1 + t2);
    let x4 = x3;
    let x5 = x4 - d6 * s(p123);
    let x6 = x5 + a6 * c(t4 + t0) * c(p123) * s(t5);
    let x7 = x6 + d6 * s(p123);
    let x8 = x7 + d3 * c(t4 + t0 + t7) * c(p123) * s(t5 + t6);
    let y1 = y0 - a1 * s(t0);
    let y2 = y1 - a2 * c(t1) * s(t0);
    let y3 = y2 - a3 * c(t1 + t2) * s(t0);
    let y4 = y3 + d3 * c(t0);
    let y5 = y4 + d6 * s(t4 + t0);
    let y6 = y5 + a6 * c(t4 + t0) * c(p123) * c(t5);
    let y7 = y6 - d6 * s(t4 + t0);
    let y8 = y7 + d3 * c(t4 + t0 + t7) * c(p123) * c(t5 + t6);
    let z1 = z0 + a1 * c(t0);
    let z2 = z1 + a2 * c(t1) * c(t0);
    let z3 = z2 + a3 * c(t1 + t2) * c(t0);
    let z4 = z3 + d3 * s(t0);
    let z5 = z4 - d6 * c(t4 + t0) * c(p123);
    let z6 = z5 + a6 * s(t4 + t0) * c(p123);
    let z7 = z6 + d6 * c(t4 + t0) * c(p123);
    let z8 = z7 + d3 * s(t4 + t0 + t7) * c(p123);
    let (q8, r) = (p123 + t8, t4 + t0 + t7);
    let (q9, q10) = (q8 + t9, q8 + t9 + t10);
    let x9 = x8 + a9 * s(q8);
    let x10 = x9 + a10 * s(q9);
    let x11 = x10 + a11 * s(q10);
    let x12 = x11 + a12 * s(q10);
    let y9 = y8 + a9 * s(r) * c(q8);
    let y10 = y9 + a10 * s(r) * c(q9);
    let y11 = y10 + a11 * s(r) * c(q10);
    let y12 = y11 + a12 * s(r + t11) * c(q10);
    let z9 = z8 - a9 * c(r) * c(q8);
    let z10 = z9 - a10 * c(r) * c(q9);
    let z11 = z10 - a11 * c(r) * c(q10);
    let z12 = z11 - a12 * c(r + t11) * c(q10);
    [
        [x0, y0, z0],
        [x1, y1, z1],
        [x2, y2, z2],
        [x3, y3, z3],
        [x4, y4, z4],
        [x5, y5, z5],
        [x6, y6, z6],
        [x7, y7, z7],
        [x8, y8, z8],
        [x9, y9, z9],
        [x10, y10, z10],
        [x11, y11, z11],
        [x12, y12, z12],
    ]
}

/// The same points of the robot by this module's kinematics, for the script's angles: with
/// the right sole on the ground (its frame the reference), the pelvis where the right leg
/// holds it and the left leg hanging from it.
pub fn exact_chain(links: &Links, theta: &[f64; 12]) -> [V3; 13] {
    let (ql, qr) = from_script(theta);
    let (sole_r, pr) = fk_points(links, Leg::Right, &qr);
    let pelvis = sole_r.inverse(); // the pelvis in the right sole's frame
    let (_, pl) = fk_points(links, Leg::Left, &ql);
    let w = |p: &V3| pelvis.apply(p);
    let s = -1.0;
    let r_hip = rz(qr[0]) * rx(qr[1]) * ry(qr[2]);
    let top_r: V3 = (Vector3::from(pr[0]) + r_hip * Vector3::new(0.0, s * links.d3, 0.0)).into();
    let l_hip = rz(ql[0]) * rx(ql[1]) * ry(ql[2]);
    let top_l: V3 = (Vector3::from(pl[0]) + l_hip * Vector3::new(0.0, links.d3, 0.0)).into();
    let bar_r = [0.0, -links.a6 / 2.0, 0.0];
    let bar_l = [0.0, links.a6 / 2.0, 0.0];
    [
        w(&pr[3]),
        w(&pr[2]),
        w(&pr[1]),
        w(&top_r),
        w(&pr[0]),
        w(&bar_r),
        w(&bar_l),
        w(&pl[0]),
        w(&top_l),
        w(&pl[1]),
        w(&pl[2]),
        w(&pl[3]),
        w(&pl[4]),
    ]
}

/// The geometric joint pattern's published equations, run as printed (off: the exact forms).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Faithful {
    /// Eq 42's small-angle form of the hip roll, with `Stepping.sce`'s min(|θ01|, |θ02|).
    pub eq_42: bool,
    /// `Stepping.sce`'s sign conventions for the pattern's angles θ0..θ11 (its
    /// y1 = y0 − a1 sin θ0, the opposite of eq 39; its knee θ9 = π − γ, the opposite of eq 48;
    /// a swing hip lifted forward positive). Off: each angle right-handed about its joint's
    /// axis, this module's convention ([`SCRIPT_TO_JOINT`]).
    pub scilab_signs: bool,
}

/// The sign that turns each of the script's angles θ0..θ11 into this module's convention
/// (right-handed about the joint's axis): [`from_script`] is these signs and a reordering.
pub const SCRIPT_TO_JOINT: [f64; 12] = [
    -1.0, -1.0, -1.0, -1.0, -1.0, 1.0, -1.0, 1.0, -1.0, -1.0, -1.0, 1.0,
];

/// The joint pattern of one sample (eqs 41-54, as `Stepping.sce` runs them): the script's
/// angles and the points it reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PatternSample {
    /// θ0..θ11, rad (θ9 and θ10 wrapped to (−π, π]): in `Stepping.sce`'s signs with
    /// [`Faithful::scilab_signs`], else in this module's ([`SCRIPT_TO_JOINT`]).
    pub theta: [f64; 12],
    /// The signs `theta` is in: the script's.
    pub scilab_signs: bool,
    /// The pelvis centre's y (the script's y61), m.
    pub hip_y: f64,
    /// The right hip joint's height (z4), m.
    pub z_hip: f64,
    /// hn1 of eq 46, m.
    pub hn1: f64,
}

/// The hip roll of eq 41 in closed form, in the script's sign: exact (the small root of
/// k2 t² + 2 k1 t + k3 = 0 with t = tan(θ0/2), in a form without the printed formula's
/// division by k2), or as eq 42 prints it with the script's min(|θ01|, |θ02|).
pub fn hip_roll(k1: f64, k2: f64, k3: f64, faithful: Faithful) -> Result<f64, KinError> {
    let disc = k1 * k1 - k2 * k3;
    if disc.is_nan() || disc < 0.0 {
        return Err(KinError::Unreachable(format!(
            "eq 42: no hip roll puts the COM there (k1² − k2 k3 = {disc:.3e} < 0)"
        )));
    }
    if faithful.eq_42 {
        if k2 == 0.0 {
            return Err(KinError::Singular(
                "eq 42 divides by k2 = 0 (the COM at a6/2 − d3 from the ankle)".into(),
            ));
        }
        let root = (4.0 * disc).sqrt();
        let th01 = (2.0 * ((2.0 * k1 + root) / (2.0 * k2))).atan();
        let th02 = (2.0 * ((2.0 * k1 - root) / (2.0 * k2))).atan();
        Ok(th01.abs().min(th02.abs()))
    } else {
        let t = -k3 / (k1 + k1.signum() * disc.sqrt());
        // Eq 41's own sign is the script's negated.
        Ok(-2.0 * t.atan())
    }
}

/// The joint pattern for the pelvis centre ΔX ahead of and ΔY beside the right (support)
/// ankle (m): support leg by eqs 41-43 (knee straight, pelvis upright), swing leg by eqs
/// 44-52 (foot flat, ΔX ahead), as `Stepping.sce` computes them.
pub fn joint_pattern(
    links: &Links,
    dx: f64,
    dy: f64,
    faithful: Faithful,
) -> Result<PatternSample, KinError> {
    links.check()?;
    let reach = links.a2 + links.a3;
    if !(dx.is_finite() && dy.is_finite()) || dx.abs() > reach {
        return Err(KinError::Unreachable(format!(
            "the pattern's COM {dx} m ahead is beyond the leg's {reach} m"
        )));
    }
    let th1 = (dx / reach).asin();
    let k1 = links.a1 + reach * th1.cos();
    let k2 = links.a6 / 2.0 - links.d3 - dy;
    let k3 = links.d3 + links.a6 / 2.0 - dy;
    let th0 = hip_roll(k1, k2, k3, faithful)?;
    let mut theta = [0.0; 12];
    theta[0] = th0;
    theta[1] = th1;
    theta[3] = -th1;
    theta[4] = -th0;
    let pts = scilab_chain(links, &theta);
    let (y8, z8) = (pts[8][1], pts[8][2]);
    let hn1 = z8 - y8 * (2.0 * th0).tan() - links.a1 - links.sole;
    let r2 = dx * dx + hn1 * hn1;
    let r = r2.sqrt();
    let (a9, a10) = (links.a3, links.a2);
    let cg = snap((a9 * a9 + a10 * a10 - r2) / (2.0 * a9 * a10));
    let c8 = snap((a9 * a9 + r2 - a10 * a10) / (2.0 * a9 * r));
    if !((-1.0..=1.0).contains(&cg) && (-1.0..=1.0).contains(&c8)) || hn1 == 0.0 {
        return Err(KinError::Unreachable(format!(
            "eqs 47-50: the swing foot {r:.4} m from the hip is out of the leg's reach"
        )));
    }
    let gamma = -cg.acos();
    theta[9] = wrap(std::f64::consts::PI - gamma);
    theta[8] = c8.acos() + (dx / hn1).atan();
    theta[10] = wrap(-(theta[9] + theta[8]));
    let p123 = theta[1] + theta[2] + theta[3];
    let hip_y =
        pts[5][1] + (links.a6 / 2.0) * (theta[4] + theta[0]).cos() * p123.cos() * theta[5].cos();
    if !faithful.scilab_signs {
        for (t, sign) in theta.iter_mut().zip(SCRIPT_TO_JOINT) {
            *t *= sign;
        }
    }
    Ok(PatternSample {
        theta,
        scilab_signs: faithful.scilab_signs,
        hip_y,
        z_hip: pts[4][2],
        hn1,
    })
}

impl PatternSample {
    /// θ0..θ11 in `Stepping.sce`'s signs, whichever signs the sample is in.
    pub fn script_theta(&self) -> [f64; 12] {
        if self.scilab_signs {
            return self.theta;
        }
        std::array::from_fn(|k| self.theta[k] * SCRIPT_TO_JOINT[k])
    }

    /// The legs' joints (left, right) of the sample.
    pub fn legs(&self) -> (Q, Q) {
        from_script(&self.script_theta())
    }
}

/// Eq 41's residual for a support leg's hip roll (script sign) and ankle pitch: its y_COM
/// less `dy`, m.
pub fn eq_41_residual(links: &Links, th0_script: f64, th1: f64, dy: f64) -> f64 {
    let th0 = -th0_script;
    (links.a1 + (links.a2 + links.a3) * th1.cos()) * th0.sin()
        + links.d3 * th0.cos()
        + links.a6 / 2.0
        - dy
}

/// A sole's pose from its frame's heading and place (level).
pub fn level(p: V3, yaw: f64) -> Pose {
    yawed(p, yaw)
}

/// What drives a joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Motor {
    /// A Maxon EC 45 flat on a 160:1 harmonic drive.
    Brushless,
    /// The brushed motor on a 415:1 planetary gear.
    Brushed,
}

/// One joint's limits (the same on both legs).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointSpec {
    /// One of [`JOINTS`].
    pub name: String,
    /// Lowest angle, rad.
    pub min: f64,
    /// Highest angle, rad.
    pub max: f64,
    /// Top speed, rad/s.
    pub max_velocity: f64,
    /// Top acceleration, rad/s².
    pub max_acceleration: f64,
    /// What drives it.
    pub motor: Motor,
}

/// The sole the ZMP must stay on, and where its centre is.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FootSpec {
    /// Along the foot, m.
    pub length: f64,
    /// Across the foot, m.
    pub width: f64,
    /// The sole's centre ahead of the ankle, m.
    pub centre_ahead: f64,
}

/// Point masses, kg: the pelvis's at its centre, each leg link's at its middle (the foot's
/// at the ankle roll axis).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Masses {
    /// The pelvis with the trunk and what it carries.
    pub pelvis: f64,
    /// One thigh.
    pub thigh: f64,
    /// One shank.
    pub shank: f64,
    /// One foot with the ankle's drives.
    pub foot: f64,
}

impl Masses {
    /// The robot's mass.
    pub fn total(&self) -> f64 {
        self.pelvis + 2.0 * (self.thigh + self.shank + self.foot)
    }
}

/// Archie's robot file (`config/robots/archie.toml`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArchieConfig {
    /// The legs' dimensions.
    pub links: Links,
    /// The six joints' limits, in [`JOINTS`] order.
    pub joint: Vec<JointSpec>,
    /// The sole.
    pub foot: FootSpec,
    /// The masses.
    pub mass: Masses,
    /// Published equations run as printed.
    #[serde(default)]
    pub faithful: Faithful,
}

impl ArchieConfig {
    /// Reads and checks a robot file.
    pub fn load(path: &std::path::Path) -> Result<ArchieConfig, KinError> {
        let cfg: ArchieConfig = crate::read_toml(path)?;
        cfg.check()?;
        Ok(cfg)
    }

    /// Parses and checks a robot file's text.
    pub fn from_toml(text: &str) -> Result<ArchieConfig, KinError> {
        let cfg: ArchieConfig =
            toml::from_str(text).map_err(|e| KinError::Config(e.to_string()))?;
        cfg.check()?;
        Ok(cfg)
    }

    /// Checks the file: the links, the six joints in order with ordered, finite limits and
    /// positive speeds, a sole and masses of positive size.
    pub fn check(&self) -> Result<(), KinError> {
        self.links.check()?;
        let names: Vec<&str> = self.joint.iter().map(|j| j.name.as_str()).collect();
        if names != JOINTS {
            return Err(KinError::Config(format!(
                "Archie's joints must be {JOINTS:?} in that order, not {names:?}"
            )));
        }
        for j in &self.joint {
            let ok = j.min.is_finite()
                && j.max.is_finite()
                && j.min < j.max
                && j.max_velocity.is_finite()
                && j.max_velocity > 0.0
                && j.max_acceleration.is_finite()
                && j.max_acceleration > 0.0;
            if !ok {
                return Err(KinError::Config(format!(
                    "joint {}: ordered finite limits and a positive speed and acceleration",
                    j.name
                )));
            }
        }
        let f = &self.foot;
        let m = &self.mass;
        let sole_ok = f.length > 0.0 && f.width > 0.0 && f.centre_ahead.is_finite();
        let masses_ok = [m.pelvis, m.thigh, m.shank, m.foot]
            .iter()
            .all(|v| v.is_finite() && *v >= 0.0)
            && m.total() > 0.0;
        if !(sole_ok && masses_ok) {
            return Err(KinError::Config(
                "a sole of positive size and masses that are not negative".into(),
            ));
        }
        Ok(())
    }

    /// The joints' names on `leg`, e.g. "left_knee".
    pub fn names(&self, leg: Leg) -> [String; 6] {
        std::array::from_fn(|k| format!("{}_{}", leg.name(), JOINTS[k]))
    }

    /// Checks joint angles against the position limits.
    pub fn check_q(&self, leg: Leg, q: &Q) -> Result<(), KinError> {
        for (k, (v, j)) in q.iter().zip(&self.joint).enumerate() {
            if !(j.min..=j.max).contains(v) {
                return Err(KinError::Limit {
                    joint: format!("{}_{}", leg.name(), JOINTS[k]),
                    value: v.to_degrees(),
                    min: j.min.to_degrees(),
                    max: j.max.to_degrees(),
                });
            }
        }
        Ok(())
    }

    /// The sole frame's pose (below the ankle) of a foot whose sole centre is at `centre`
    /// with heading `yaw`, on level ground.
    pub fn sole_frame(&self, centre: V3, yaw: f64) -> Pose {
        let (s, c) = yaw.sin_cos();
        let b = self.foot.centre_ahead;
        yawed([centre[0] - c * b, centre[1] - s * b, centre[2]], yaw)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_closed_forms_sines_and_cosines_are_its_angles() {
        // The check of `solve` runs forward kinematics on the sines and cosines the closed
        // form found; they must be those of the angles it returns.
        let links = Links::SCRIPT;
        let mut seed = 11u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut checked = 0;
        for i in 0..2000 {
            let leg = if i % 2 == 0 { Leg::Left } else { Leg::Right };
            let q: Q = [
                rnd() - 0.5,
                rnd() - 0.5,
                -1.5 + 2.0 * rnd(),
                0.05 + 2.0 * rnd(),
                -1.0 + 2.0 * rnd(),
                rnd() - 0.5,
            ];
            let Ok((got, sc)) = ik_sc(&links, leg, &fk(&links, leg, &q)) else {
                continue;
            };
            for (a, [s, c]) in got.iter().zip(sc) {
                assert!((a.sin() - s).abs() < 1e-9 && (a.cos() - c).abs() < 1e-9);
            }
            checked += 1;
        }
        assert!(checked > 1900, "{checked}");
    }
}
