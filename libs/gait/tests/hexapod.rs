//! The hexapod's gaits: tripod and wave walks on flat ground, the sensing lift and foothold
//! plans, every row through the legs' kinematics within Table 3.2's limits and the servos'
//! speed, the static stability margin kept, and each servo's moving speed bringing it to its
//! goal within the control period.

use std::path::Path;

use stride_gait::hexapod::{HexConfig, HexGait, HexGaitConfig, HexRow, SPEED_UNIT};
use stride_gait::GaitError;
use stride_kinematics::hexapod::Hexapod;

fn gait() -> HexGait {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/robots/hexapod.toml");
    HexGait::new(Hexapod::load(&path).unwrap(), HexGaitConfig::default()).unwrap()
}

/// Every servo reaches its goal within the period at its moving speed, and one unit slower
/// would not.
fn arrive_in_time(rows: &[HexRow], period: f64) {
    for w in rows.windows(2) {
        for l in 0..6 {
            for j in 0..3 {
                let need = (w[1].servo_deg[l][j] - w[0].servo_deg[l][j])
                    .to_radians()
                    .abs();
                let units = w[1].moving_speed[l][j] as f64;
                assert!(
                    need <= units * SPEED_UNIT * period + 1e-12,
                    "{need} at {units}"
                );
                if units > 1.0 {
                    assert!(
                        need > (units - 1.0) * SPEED_UNIT * period,
                        "{need} at {units}"
                    );
                }
            }
        }
    }
}

#[test]
fn a_tripod_walk_on_flat_ground_keeps_its_margin_and_its_servos_in_time() {
    let g = gait();
    let start = g.standing([0.0, 0.0, 0.0, 0.0]);
    let (configs, trans) = g.tripod(&start, 0.3);
    assert!(trans.iter().all(|t| t.swing.len() == 3));
    let rows = g.rows(&configs, &trans, None).unwrap();
    let worst = rows.iter().map(|r| r.margin).fold(f64::INFINITY, f64::min);
    assert!(worst >= 0.02, "{worst}");
    arrive_in_time(&rows, g.cfg.period);
    // The body ends 0.3 m ahead, every foot home under it.
    let end = configs.last().unwrap();
    assert!((end.body[0] - 0.3).abs() < 1e-9);
    for n in 1..=6u8 {
        let home = stride_gait::hexapod::to_world(&end.body, g.home(n));
        let f = end.feet[n as usize - 1];
        assert!((f[0] - home[0]).hypot(f[1] - home[1]) < 1e-9, "leg {n}");
    }
    eprintln!(
        "tripod: {} rows, {:.1} s, smallest margin {worst:.3} m, fastest servo {:.2} rad/s",
        rows.len(),
        rows.last().unwrap().t,
        rows.iter()
            .flat_map(|r| r.speed.iter().flatten().copied())
            .fold(0.0, f64::max)
    );
}

#[test]
fn the_wave_gait_swings_one_leg_at_a_time_with_five_on_the_ground() {
    let g = gait();
    let start = g.standing([0.0, 0.0, 0.0, 0.0]);
    let (configs, trans) = g.wave(&start, 0.1);
    assert!(trans.iter().all(|t| t.swing.len() == 1));
    let order: Vec<u8> = trans.iter().take(6).map(|t| t.swing[0]).collect();
    assert_eq!(order, [5, 6, 1, 4, 3, 2]);
    let rows = g.rows(&configs, &trans, None).unwrap();
    let worst = rows.iter().map(|r| r.margin).fold(f64::INFINITY, f64::min);
    assert!(worst >= 0.02, "{worst}");
    arrive_in_time(&rows, g.cfg.period);
    // The same transitions as a foothold plan.
    assert_eq!(g.foothold_plan(&configs).unwrap().len(), trans.len());
}

#[test]
fn a_foothold_plan_moving_two_legs_at_once_is_refused() {
    let g = gait();
    let a = g.standing([0.0, 0.0, 0.0, 0.0]);
    let mut b: HexConfig = a;
    b.feet[0][0] += 0.03;
    b.feet[3][0] += 0.03;
    let e = g.foothold_plan(&[a, b]).unwrap_err();
    assert!(
        matches!(&e, GaitError::Plan(m) if m.contains("one at a time")),
        "{e}"
    );
}

#[test]
fn the_sensing_lift_raises_the_body_7_cm_with_every_foot_down() {
    let g = gait();
    let start = g.standing([0.0, 0.0, 0.0, 0.0]);
    let (configs, trans) = g.sensing_lift(&start);
    // The legs step in one at a time, the body rises with all six down, and back.
    let top = configs
        .iter()
        .max_by(|a, b| a.body[2].total_cmp(&b.body[2]))
        .unwrap();
    assert!((top.body[2] - start.body[2] - 0.07).abs() < 1e-12);
    let i = configs.iter().position(|c| c == top).unwrap();
    assert!(trans[i - 1].swing.is_empty() && trans[i].swing.is_empty());
    assert_eq!(configs.last().unwrap(), &start);
    let rows = g.rows(&configs, &trans, None).unwrap();
    assert!(rows.iter().all(|r| r.margin >= 0.02));
}

#[test]
fn a_walk_too_fast_for_the_servos_or_beyond_a_limit_is_refused_whole() {
    let mut g = gait();
    g.cfg.cycle = 0.1;
    let start = g.standing([0.0, 0.0, 0.0, 0.0]);
    let (configs, trans) = g.tripod(&start, 0.3);
    match g.rows(&configs, &trans, None) {
        Err(GaitError::Plan(m)) => assert!(m.contains("beyond the servos'"), "{m}"),
        other => panic!("{:?}", other.map(|r| r.len())),
    }
    let g = gait();
    let mut far = start;
    far.feet[0][0] += 0.12;
    let e = g
        .rows(
            &[start, far],
            &[stride_gait::hexapod::Transition {
                swing: vec![1],
                duration: 1.0,
            }],
            None,
        )
        .unwrap_err();
    assert!(
        matches!(&e, GaitError::Plan(m) if m.contains("leg 1")),
        "{e}"
    );
}
