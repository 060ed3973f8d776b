//! Archie's leg kinematics against independent references: an independent DH-chain
//! computation of the thesis's geometry (golden vectors), the thesis's DH tables with the
//! quarter turn they do not print, `Stepping.sce`'s chain and joint pattern (the notes'
//! table of section 2.4.6), FK∘IK round trips and the fallback.

use std::path::Path;

use proptest::prelude::*;
use stride_kinematics::archie::{
    self, dh_angles, dh_frames, dh_pelvis, eq_41_residual, exact_chain, fk, from_script, ik,
    ik_dls, joint_pattern, max_pelvis_height, scilab_chain, solve, ArchieConfig, Faithful, Leg,
    Links, Q,
};
use stride_kinematics::math::{at, pose, rx, ry, rz, Frame, Matrix3, Rotation3};
use stride_kinematics::KinError;

const L: Links = Links::SCRIPT;

fn shipped() -> ArchieConfig {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/robots/archie.toml");
    ArchieConfig::load(&path).unwrap()
}

fn close(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Script angles θ0..θ11; the pelvis (position, rotation) in the right sole's frame; the
/// left sole's origin there. Computed by `tests/golden/archie_poe.py`, which shares no code
/// with this crate: the product of exponentials of the twelve joints' twists, from the
/// right sole up one leg and down the other, the axes written from the thesis's Tables 3
/// and 4 and the signs of `Stepping.sce` (the test below runs it).
#[allow(clippy::type_complexity)]
const GOLDEN: [([f64; 12], [f64; 3], [[f64; 3]; 3], [f64; 3]); 5] = [
    // G1: zero
    (
        [0.0; 12],
        [0.0, 0.165, 0.675],
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        [0.0, 0.33, 0.0],
    ),
    // G2: frontal, pelvis upright
    (
        [
            0.1, 0.0, 0.0, 0.0, -0.1, 0.0, 0.0, 0.05, 0.3, -0.6, 0.3, -0.05,
        ],
        [0.0, 0.0957402549095405, 0.67904038029035],
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        [
            0.014776010333066962,
            0.2938597714889089,
            0.03407752338921802,
        ],
    ),
    // G3: sagittal, pelvis upright
    (
        [0.0, 0.2, 0.3, -0.5, 0.0, 0.0, 0.0, 0.0, 0.4, -0.5, 0.1, 0.0],
        [0.20027594297401882, 0.165, 0.6318679044247383],
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        [0.29503894076152515, 0.33, -0.017362086688442947],
    ),
    // G4: pelvis upright, with yaw
    (
        [
            -0.08, 0.15, 0.1, -0.25, 0.08, 0.3, -0.3, 0.1, 0.2, -0.4, 0.2, -0.1,
        ],
        [0.14214596041155847, 0.21487808847181716, 0.6542830662101333],
        [
            [0.955336489125606, 0.29552020666133955, 0.0],
            [-0.29552020666133955, 0.955336489125606, 0.0],
            [0.0, 0.0, 1.0],
        ],
        [
            0.17867624555083209,
            0.4432344300407288,
            0.0015229861202469483,
        ],
    ),
    // G5: general
    (
        [
            0.1, -0.2, 0.4, 0.15, 0.2, -0.3, 0.1, -0.1, 0.25, -0.5, 0.2, 0.08,
        ],
        [
            -0.025996734350700077,
            0.10268699029476441,
            0.706377264751819,
        ],
        [
            [
                0.9175488346467758,
                -0.21252296505940754,
                0.33606268070212914,
            ],
            [0.315380300322442, 0.9037001299761696, -0.2895882270562472],
            [-0.24215573957036343, 0.371698889429888, 0.8962145576756262],
        ],
        [-0.2638257302124077, 0.3828886771140515, 0.1483180142043473],
    ),
];

#[test]
fn the_golden_vectors_are_what_the_independent_program_computes() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests");
    let out = std::process::Command::new("python3")
        .arg(dir.join("golden/archie_poe.py"))
        .arg("--check")
        .arg(dir.join("archie.rs"))
        .output()
        .expect("python3 (scripts/setup installs it)");
    let text =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{text}");
    assert!(
        text.contains("all 135 numbers of 5 entries agree"),
        "{text}"
    );
}

