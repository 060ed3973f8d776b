//! Plans stop coming mid-walk at the walker's longest steps (the planner or its link lost):
//! the walker walks the last plan's next step, stops with the one after, steps in place
//! and stands, and every pattern it switches to on the way becomes joint rows within the
//! joints' limits (as stride-gait sends them), joined to the rows before; plans that come
//! again walk on from the stand. Guards the stop that the legs could not make
//! (in place from a long stride, lifted higher than a step: the rear ankle past its limit),
//! which left the gait sending the old plan's rows.

mod common;

use std::cell::RefCell;

use stride_gait::pattern::Pattern;
use stride_gait::timeline::Footstep;
use stride_gait::walker::{Plan, Verdict};
use stride_gait::GaitError;

#[test]
fn plans_that_stop_coming_mid_walk_end_in_a_stand_the_legs_can_make() {
    let common::Archie {
        cfg,
        legs,
        walker: mut w,
    } = common::archie();
    // The walker's longest steps.
    let stride = cfg.walker.max_length;
    let step = |n: i64| common::straight(n, stride);
    let cache = RefCell::new(None);
    // The legs checked as far as the pattern can play, as the gait does.
    let check = |p: &Pattern, until: f64| -> Result<(), GaitError> {
        *cache.borrow_mut() = Some(legs.joints_until(p, until)?.plan);
        Ok(())
    };
    let reach = |_: &Footstep, _: &[f64; 4]| Ok(());
    let plan = |echo: i64| Plan {
        echo,
        steps: (echo + 1..=echo + 8).map(step).collect(),
        reaches_goal: false,
    };
    assert!(matches!(
        w.on_plan(&plan(0), 0.0, &reach, &check),
        Verdict::Taken(1)
    ));
    let mut rows = cache.borrow_mut().take().unwrap();
    let mut rows_start = w.pattern().timeline.start;
    // Each new pattern's first row against the rows it replaces at its start, rad: the
    // largest jump of any joint.
    let mut worst_join = 0.0f64;
    let mut join = |rows: &mut stride_gait::archie::JointPlan,
                    rows_start: &mut f64,
                    new: stride_gait::archie::JointPlan,
                    start: f64| {
        let i = rows
            .times
            .partition_point(|&x| *rows_start + x < start - 1e-9)
            .min(rows.times.len() - 1);
        for (a, b) in [(&rows.left, &new.left), (&rows.right, &new.right)] {
            for (p, q) in a.positions[i].iter().zip(&b.positions[0]) {
                worst_join = worst_join.max((p - q).abs());
            }
        }
        *rows = new;
        *rows_start = start;
    };
    let dt = 0.01;
    let mut echo = 0;
    let mut t = 0.0;
    let mut changes = Vec::new();
    let mut stopped = None;
    while t < 40.0 {
        t += dt;
        if t > 30.0 && t < 30.0 + dt {
            assert!(w.standing(t), "still walking after 30 s");
            stopped = Some((w.pattern().timeline.feet_end, w.counters()));
            echo = w.counter(t).number - 1;
        }
        let c = w.counter(t);
        // Plans for steps 1 to 4; none from 4 s to 30 s (lost); then again.
        let resumed = t > 30.0;
        if c.number > echo && (c.number <= 4 || resumed) {
            echo = c.number;
            let p = if resumed {
                // From where the feet stand once the step under way lands.
                let tl = &w.pattern().timeline;
                let mut feet = tl.feet_start;
                for s in tl.steps.iter().filter(|s| s.footstep.number <= echo) {
                    feet[s.footstep.side.index()] = s.footstep.place;
                }
                let x = feet[0][0].max(feet[1][0]);
                let mut p = plan(echo);
                for (k, f) in p.steps.iter_mut().enumerate() {
                    f.place[0] = x + stride * (k + 1) as f64;
                }
                p
            } else {
                plan(echo)
            };
            let v = w.on_plan(&p, t, &reach, &check);
            assert!(matches!(v, Verdict::Taken(_)), "at {t:.2} s: {v:?}");
            let new = cache.borrow_mut().take().unwrap();
            join(&mut rows, &mut rows_start, new, w.pattern().timeline.start);
        }
        if w.tick(t, &check) {
            let made = cache.borrow_mut().take();
            let joints = match made {
                Some(j) => Ok(j),
                None => legs.joints(w.pattern()),
            };
            if let Ok(j) = &joints {
                join(
                    &mut rows,
                    &mut rows_start,
                    j.clone(),
                    w.pattern().timeline.start,
                );
            }
            changes.push((t, w.note().to_string(), joints.map(|_| ())));
        }
    }
    for (t, note, joints) in &changes {
        assert!(joints.is_ok(), "at {t:.2} s, {note}: {joints:?}");
    }
    assert!(
        worst_join < 0.02,
        "a pattern joins its rows {worst_join} rad away"
    );
    // The last plan (echo 4) was walked one step (step 5), and its step 6 (or less of it,
    // when the legs need) stopped the walk; then the feet side by side.
    let (feet, counters) = stopped.unwrap();
    let front = feet[0][0].max(feet[1][0]);
    assert!(
        front > 5.0 * stride && front <= 6.0 * stride + 1e-9,
        "the foremost foot at {front}: {feet:?}"
    );
    assert!((feet[0][0] - feet[1][0]).abs() < 1e-9, "{feet:?}");
    assert!(counters.in_place > 0, "{counters:?}");
    // Plans again: the walk goes on from the stand.
    let end = w.pattern().timeline.feet_end;
    assert!(end[0][0].min(end[1][0]) > front + stride, "{end:?}");
}
