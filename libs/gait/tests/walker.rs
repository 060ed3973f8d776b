//! The walk in step with a replanning planner (KAIST's protocol): plans taken when their
//! echoed step number matches, late ones dropped, in-place steps while no plan comes, a
//! stand when none comes for long or on a stop, bad plans refused.

mod common;

use common::{generator, standing, straight};
use std::collections::BTreeMap;
use stride_gait::pattern::{Kind, Pattern};

use stride_gait::timeline::{Footstep, Side, Step};
use stride_gait::walker::{Plan, Verdict, Walker, WalkerConfig};
use stride_gait::GaitError;

fn ok(_: &Footstep, _: &[f64; 4]) -> Result<(), String> {
    Ok(())
}

fn any(_: &Pattern, _: f64) -> Result<(), GaitError> {
    Ok(())
}

fn walker() -> Walker {
    let (l, r) = standing();
    Walker::new(
        generator(Kind::Preview),
        WalkerConfig::default(),
        0.0,
        l,
        r,
        0,
    )
    .unwrap()
}

/// A plan of `n` steps straight ahead from where the walker's feet will be when its steps
/// up to `echo` are done (a planner planning from the predicted stance), numbered from
/// `echo + 1`, the last `pad` of them in place.
fn plan_from(w: &Walker, t: f64, echo: i64, n: usize, pad: usize) -> Plan {
    let tl = &w.pattern().timeline;
    let mut feet = [tl.feet_start[0], tl.feet_start[1]];
    for s in &tl.steps {
        if s.footstep.number <= echo {
            feet[s.footstep.side.index()] = s.footstep.place;
        }
    }
    let _ = t;
    // The next foot to swing: the other than the last one moved.
    let last = tl
        .steps
        .iter()
        .rfind(|s| s.footstep.number <= echo)
        .map(|s| s.footstep.side);
    let mut side = last.map_or(Side::Left, Side::other);
    let mut steps = Vec::new();
    for i in 0..n {
        let k = side.index();
        let other = feet[1 - k];
        let place = if i + pad >= n {
            feet[k]
        } else {
            [other[0] + 0.15, feet[k][1], 0.0, 0.0]
        };
        steps.push(Footstep {
            number: echo + 1 + i as i64,
            side,
            place,
            swing_height: 0.0,
            duration: 0.0,
            padding: i + pad >= n,
        });
        feet[k] = place;
        side = side.other();
    }
    Plan {
        echo,
        steps,
        reaches_goal: false,
    }
}

#[test]
fn a_matching_plan_is_walked_and_the_robot_stands_at_its_goal() {
    let mut w = walker();
    assert_eq!(w.counter(0.0).number, 0);
    let p = plan_from(&w, 0.0, 0, 5, 2);
    assert_eq!(w.on_plan(&p, 0.0, &ok, &any), Verdict::Taken(1));
    // The counter counts the plan's steps, with the foot in the air and the phase.
    let tl = w.pattern().timeline.clone();
    assert_eq!(
        tl.steps.len(),
        3,
        "padding at the end is the goal: not walked"
    );
    let s = &tl.steps[1];
    let c = w.counter((s.lift + s.land) / 2.0);
    assert_eq!(c.number, 2);
    assert_eq!(c.swing, Some(s.footstep.side));
    assert!(c.phase > 0.5 && c.phase < 1.0, "{c:?}");
    // Nothing more comes: the robot stands where the plan ended, still.
    assert!(!w.tick(tl.steps[2].start + 0.1, &any));
    assert!(w.standing(tl.end));
    assert_eq!(w.counter(tl.end).number, 3);
    assert_eq!(w.counters().in_place, 0);
}