#[test]
fn forward_kinematics_meets_the_golden_vectors() {
    for (k, (theta, pelvis_p, pelvis_r, left_sole)) in GOLDEN.iter().enumerate() {
        let (ql, qr) = from_script(theta);
        // The pelvis in the right sole's frame, the left sole in it.
        let pelvis = fk(&L, Leg::Right, &qr).inverse();
        let r = Matrix3::from_row_slice(&pelvis_r.concat());
        let (dp, dr) = pelvis.distance(&pose(Rotation3::from_matrix_unchecked(r), *pelvis_p));
        assert!(dp < 1e-12 && dr < 1e-12, "G{}: {dp:.2e} m, {dr:.2e}", k + 1);
        let left = pelvis * fk(&L, Leg::Left, &ql);
        assert!(
            close(&left.position(), left_sole) < 1e-12,
            "G{}: {:?}",
            k + 1,
            left.position()
        );
    }
}

#[test]
fn the_dh_tables_give_this_geometry_with_a_quarter_turn_on_joint_5() {
    let mut rng = 0x1234_5678_u64;
    let mut next = || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        (rng % 10_000) as f64 / 10_000.0 - 0.5
    };
    for _ in 0..500 {
        let q: Q = std::array::from_fn(|_| next() * 1.6);
        for leg in [Leg::Left, Leg::Right] {
            let frames = dh_frames(&L, leg, &dh_angles(leg, &q));
            let pelvis = dh_pelvis(&L, leg, &frames);
            let (dp, dr) = pelvis.distance(&fk(&L, leg, &q).inverse());
            assert!(dp < 1e-12 && dr < 1e-12, "{leg:?} {q:?}: {dp:.2e} {dr:.2e}");
        }
    }
}

#[test]
fn without_the_quarter_turn_the_dh_tables_miss_the_geometry() {
    // The tables as printed (no offset on joint 5): the bar points forward, not across.
    let q = [0.0; 6];
    let mut th = dh_angles(Leg::Right, &q);
    th[4] -= std::f64::consts::FRAC_PI_2;
    let frames = dh_frames(&L, Leg::Right, &th);
    let pelvis = dh_pelvis(&L, Leg::Right, &frames);
    let (dp, _) = pelvis.distance(&fk(&L, Leg::Right, &q).inverse());
    assert!(dp > 0.05, "{dp}");
}

