//! A walk replanned at every step, as stride-gait does with a replanning planner: each new
//! plan is taken where the rows already sent end, and the new pattern's first joint row joins
//! the old rows within the joints' limits. Guards three defects the closed-loop walk found:
//! a swing under way was planned again from mid-air (lifted anew by the clearance just before
//! touch-down), its lift-off place was lost (the foot jumped to its target), and the pelvis's
//! offset was extrapolated from the standing one at a pattern that starts mid-walk (a first
//! guess out of the legs' reach).

mod common;

use std::cell::RefCell;

use stride_gait::pattern::Pattern;
use stride_gait::timeline::Footstep;
use stride_gait::walker::{Plan, Verdict};
use stride_gait::GaitError;

#[test]
fn a_walk_replanned_at_every_step_joins_its_rows_within_the_joints_limits() {
    let common::Archie {
        cfg,
        legs,
        walker: mut w,
    } = common::archie();
    let robot = legs.robot.clone();
    let step = |n: i64| common::straight(n, 0.2);
    let cache = RefCell::new(None);
    // The legs checked as far as the pattern can play, as the gait does.
    let check = |p: &Pattern, until: f64| -> Result<(), GaitError> {
        *cache.borrow_mut() = Some(legs.joints_until(p, until)?.plan);
        Ok(())
    };
    let reach = |_: &Footstep, _: &[f64; 4]| Ok(());
    let first = Plan {
        echo: 0,
        steps: (1..=4).map(step).collect(),
        reaches_goal: false,
    };
    assert!(matches!(
        w.on_plan(&first, 0.0, &reach, &check),
        Verdict::Taken(1)
    ));
    let mut old = cache.borrow_mut().take().unwrap();
    let mut old_start = w.pattern().timeline.start;
    let (mut taken, mut worst) = (0, 0.0f64);
    // Decisions at times all over the steps (double support, lift-off, mid-swing, just before
    // touch-down), each on a row of the current pattern as the gait makes them.
    let mut t: f64 = 0.5;
    while t < 12.0 {
        let now = old_start + ((t - old_start) / 0.01).ceil() * 0.01 - cfg.walker.switch_ahead;
        let c = w.counter(now + cfg.walker.switch_ahead);
        let plan = Plan {
            echo: c.number,
            steps: (c.number + 1..=c.number + 4).map(step).collect(),
            reaches_goal: false,
        };
        match w.on_plan(&plan, now + 1e-7, &reach, &check) {
            Verdict::Taken(_) => {
                let new = cache.borrow_mut().take().unwrap();
                let start = w.pattern().timeline.start;
                // The old rows up to the new start, then the new rows: the cubic between the
                // last old row and the new first one.
                let i = old.times.partition_point(|&x| old_start + x < start - 1e-9);
                assert!(i > 0);
                let dt = start - (old_start + old.times[i - 1]);
                for (a, b) in [(&old.left, &new.left), (&old.right, &new.right)] {
                    for (j, spec) in robot.joint.iter().enumerate() {
                        let (p0, v0) = (a.positions[i - 1][j], a.velocities[i - 1][j]);
                        let (p1, v1) = (b.positions[0][j], b.velocities[0][j]);
                        let a0 = (6.0 * (p1 - p0) - (4.0 * v0 + 2.0 * v1) * dt) / (dt * dt);
                        let a1 = (-6.0 * (p1 - p0) + (2.0 * v0 + 4.0 * v1) * dt) / (dt * dt);
                        let acc = a0.abs().max(a1.abs());
                        worst = worst.max(acc / spec.max_acceleration);
                        assert!(
                            acc <= spec.max_acceleration,
                            "replanned at {t:.2} s: {} joins at {acc:.1} rad/s² (at most {})",
                            spec.name,
                            spec.max_acceleration
                        );
                    }
                }
                old = new;
                old_start = start;
                taken += 1;
            }
            Verdict::Late { .. } => {}
            other => panic!("replanned at {t:.2} s: {other:?}"),
        }
        t += 0.37;
    }
    assert!(taken >= 15, "{taken} plans taken");
    assert!(worst < 1.0, "{worst}");
}