#[test]
fn a_late_planner_gets_in_place_steps_until_its_plan_matches() {
    let (l, r) = standing();
    let cfg = WalkerConfig {
        plan_timeout: 10.0,
        ..WalkerConfig::default()
    };
    let mut w = Walker::new(generator(Kind::Preview), cfg, 0.0, l, r, 0).unwrap();
    let p = plan_from(&w, 0.0, 0, 3, 0);
    assert!(matches!(w.on_plan(&p, 0.0, &ok, &any), Verdict::Taken(1)));
    // During step 2 a plan for step 1 comes: it is late (the robot is past step 1).
    let s2 = w.pattern().timeline.steps[1].clone();
    let late = plan_from(&w, s2.lift, 1, 3, 0);
    let v = w.on_plan(&late, s2.lift, &ok, &any);
    assert_eq!(v, Verdict::Late { echo: 1, now: 2 });
    assert_eq!(w.counters().late, 1);
    // The last taken step begins with nothing after it: the robot brings its feet side by
    // side and steps in place.
    let s3 = w.pattern().timeline.steps[2].clone();
    assert!(w.tick(s3.start, &any));
    assert!(w.counters().in_place > 0);
    let next = w
        .pattern()
        .timeline
        .steps
        .iter()
        .find(|s| s.footstep.padding)
        .cloned()
        .unwrap();
    assert_eq!(
        next.footstep.place, next.from,
        "an in-place step lands where it lifted"
    );
    // A plan that echoes the step under way then is taken and walked.
    let t = (next.lift + next.land) / 2.0;
    let now = w.counter(t).number;
    assert_eq!(now, next.footstep.number);
    let p = plan_from(&w, t, now, 3, 0);
    assert_eq!(w.on_plan(&p, t, &ok, &any), Verdict::Taken(now + 1));
    assert_eq!(w.counters().taken, 2);
}

#[test]
fn with_no_valid_plan_for_long_the_robot_brings_its_feet_together_and_stands() {
    let mut w = walker();
    let p = plan_from(&w, 0.0, 0, 3, 0);
    w.on_plan(&p, 0.0, &ok, &any);
    // In-place steps after the plan, then, past the timeout, feet together and stand.
    let mut t = 0.0;
    while t < 20.0 && !w.standing(t) {
        w.tick(t, &any);
        t += 0.05;
    }
    assert!(w.standing(t), "still walking at {t} s");
    let c = w.counters();
    assert!(c.in_place > 0 && c.stops == 1, "{c:?}");
    assert!(w.note().contains("no valid plan"), "{}", w.note());
    let feet = w.pattern().timeline.feet_end;
    assert!((feet[0][0] - feet[1][0]).abs() < 1e-9);
    assert!(
        ((feet[0][1] - feet[1][1]).abs() - 0.2).abs() < 1e-9,
        "{feet:?}"
    );
}

#[test]
fn a_bad_plan_is_refused_with_its_reason() {
    let mut w = walker();
    let mut p = plan_from(&w, 0.0, 0, 3, 0);
    p.steps[1].place[0] = f64::NAN;
    match w.on_plan(&p, 0.0, &ok, &any) {
        Verdict::Refused(why) => assert!(why.contains("not a finite footstep"), "{why}"),
        v => panic!("{v:?}"),
    }
    let mut p = plan_from(&w, 0.0, 0, 3, 0);
    p.steps[1].place[0] += 0.5;
    match w.on_plan(&p, 0.0, &ok, &any) {
        Verdict::Refused(why) => assert!(why.contains("step 2") && why.contains("along"), "{why}"),
        v => panic!("{v:?}"),
    }
    let p = plan_from(&w, 0.0, 0, 3, 0);
    let far = |f: &Footstep, _: &[f64; 4]| {
        if f.number == 3 {
            Err("no leg reaches it".to_string())
        } else {
            Ok(())
        }
    };
    match w.on_plan(&p, 0.0, &far, &any) {
        Verdict::Refused(why) => assert!(why.contains("step 3: no leg reaches it"), "{why}"),
        v => panic!("{v:?}"),
    }
    assert_eq!(w.counters().refused, 3);
    assert!(w.note().starts_with("plan refused"));
    // A plan the legs refuse as a whole is refused too.
    let legs =
        |_: &Pattern, _: f64| Err(GaitError::Limit("row 3, joint left_knee: too fast".into()));
    assert!(matches!(
        w.on_plan(&p, 0.0, &ok, &legs),
        Verdict::Refused(_)
    ));
    // Standing where it stood.
    let end = w.pattern().timeline.end;
    assert!(w.standing(end));
}