/// Random joint sets with the pelvis upright where `Stepping.sce`'s chain is exact: the
/// support leg's pitches sum to 0, its rolls too, the swing hip's yaw undoes the support's,
/// the swing foot flat in pitch.
fn upright(r: [f64; 9]) -> [f64; 12] {
    let [t0, t1, t2, t5, t7, t8, t9, t11, _] = r;
    [
        t0,
        t1,
        t2,
        -(t1 + t2),
        -t0,
        t5,
        -t5,
        t7,
        t8,
        t9,
        -(t8 + t9),
        t11,
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn the_scripts_chain_is_exact_with_an_upright_pelvis(
        r in proptest::array::uniform9(-0.5f64..0.5),
    ) {
        let theta = upright(r);
        let (a, b) = (scilab_chain(&L, &theta), exact_chain(&L, &theta));
        for (i, (p, q)) in a.iter().zip(&b).enumerate() {
            prop_assert!(close(p, q) < 1e-12, "point {i}: {p:?} vs {q:?}");
        }
    }

    #[test]
    fn fk_of_ik_meets_the_target_within_1e_9_m(
        q in proptest::array::uniform6(-0.5f64..0.5), knee in 0.05f64..1.8, left in any::<bool>(),
    ) {
        let leg = if left { Leg::Left } else { Leg::Right };
        let q = [q[0], q[1], q[2] * 2.0, knee, q[4] * 1.5, q[5]];
        let target = fk(&L, leg, &q);
        let got = ik(&L, leg, &target).unwrap();
        let (dp, dr) = fk(&L, leg, &got).distance(&target);
        prop_assert!(dp < 1e-9 && dr < 1e-9, "{q:?} -> {got:?}: {dp:.2e} m {dr:.2e}");
        // The knee forward: the same joints again.
        for (a, b) in got.iter().zip(&q) {
            prop_assert!((a - b).abs() < 1e-7, "{q:?} -> {got:?}");
        }
    }

    #[test]
    fn damped_least_squares_meets_what_the_closed_form_meets(
        q in proptest::array::uniform6(-0.4f64..0.4), knee in 0.2f64..1.5,
    ) {
        let q = [q[0], q[1], q[2], knee, q[4], q[5]];
        let target = fk(&L, Leg::Left, &q);
        let from = [q[0] + 0.05, q[1] - 0.05, q[2] + 0.05, knee - 0.1, q[4], q[5] + 0.05];
        let got = ik_dls(&L, Leg::Left, &target, &from).unwrap();
        let (dp, dr) = fk(&L, Leg::Left, &got).distance(&target);
        prop_assert!(dp < 1e-9 && dr < 1e-9);
        let closed = ik(&L, Leg::Left, &target).unwrap();
        for (a, b) in got.iter().zip(&closed) {
            prop_assert!((a - b).abs() < 1e-6, "{got:?} vs {closed:?}");
        }
    }

    #[test]
    fn any_target_gives_joints_or_an_error_never_nan(
        p in proptest::array::uniform3(-0.9f64..0.9), yaw in -3.0f64..3.0, roll in -1.0f64..1.0,
    ) {
        let target = pose(rz(yaw) * rx(roll), p);
        match ik(&L, Leg::Right, &target) {
            Ok(q) => {
                prop_assert!(q.iter().all(|v| v.is_finite()));
                let (dp, dr) = fk(&L, Leg::Right, &q).distance(&target);
                prop_assert!(dp < 1e-9 && dr < 1e-9);
            }
            Err(KinError::Unreachable(_)) | Err(KinError::Singular(_)) => {}
            Err(e) => prop_assert!(false, "{e}"),
        }
    }
}

#[test]
fn the_scripts_chain_is_off_with_the_pelvis_pitched() {
    // 0.1 rad of pelvis pitch: the swing sole lands 14.5 cm off; the general set G5 0.46 m.
    let mut theta = [0.0; 12];
    theta[3] = 0.1;
    let (a, b) = (scilab_chain(&L, &theta), exact_chain(&L, &theta));
    let err = close(&a[12], &b[12]);
    assert!((err - 0.1448).abs() < 0.001, "{err}");
    let g5 = GOLDEN[4].0;
    let worst = scilab_chain(&L, &g5)
        .iter()
        .zip(exact_chain(&L, &g5).iter())
        .map(|(p, q)| close(p, q))
        .fold(0.0, f64::max);
    assert!(worst > 0.4, "{worst}");
    eprintln!(
        "Stepping.sce's chain off by {err:.4} m at 0.1 rad of pelvis pitch, {worst:.3} m at G5"
    );
}

#[test]
fn a_singular_hip_falls_back_to_damped_least_squares() {
    // Hip roll at 90°: the closed form has no yaw/pitch split; the fallback meets the pose.
    let q = [0.2, std::f64::consts::FRAC_PI_2, -0.3, 0.8, -0.4, 0.1];
    let target = fk(&L, Leg::Left, &q);
    assert!(matches!(
        ik(&L, Leg::Left, &target),
        Err(KinError::Singular(_))
    ));
    let near = [0.1, 1.5, -0.2, 0.7, -0.3, 0.0];
    let got = solve(&L, Leg::Left, &target, &near).unwrap();
    let (dp, dr) = fk(&L, Leg::Left, &got).distance(&target);
    assert!(dp < 1e-9 && dr < 1e-9, "{dp:.2e} {dr:.2e}");
}

#[test]
fn unreachable_and_bad_targets_are_errors() {
    let far = at([0.0, 0.09, -1.0]);
    let e = ik(&L, Leg::Left, &far).unwrap_err();
    assert!(
        matches!(&e, KinError::Unreachable(m) if m.contains("knee reaches")),
        "{e}"
    );
    let nan = at([f64::NAN, 0.0, -0.6]);
    assert!(matches!(
        ik(&L, Leg::Left, &nan),
        Err(KinError::Unreachable(_))
    ));
    assert!(solve(&L, Leg::Left, &far, &[0.0; 6]).is_err());
}

/// The notes' table of section 2.4.6 (Stepping.sce re-run): ΔY, ΔX (cm); θ0 as the script
/// computes it, θ1, hip y, z_hip, hn1 (cm), θ8, θ9, θ10 (degrees).
const TABLE: [[f64; 10]; 12] = [
    [
        16.5, 0.0, 0.000, 0.000, 16.500, 72.500, 57.000, 0.000, 0.000, 0.000,
    ],
    [
        14.5, 0.0, 1.658, 0.000, 14.500, 72.688, 55.392, 12.471, -27.392, 14.920,
    ],
    [
        12.5, 0.0, 3.310, 0.000, 12.503, 72.818, 53.952, 17.178, -37.797, 20.618,
    ],
    [
        10.5, 0.0, 4.956, 0.000, 10.511, 72.890, 52.670, 20.480, -45.136, 24.656,
    ],
    [
        8.5, 0.0, 6.594, 0.000, 8.527, 72.905, 51.540, 23.004, -50.775, 27.771,
    ],
    [
        6.5, 0.0, 8.225, 0.000, 6.552, 72.863, 50.557, 24.994, -55.243, 30.250,
    ],
    [
        6.5, 0.0, 8.225, 0.000, 6.552, 72.863, 50.557, 24.994, -55.243, 30.250,
    ],
    [
        8.5, 3.0, 6.602, 3.017, 8.527, 72.826, 51.455, 26.336, -50.765, 24.429,
    ],
    [
        10.5, 6.0, 4.978, 6.042, 10.511, 72.575, 52.333, 27.007, -45.105, 18.098,
    ],
    [
        12.5, 9.0, 3.345, 9.085, 12.503, 72.106, 53.205, 26.755, -37.742, 10.987,
    ],
    [
        14.5, 12.0, 1.689, 12.153, 14.500, 71.414, 54.084, 24.952, -27.328, 2.375,
    ],
    [
        16.5, 15.0, 0.000, 15.258, 16.500, 70.491, 54.991, 15.258, 0.000, -15.258,
    ],
];

/// Eq 42 as printed, the angles in this module's signs.
const EQ_42: Faithful = Faithful {
    eq_42: true,
    scilab_signs: false,
};

#[test]
fn the_faithful_pattern_reproduces_the_section_2_4_6_table() {
    let faithful = Faithful {
        eq_42: true,
        scilab_signs: true,
    };
    for row in TABLE {
        let s = joint_pattern(&L, row[1] / 100.0, row[0] / 100.0, faithful).unwrap();
        let got = [
            s.theta[0].to_degrees(),
            s.theta[1].to_degrees(),
            s.hip_y * 100.0,
            s.z_hip * 100.0,
            s.hn1 * 100.0,
            s.theta[8].to_degrees(),
            s.theta[9].to_degrees(),
            s.theta[10].to_degrees(),
        ];
        for (k, (g, want)) in got.iter().zip(&row[2..]).enumerate() {
            assert!(
                (g - want).abs() <= 5e-4 + 1e-9,
                "ΔY {} ΔX {} column {k}: {g:.4} against {want}",
                row[0],
                row[1]
            );
        }
    }
}

#[test]
fn the_exact_pattern_puts_the_com_where_it_is_commanded() {
    for row in TABLE {
        let (dy, dx) = (row[0] / 100.0, row[1] / 100.0);
        let s = joint_pattern(&L, dx, dy, Faithful::default()).unwrap();
        // Eq 41 holds to round-off with the exact hip roll (not with the printed one).
        let script = s.script_theta();
        let res = eq_41_residual(&L, script[0], script[1], dy);
        assert!(res.abs() < 1e-9, "ΔY {dy}: residual {res:.2e} m");
        // Forward kinematics of the pattern: the pelvis centre at (ΔX, ΔY) from the support
        // ankle, upright.
        let (_, qr) = s.legs();
        let pelvis = fk(&L, Leg::Right, &qr).inverse();
        let p = pelvis.position();
        assert!((p[0] - dx).abs() < 1e-12 && (p[1] - dy).abs() < 1e-12);
        let (_, dr) = pelvis.distance(&at(p));
        assert!(dr < 1e-12);
        let printed = joint_pattern(&L, dx, dy, EQ_42).unwrap();
        let off = (printed.hip_y - dy).abs();
        assert!(off < 6e-4, "the printed form is off by {off} m");
    }
}

#[test]
fn scilabs_signs_are_a_flag_and_give_the_same_legs() {
    // Stepping.sce's signs: its swing knee bends negative (θ9 = π − γ, table 2.4.6), its
    // hip roll is eq 39's negated. In this module's convention a knee bends positive.
    let script = Faithful {
        eq_42: false,
        scilab_signs: true,
    };
    for row in TABLE.iter().filter(|r| r[9] != 0.0) {
        let (dy, dx) = (row[0] / 100.0, row[1] / 100.0);
        let a = joint_pattern(&L, dx, dy, script).unwrap();
        let b = joint_pattern(&L, dx, dy, Faithful::default()).unwrap();
        assert!(
            a.theta[9] < 0.0 && b.theta[9] > 0.0,
            "{:?} {:?}",
            a.theta,
            b.theta
        );
        for k in 0..12 {
            assert_eq!(
                a.theta[k] * stride_kinematics::archie::SCRIPT_TO_JOINT[k],
                b.theta[k]
            );
        }
        assert_eq!(a.legs(), b.legs());
        assert_eq!(a.script_theta(), b.script_theta());
    }
}

#[test]
fn k2_zero_is_an_error_as_printed_and_solved_exactly() {
    // k2 = a6/2 − d3 − ΔY = 0 at ΔY = 1.5 cm: eq 42 divides by zero.
    let dy = L.a6 / 2.0 - L.d3;
    let e = joint_pattern(&L, 0.0, dy, EQ_42).unwrap_err();
    assert!(matches!(e, KinError::Singular(_)), "{e}");
    let s = joint_pattern(&L, 0.0, dy, Faithful::default()).unwrap();
    assert!(s.theta.iter().all(|v| v.is_finite()));
    let script = s.script_theta();
    assert!(eq_41_residual(&L, script[0], script[1], dy).abs() < 1e-9);
    // Beyond the leg: an error, not NaN.
    assert!(matches!(
        joint_pattern(&L, 0.7, 0.1, Faithful::default()),
        Err(KinError::Unreachable(_))
    ));
}

#[test]
fn the_pelvis_centre_stands_at_most_0_674_m_high() {
    // Straight legs, the feet under the pelvis: 0.673 m; with the feet apart across and the
    // pelvis over either of them or between (where a walk takes it), no higher: the
    // thesis's z_c = 0.72 m is out of reach.
    let zero = max_pelvis_height(&L, 0.0, 0.0, 0.0, |_, _| true);
    assert!(zero < 0.674 && zero > 0.672, "{zero}");
    let heights: Vec<f64> = (1..=40)
        .map(|i| max_pelvis_height(&L, 0.0, i as f64 * 0.01, 0.0, |_, _| true))
        .collect();
    // Up to 0.18 m apart the pelvis stands as high over a foot as between them; wider,
    // lower and lower.
    assert!(heights.iter().all(|&h| h <= zero + 1e-9), "{heights:?}");
    assert!(
        heights.windows(2).all(|w| w[1] <= w[0] + 1e-9),
        "{heights:?}"
    );
    assert!((heights[19] - 0.6703).abs() < 1e-4, "{heights:?}");
    // A least knee bend lowers it further.
    let bent = max_pelvis_height(&L, 0.0, 0.2, 0.0, |_, q| q[3] >= 0.4);
    assert!(bent < heights[19] - 0.01, "{bent}");
}

#[test]
fn the_shipped_robot_file_loads_and_bad_ones_are_refused() {
    let cfg = shipped();
    assert_eq!(cfg.links, L);
    assert!((cfg.mass.total() - 20.0).abs() < 1e-9);
    assert_eq!(cfg.names(Leg::Left)[3], "left_knee");
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/robots/archie.toml");
    let text = std::fs::read_to_string(path).unwrap();
    let e = ArchieConfig::from_toml(&text.replacen("name = \"knee\"", "name = \"elbow\"", 1))
        .unwrap_err();
    assert!(e.to_string().contains("in that order"), "{e}");
    let e = ArchieConfig::from_toml(&text.replacen("a2 = 0.26", "a2 = -0.26", 1)).unwrap_err();
    assert!(e.to_string().contains("positive"), "{e}");
    // A joint beyond its limit.
    let e = cfg
        .check_q(Leg::Right, &[0.0, 0.0, 0.0, 2.5, 0.0, 0.0])
        .unwrap_err();
    assert!(
        matches!(&e, KinError::Limit { joint, .. } if joint == "right_knee"),
        "{e}"
    );
    let _ = (ry(0.0), archie::JOINTS);
}
