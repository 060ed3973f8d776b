//! The hexapod's leg kinematics: the thesis's worked example, FK∘IK round trips, the servo
//! mapping of Table 3.1 (mirrored legs mirror about 511.5) and the limits of Table 3.2.

use std::path::Path;

use proptest::prelude::*;
use stride_kinematics::hexapod::{Faithful, Hexapod, LegAngles, Links};
use stride_kinematics::KinError;

const LINKS: Links = Links {
    coxa: 0.052,
    femur: 0.066,
    tibia: 0.130,
};

fn shipped() -> Hexapod {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/robots/hexapod.toml");
    Hexapod::load(&path).unwrap()
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// The worked example: d_p = 100 mm, f_z = −90 mm, so the foot is 152 mm out from the coxa.
const EXAMPLE: [f64; 3] = [0.152, 0.0, -0.090];

#[test]
fn the_worked_example_gives_41_99_degrees_corrected_and_33_78_printed() {
    // By hand: d_l = √(100² + 90²) = 134.54 mm; δ = atan(90 / 100) = 41.99° (printed:
    // atan(90 / 134.54) = 33.78°); ε = acos((d_l² + 66² − 130²) / (2 · d_l · 66)) = 71.77°;
    // γ = acos((66² + 130² − d_l²) / (2 · 66 · 130)) = 79.40°.
    let dl = (0.1f64.powi(2) + 0.09f64.powi(2)).sqrt();
    let eps = ((dl * dl + 0.066f64.powi(2) - 0.13f64.powi(2)) / (2.0 * dl * 0.066))
        .acos()
        .to_degrees();
    assert!((eps - 71.77).abs() < 0.005, "{eps}");
    let a = LINKS.ik(EXAMPLE, Faithful::default()).unwrap();
    assert_eq!(a.alpha, 0.0);
    assert!((eps - a.beta.to_degrees() - 41.99).abs() < 0.005, "{a:?}");
    assert!((a.gamma.to_degrees() - 79.40).abs() < 0.005, "{a:?}");
    let printed = LINKS.ik(EXAMPLE, Faithful { eq_3_5: true }).unwrap();
    assert!(
        (eps - printed.beta.to_degrees() - 33.78).abs() < 0.005,
        "{printed:?}"
    );
    // The corrected angles put the foot there; the printed ones do not.
    assert!(dist(LINKS.fk(&a), EXAMPLE) < 1e-12);
    assert!(dist(LINKS.fk(&printed), EXAMPLE) > 0.01);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4000))]

    #[test]
    fn fk_of_ik_is_the_target_within_1e_9_m(
        alpha in -1.5f64..1.5, beta in -0.8f64..1.3, gamma in 0.5f64..3.0,
    ) {
        let target = LINKS.fk(&LegAngles { alpha, beta, gamma });
        // The foot out from the coxa axis (behind it, the coxa turned half round reaches it
        // another way).
        let tau = beta - (std::f64::consts::PI - gamma);
        let out = LINKS.coxa + LINKS.femur * beta.cos() + LINKS.tibia * tau.cos();
        prop_assume!(out > 1e-3);
        let a = LINKS.ik(target, Faithful::default()).unwrap();
        prop_assert!(dist(LINKS.fk(&a), target) < 1e-9, "{:?} -> {:?}", target, a);
    }

    #[test]
    fn any_target_gives_angles_or_an_error_never_nan(
        x in -0.4f64..0.4, y in -0.4f64..0.4, z in -0.4f64..0.4,
    ) {
        match LINKS.ik([x, y, z], Faithful::default()) {
            Ok(a) => {
                prop_assert!(a.alpha.is_finite() && a.beta.is_finite() && a.gamma.is_finite());
                prop_assert!(dist(LINKS.fk(&a), [x, y, z]) < 1e-9);
            }
            Err(KinError::Unreachable(_)) | Err(KinError::Singular(_)) => {}
            Err(e) => prop_assert!(false, "{e}"),
        }
    }
}

#[test]
fn unreachable_and_singular_targets_are_errors() {
    let e = LINKS.ik([0.4, 0.0, 0.0], Faithful::default()).unwrap_err();
    assert!(
        matches!(&e, KinError::Unreachable(m) if m.contains("reaches from 0.0640 to 0.1960 m")),
        "{e}"
    );
    // Too close to the femur joint: less than 130 − 66 mm.
    let e = LINKS
        .ik([0.062, 0.0, -0.01], Faithful::default())
        .unwrap_err();
    assert!(matches!(e, KinError::Unreachable(_)), "{e}");
    let e = LINKS.ik([0.0, 0.0, -0.1], Faithful::default()).unwrap_err();
    assert!(matches!(e, KinError::Singular(_)), "{e}");
    let e = LINKS
        .ik([f64::NAN, 0.0, -0.1], Faithful::default())
        .unwrap_err();
    assert!(matches!(e, KinError::Unreachable(_)), "{e}");
}