/// "One bad plan aborts it": a refused plan stood a walking robot at once, so a peer that
/// floods bad plans stopped every walk. Refused, a plan changes nothing: the walk goes on
/// with the last valid plan's steps, and in place, as if it never came.
#[test]
fn a_refused_plan_mid_walk_leaves_the_walk_as_it_was() {
    let mut w = walker();
    let p = plan_from(&w, 0.0, 0, 6, 0);
    assert_eq!(w.on_plan(&p, 0.0, &ok, &any), Verdict::Taken(1));
    let s1 = w.pattern().timeline.steps[0].clone();
    let t = (s1.lift + s1.land) / 2.0;
    let before = w.pattern().clone();
    let mut bad = plan_from(&w, t, 1, 3, 0);
    bad.steps[0].place[0] = f64::NAN;
    assert!(matches!(w.on_plan(&bad, t, &ok, &any), Verdict::Refused(_)));
    assert_eq!(w.pattern(), &before, "the pattern changed");
    // A valid plan for the step is still taken afterwards.
    let good = plan_from(&w, t, 1, 3, 0);
    assert_eq!(w.on_plan(&good, t, &ok, &any), Verdict::Taken(2));
}

#[test]
fn a_stop_command_stands_the_robot_and_plans_wait_for_a_resume() {
    let mut w = walker();
    let p = plan_from(&w, 0.0, 0, 6, 0);
    w.on_plan(&p, 0.0, &ok, &any);
    let s2 = w.pattern().timeline.steps[1].clone();
    w.stop(s2.start);
    assert!(w.is_stopped());
    let tl = w.pattern().timeline.clone();
    assert!(tl.steps.len() < 6, "the plan's later steps are dropped");
    let feet = tl.feet_end;
    assert!(
        ((feet[0][1] - feet[1][1]).abs() - 0.2).abs() < 1e-9,
        "{feet:?}"
    );
    let n = w.counter(tl.end).number;
    let again = plan_from(&w, tl.end, n, 3, 0);
    assert_eq!(w.on_plan(&again, tl.end, &ok, &any), Verdict::Stopped);
    w.resume();
    let v = w.on_plan(&again, tl.end, &ok, &any);
    assert!(matches!(v, Verdict::Taken(_)), "{v:?}");
    let _ = straight;
}

#[test]
fn a_lost_planner_stops_the_robots_progress_within_a_step() {
    // Plans come for steps 1 to 3 (echo 0, then 1, then 2), then no more (the planner or
    // its link lost): the robot walks the last plan's first step, stops with its second,
    // then in place.
    let (l, r) = standing();
    let cfg = WalkerConfig {
        plan_timeout: 30.0,
        ..WalkerConfig::default()
    };
    let mut w = Walker::new(generator(Kind::Preview), cfg, 0.0, l, r, 0).unwrap();
    let p = plan_from(&w, 0.0, 0, 4, 0);
    assert_eq!(w.on_plan(&p, 0.0, &ok, &any), Verdict::Taken(1));
    let mut t = 0.0;
    let mut echo = 0;
    // A plan at the middle of each of steps 1 and 2, echoing it.
    while echo < 2 {
        t += 0.01;
        w.tick(t, &any);
        let c = w.counter(t);
        if c.number == echo + 1 && c.phase > 0.5 {
            echo = c.number;
            let p = plan_from(&w, t, echo, 4, 0);
            assert_eq!(w.on_plan(&p, t, &ok, &any), Verdict::Taken(echo + 1));
        }
    }
    // No plan from here: walk on for a while. Each step as it started.
    let mut started = BTreeMap::new();
    let end = t + 15.0;
    while t < end {
        t += 0.01;
        w.tick(t, &any);
        note_started(&w, t, &mut started);
    }
    // The last plan (echo 2) gave steps 3 to 6: step 3 walked (the foremost foot ahead),
    // step 4 stops the walk, then the rear foot is brought beside it and only in place.
    let forward = forward_steps(&started);
    assert_eq!(forward.last(), Some(&4), "{forward:?}");
    let in_place = started.values().filter(|s| s.footstep.padding).count();
    assert!(in_place >= 3, "{started:?}");
    assert!(w.counters().in_place >= 3, "{:?}", w.counters());
}

#[test]
fn a_plan_to_the_goal_is_not_walked_to_its_end_when_no_newer_plan_comes() {
    // A plan that reaches the goal (its last steps padding), then nothing: the planner that
    // made it gone. Its first step is walked and its second stops the walk; then in place,
    // then the robot stands.
    let mut w = walker();
    let p = plan_from(&w, 0.0, 0, 5, 2);
    assert_eq!(w.on_plan(&p, 0.0, &ok, &any), Verdict::Taken(1));
    let mut t = 0.0;
    while t < 20.0 {
        w.tick(t, &any);
        t += 0.01;
    }
    assert!(w.standing(t));
    let moved: Vec<i64> = w
        .pattern()
        .timeline
        .steps
        .iter()
        .filter(|s| !s.footstep.padding && (s.footstep.place[0] - s.from[0]).abs() > 0.05)
        .map(|s| s.footstep.number)
        .collect();
    let feet = w.pattern().timeline.feet_end;
    assert!(
        feet[0][0].max(feet[1][0]) < 0.3 + 1e-9,
        "walked beyond the stopping step: {feet:?}, {moved:?}"
    );
    let c = w.counters();
    assert!(c.in_place > 0 && c.stops == 1, "{c:?}");
}

/// The 1 m closed-loop walk took 13 steps, not at most 12, once a lost planner's stop was
/// decided in time: at the goal the gait asks no more, and the walker stopped the last plan
/// as a lost planner's and stepped in place for the plan timeout before it stood. Told that
/// no newer plan will come, it walks a plan that ends the walk to its end and stands; a plan
/// with more steps than that is still stopped as a lost planner's.
#[test]
fn at_the_goal_the_last_plan_is_walked_to_its_end_and_the_robot_stands_without_stepping_in_place() {
    let run = |real: usize| {
        let mut w = walker();
        // `real` steps, then two in place: it reaches the goal.
        let p = plan_from(&w, 0.0, 0, real + 2, 2);
        assert_eq!(w.on_plan(&p, 0.0, &ok, &any), Verdict::Taken(1));
        let finished = w.finish_plan();
        let mut t = 0.0;
        while t < 20.0 {
            w.tick(t, &any);
            t += 0.01;
        }
        assert!(w.standing(t));
        let feet = w.pattern().timeline.feet_end;
        (finished, feet[0][0].max(feet[1][0]), w.counters())
    };
    // Two steps (0.15 m past the other foot each): walked, and it stands.
    let (finished, front, c) = run(2);
    assert!(finished);
    assert!((front - 0.3).abs() < 1e-9, "{front}");
    assert_eq!((c.in_place, c.stops), (0, 0), "{c:?}");
    // Three: the third is beyond what was checked with the plan; stopped with the second.
    let (finished, front, c) = run(3);
    assert!(!finished);
    assert!((front - 0.3).abs() < 1e-9, "{front}");
    assert!(c.in_place > 0 && c.stops == 1, "{c:?}");
}

#[test]
fn a_long_plans_pattern_is_made_of_what_can_play_and_what_its_preview_sees() {
    // Of a 30-step plan, one step is walked and the next stops the walk when no newer plan
    // comes: the pattern holds those and the steps the preview of the stop's touch-down
    // sees, and the legs are checked to that touch-down. Its samples up to there are those
    // of the whole plan's pattern.
    let until = std::cell::Cell::new(f64::NAN);
    let check = |_: &Pattern, u: f64| -> Result<(), GaitError> {
        until.set(u);
        Ok(())
    };
    let mut short = walker();
    let p = plan_from(&short, 0.0, 0, 30, 0);
    assert_eq!(short.on_plan(&p, 0.0, &ok, &check), Verdict::Taken(1));
    let (l, r) = standing();
    let all = WalkerConfig {
        steps_per_plan: 100,
        ..WalkerConfig::default()
    };
    let mut whole = Walker::new(generator(Kind::Preview), all, 0.0, l, r, 0).unwrap();
    assert_eq!(whole.on_plan(&p, 0.0, &ok, &any), Verdict::Taken(1));
    let (a, b) = (short.pattern(), whole.pattern());
    assert_eq!(b.timeline.steps.len(), 30);
    let n = a.timeline.steps.len();
    assert!(n > 2 && n < 12, "{n} steps made");
    let stop = &a.timeline.steps[1];
    assert_eq!(stop.footstep.number, 2);
    assert!((until.get() - stop.land).abs() < 1e-12, "{}", until.get());
    let end = a.index_at(stop.land);
    let mut worst: f64 = 0.0;
    for k in 0..=end {
        let (x, y) = (a.samples[k].com.com()[0], b.samples[k].com.com()[0]);
        worst = worst.max((x[0] - y[0]).abs()).max((x[1] - y[1]).abs());
        assert_eq!(a.samples[k].feet, b.samples[k].feet);
    }
    eprintln!("{n} steps made, the COM within {worst:e} m of the whole plan's");
    assert!(worst < 1e-6, "the COM differs by {worst} m");
}