#[test]
fn mirrored_targets_on_mirrored_legs_give_raw_values_mirrored_about_511_5() {
    let h = shipped();
    // Front, middle and rear pairs: left leg, right leg.
    for (l, r) in [(1u8, 2u8), (6, 3), (5, 4)] {
        for target in [
            [0.172, 0.0, -0.08],
            [0.175, 0.03, -0.075],
            [0.17, -0.02, -0.085],
        ] {
            let left = h.leg(l).unwrap();
            let foot_l = Hexapod::to_body(left, target);
            let foot_r = [foot_l[0], -foot_l[1], foot_l[2]];
            let (sl, sr) = (h.solve(l, foot_l).unwrap(), h.solve(r, foot_r).unwrap());
            for j in 0..3 {
                let sum = sl.raw[j] as i32 + sr.raw[j] as i32;
                assert!(
                    (1022..=1024).contains(&sum),
                    "legs {l}/{r} joint {j}: {:?} and {:?}",
                    sl.raw,
                    sr.raw
                );
            }
        }
    }
    // The worked example's femur on legs 1 and 2: 150 ∓ 29.78° is 410 and 613, not equal.
    let (f1, f2) = (
        h.solve(1, Hexapod::to_body(h.leg(1).unwrap(), EXAMPLE))
            .unwrap(),
        h.solve(2, Hexapod::to_body(h.leg(2).unwrap(), EXAMPLE))
            .unwrap(),
    );
    assert_eq!((f1.raw[1], f2.raw[1]), (410, 613));
    assert!((f1.servo_deg[1] + 29.78).abs() < 0.005, "{f1:?}");
}

#[test]
fn with_zero_offsets_the_worked_example_exceeds_the_tibia_limit_on_legs_5_and_6() {
    let h = shipped();
    for n in 1..=6u8 {
        let foot = Hexapod::to_body(h.leg(n).unwrap(), EXAMPLE);
        let r = h.solve(n, foot);
        if n == 5 || n == 6 {
            let e = r.unwrap_err();
            assert!(
                matches!(&e, KinError::Limit { joint, value, max, .. }
                    if joint.ends_with("tibia") && (*value - 100.60).abs() < 0.005 && *max == 99.0),
                "leg {n}: {e}"
            );
        } else {
            let s = r.unwrap();
            assert!(
                (s.servo_deg[2].abs() - 100.60).abs() < 0.005,
                "leg {n}: {s:?}"
            );
        }
    }
}

#[test]
fn a_leg_1_coxa_target_of_45_degrees_is_refused() {
    let h = shipped();
    let leg = h.leg(1).unwrap();
    let at = |deg: f64| {
        let (s, c) = deg.to_radians().sin_cos();
        Hexapod::to_body(leg, [0.172 * c, 0.172 * s, -0.08])
    };
    let e = h.solve(1, at(45.0)).unwrap_err();
    assert!(
        matches!(&e, KinError::Limit { joint, max, .. } if joint == "leg 1 (lf) coxa" && *max == 42.0),
        "{e}"
    );
    assert!((h.solve(1, at(41.0)).unwrap().servo_deg[0] - 41.0).abs() < 1e-9);
    // Away from the middle leg it goes to −80°.
    assert!(h.solve(1, at(-79.0)).is_ok());
    assert!(h.solve(1, at(-81.0)).is_err());
}

#[test]
fn every_coxa_servo_turns_counter_clockwise_and_servo_angles_invert() {
    let h = shipped();
    for n in 1..=6u8 {
        let leg = h.leg(n).unwrap();
        let at = |deg: f64| {
            let (s, c) = deg.to_radians().sin_cos();
            Hexapod::to_body(leg, [0.172 * c, 0.172 * s, -0.08])
        };
        let (a, b) = (h.solve(n, at(0.0)).unwrap(), h.solve(n, at(10.0)).unwrap());
        assert!(
            (b.servo_deg[0] - a.servo_deg[0] - 10.0).abs() < 1e-9,
            "leg {n}"
        );
        // Forward kinematics from the servo angles finds the foot again.
        assert!(dist(h.foot(n, b.servo_deg).unwrap(), at(10.0)) < 1e-12);
    }
}

#[test]
fn robot_files_that_make_no_sense_are_refused() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/robots/hexapod.toml");
    let text = std::fs::read_to_string(path).unwrap();
    let e = Hexapod::from_toml(&text.replacen("number = 6", "number = 5", 1)).unwrap_err();
    assert!(e.to_string().contains("numbered 1 to 6"), "{e}");
    let e = Hexapod::from_toml(&text.replacen("signs = [1, 1, 1]", "signs = [2, 1, 1]", 1))
        .unwrap_err();
    assert!(e.to_string().contains("signs must be"), "{e}");
    let e = Hexapod::from_toml(&text.replacen("tibia = 0.130", "tibia = -0.130", 1)).unwrap_err();
    assert!(e.to_string().contains("positive"), "{e}");
    let e = Hexapod::from_toml(&text.replacen("[links]", "[links]\nknee = 1", 1)).unwrap_err();
    assert!(e.to_string().contains("unknown field"), "{e}");
}