/// D2 of the reliability findings: a step of 1e9 s was taken and its pattern allocated one
/// sample per 5 ms (3.2 TB, the gait aborted); 3000 s blocked the gait and stopped the drives.
/// A step's duration outside [t_min, t_max] (0: the timing rule's) is refused like any
/// per-step limit, before anything is made of it.
#[test]
fn a_step_duration_outside_the_timing_bounds_is_refused_before_any_pattern_is_made() {
    for bad in [1e9, 3000.0, 30.0, 2.5, 0.5, 1e-6, -1.0] {
        let mut w = walker();
        let mut p = plan_from(&w, 0.0, 0, 3, 0);
        p.steps[0].duration = bad;
        let legs_never_asked = |_: &Pattern, _: f64| -> Result<(), GaitError> {
            panic!("a pattern was made of a {bad} s step")
        };
        match w.on_plan(&p, 0.0, &ok, &legs_never_asked) {
            Verdict::Refused(why) => assert!(
                why.contains("step 1") && why.contains("duration") && why.contains("[1, 2]"),
                "{why}"
            ),
            v => panic!("{bad} s: {v:?}"),
        }
        assert!(!why_is_long(&w), "{}", w.note());
    }
    // Within the bounds, and 0 (the rule's), a plan is taken.
    for good in [0.0, 1.0, 1.5, 2.0] {
        let mut w = walker();
        let mut p = plan_from(&w, 0.0, 0, 3, 0);
        p.steps[0].duration = good;
        assert!(matches!(w.on_plan(&p, 0.0, &ok, &any), Verdict::Taken(1)));
    }
}

/// A refusal's figures are short, whatever the plan's numbers (a 1e300 m step was printed in
/// 300 digits).
fn why_is_long(w: &Walker) -> bool {
    w.note().len() > 200
}

#[test]
fn a_huge_step_is_refused_in_a_short_line() {
    let mut w = walker();
    let mut p = plan_from(&w, 0.0, 0, 3, 0);
    p.steps[0].place[0] = 1e300;
    match w.on_plan(&p, 0.0, &ok, &any) {
        Verdict::Refused(why) => assert!(why.contains("1.000e300 m along"), "{why}"),
        v => panic!("{v:?}"),
    }
    assert!(!why_is_long(&w), "{}", w.note());
}

/// D5 of the reliability findings: after a 3-step plan was walked, a refused plan stood the
/// robot on an empty timeline and the counter fell back to the last plan's echo (3 -> 0), so
/// the plans answering step 3 were dropped as late.
#[test]
fn the_step_counter_never_goes_back_after_a_refused_plan() {
    let mut w = walker();
    let p = plan_from(&w, 0.0, 0, 3, 0);
    assert_eq!(w.on_plan(&p, 0.0, &ok, &any), Verdict::Taken(1));
    // Walk it to its end: in place steps and then the stand after the timeout.
    let mut t = 0.0;
    let mut last = 0;
    while t < 30.0 && !w.standing(t) {
        w.tick(t, &any);
        let n = w.counter(t).number;
        assert!(n >= last, "{last} -> {n} at {t} s");
        last = n;
        t += 0.01;
    }
    assert!(last >= 3, "{last}");
    // A bad plan for the step counted: refused, and the counter stays.
    let mut bad = plan_from(&w, t, last, 3, 0);
    bad.steps[0].place[0] = f64::NAN;
    assert!(matches!(w.on_plan(&bad, t, &ok, &any), Verdict::Refused(_)));
    for k in 0..300 {
        let at = t + k as f64 * 0.01;
        assert_eq!(w.counter(at).number, last, "at {at} s");
    }
    // A good plan for that step is still taken.
    let end = w.pattern().timeline.end.max(t);
    assert_eq!(w.wanted_echo(end), Some(last));
    let good = plan_from(&w, end, last, 3, 0);
    assert_eq!(w.on_plan(&good, end, &ok, &any), Verdict::Taken(last + 1));
}

#[test]
fn the_controller_makes_only_the_newest_of_the_plans_for_its_step_into_a_pattern() {
    use stride_gait::controller::Controller;
    let w = walker();
    let legs = common::archie();
    let joints = legs.joints_until(w.pattern(), f64::INFINITY).unwrap();
    let mut c = Controller {
        legs,
        walker: w,
        joints,
        switch_ahead: WalkerConfig::default().switch_ahead,
        decide_within: 0.2,
    };
    let t = 0.0;
    let echo = c.walker.wanted_echo(c.switch_time(t, None)).unwrap();
    let older = plan_from(&c.walker, t, echo, 4, 0);
    let newer = plan_from(&c.walker, t, echo, 6, 0);
    let intake = c.take(&[older, newer], t, None);
    assert_eq!((intake.taken, intake.dropped), (1, 1), "{intake:?}");
    assert_eq!(intake.taken_echo, Some((echo, 1)));
    assert!(intake.refusals.is_empty(), "{:?}", intake.refusals);
    // The pattern played is the newer plan's (six steps), its joints made.
    let adopt = intake.adopt.expect("the new pattern's joints");
    assert!(!adopt.plan.times.is_empty());
    let last = c
        .walker
        .pattern()
        .timeline
        .steps
        .iter()
        .map(|s| s.footstep.number)
        .max();
    assert_eq!(last, Some(echo + 6));
}

/// The last step a lost planner's walk puts forward, with the walker decided on at the end of
/// what a gait has streamed, which moves `chunk` s at a time (`tick_ahead`: the walker is
/// told how far its next decision may be), plans coming for the step under way at the switch
/// until step `last_echo`, none after.
fn last_forward_step(chunk: f64, last_echo: i64, ahead: Option<f64>) -> i64 {
    let (l, r) = standing();
    let (lookahead, switch) = (0.3, 0.35);
    let cfg = WalkerConfig {
        plan_timeout: 30.0,
        switch_ahead: switch,
        ..WalkerConfig::default()
    };
    let mut w = Walker::new(generator(Kind::Preview), cfg, 0.0, l, r, 0).unwrap();
    let p = plan_from(&w, 0.0, 0, 8, 0);
    assert_eq!(w.on_plan(&p, 0.0, &ok, &any), Verdict::Taken(1));
    let (mut t, mut echo) = (0.0, 0);
    let mut started = BTreeMap::new();
    while t < 20.0 {
        t += 0.01;
        let stream_end = ((t + lookahead) / chunk).ceil() * chunk;
        let at = stream_end - switch + 1e-7;
        if let Some(e) = w.wanted_echo(at).filter(|e| *e > echo && *e <= last_echo) {
            echo = e;
            let p = plan_from(&w, at, e, 8, 0);
            assert!(matches!(w.on_plan(&p, at, &ok, &any), Verdict::Taken(_)));
        }
        match ahead {
            Some(a) => w.tick_ahead(at, a, &any),
            None => w.tick(at, &any),
        };
        note_started(&w, t, &mut started);
    }
    forward_steps(&started).last().copied().unwrap_or(0)
}

/// Notes each step of the walker's pattern as it stood when the step started.
fn note_started(w: &Walker, t: f64, started: &mut BTreeMap<i64, Step>) {
    for s in &w.pattern().timeline.steps {
        if s.start <= t {
            started
                .entry(s.footstep.number)
                .or_insert_with(|| s.clone());
        }
    }
}

/// The steps that put a foot ahead of both feet, in order.
fn forward_steps(started: &BTreeMap<i64, Step>) -> Vec<i64> {
    let mut front = f64::NEG_INFINITY;
    let mut forward = vec![];
    for s in started.values() {
        if s.footstep.place[0] > front + 1e-9 && s.footstep.number > 0 {
            forward.push(s.footstep.number);
        }
        front = front.max(s.footstep.place[0]).max(s.from[0]);
    }
    forward
}

/// A lost planner on the split profile: the robot put a plan's step forward once more than
/// the walker's rule when the gait's stream had moved past the 0.1 s before the stopping
/// step's start in one chunk (0.2 s): the decision to stop was never taken for that step,
/// and the robot walked the next one too (five touch-downs forward after the last plan, not
/// four). Told how far its next decision may be, the walker stops with the same step
/// however the stream moves.
#[test]
fn a_lost_planner_stops_the_walk_at_the_same_step_whatever_chunks_the_stream_moves_in() {
    // The last plan echoes step 5: step 6 walked, step 7 stops the walk.
    for chunk in [0.01, 0.1, 0.2, 0.25, 0.3] {
        assert_eq!(
            last_forward_step(chunk, 5, Some(chunk)),
            7,
            "chunks of {chunk} s"
        );
    }
    // Without the chunk, a stream that moves further than the decision window skips it.
    let skipped = [0.2, 0.25, 0.3]
        .iter()
        .any(|&c| last_forward_step(c, 5, None) != 7);
    assert!(skipped, "the defect this guards is not reproduced");
}
