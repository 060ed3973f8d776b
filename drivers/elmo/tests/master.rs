//! The Elmo master against fake drives on an in-memory bus: what it lets through, how it
//! plays, streams, stops and shuts down.

mod common;

use std::time::{Duration, Instant};

use common::{bump, joint, mean_speed, minjerk, rows, sine, Rig};
use stride_canbus::{CanBus, MemBus};
use stride_canopen::ds402::State as DriveState;
use stride_canopen::emcy::{ElmoEmcy, Emcy};
use stride_elmo::{Event, Master, MasterConfig, MasterError, Motion, Start};

fn emergencies(events: &[Event], code: u16) -> usize {
    events
        .iter()
        .filter(|e| matches!(e, Event::Emergency { emcy, .. } if emcy.code == code))
        .count()
}

#[test]
fn six_drives_walk_a_trajectory_longer_than_their_tables() {
    let mut r = Rig::new(6, Motion::Pvt);
    // 150 rows (1.5 s), more than the 64-row tables hold: refilled as the drives play.
    let t = bump(6, 0.3, 150);
    r.m.load(&t, r.now()).unwrap();
    r.play();
    for (i, (name, s)) in r.m.states().into_iter().enumerate() {
        let want = t.positions.last().unwrap()[i];
        assert!(
            (s.position - want).abs() < 1e-3,
            "{name}: {} vs {want}",
            s.position
        );
    }
    let events = r.m.take_events();
    // No following error, and the normal end of a motion is no emergency.
    assert!(events.is_empty(), "{events:?}");
    let shut = r.m.shutdown();
    assert!(shut.failed.is_empty() && shut.standstill, "{shut:?}");
    r.finish();
}

#[test]
fn row_limits_refuse_the_whole_trajectory() {
    let r = Rig::new(2, Motion::Pvt);
    let now = r.now();
    let mut m = r.m;
    let mut t = sine(2, 150);
    t.positions[5][1] = 2.0;
    let e = m.load(&t, now).unwrap_err();
    assert!(matches!(e, MasterError::Limit { row: 5, .. }), "{e}");
    let mut t = sine(2, 150);
    t.velocities[3][0] = 10.0;
    assert!(matches!(
        m.load(&t, now),
        Err(MasterError::Limit { row: 3, .. })
    ));
    let mut t = sine(2, 150);
    t.joints[1] = "nope".into();
    assert!(matches!(
        m.load(&t, now),
        Err(MasterError::BadTrajectory(_))
    ));
    assert_eq!(m.status().counters.refused, 3);
}

#[test]
fn zero_velocity_rows_1_ms_apart_are_refused() {
    // The finding: rows 0 and 0.5 rad 1 ms apart with zero velocities; the cubic between them
    // needs 750 rad/s against a 3 rad/s limit.
    let mut r = Rig::new(1, Motion::Pvt);
    let t = rows("j1", &[(0.0, 0.0, 0.0), (0.001, 0.5, 0.0)]);
    let e = r.m.load(&t, r.now()).unwrap_err();
    let MasterError::Limit { row, joint, what } = &e else {
        panic!("{e}")
    };
    assert_eq!((*row, joint.as_str()), (1, "j1"));
    assert!(what.starts_with("velocity 750.000 rad/s"), "{what}");
    r.run(Duration::from_millis(100));
    assert!(r.positions()[0].abs() < 1e-4, "it moved");
    r.finish();
}

#[test]
fn a_two_row_pt_table_is_refused() {
    // PT rows (no velocities): 0 to 0.45 rad in 1 ms, played as a cubic from rest to rest.
    let mut r = Rig::new(1, Motion::Pvt);
    let mut t = rows("j1", &[(0.0, 0.0, 0.0), (0.001, 0.45, 0.0)]);
    t.velocities.clear();
    let e = r.m.load(&t, r.now()).unwrap_err();
    assert!(e.to_string().contains("velocity 675.000 rad/s"), "{e}");
    // And in the drives' own PT mode, where points come every period.
    let mut pt = Rig::new(1, Motion::Pt { period_ms: 10 });
    let e = pt.m.load(&t, pt.now()).unwrap_err();
    assert!(e.to_string().contains("velocity"), "{e}");
    r.finish();
    pt.finish();
}

#[test]
fn a_first_row_away_from_where_the_joint_stands_is_refused() {
    let mut r = Rig::new(1, Motion::Pvt);
    let t = rows("j1", &[(0.0, 0.9, 0.0), (0.5, 0.9, 0.0)]);
    let e = r.m.load(&t, r.now()).unwrap_err();
    assert!(
        matches!(&e, MasterError::Limit { row: 0, what, .. } if what.contains("0.9000 rad from where the joint stands")),
        "{e}"
    );
    // The same move, joined from where the joint stands over the first 0.5 s, is played.
    let t = rows("j1", &[(0.5, 0.3, 0.0)]);
    r.m.load(&t, r.now()).unwrap();
    r.play();
    assert!((r.positions()[0] - 0.3).abs() < 1e-3, "{:?}", r.positions());
    r.finish();
}

#[test]
fn a_joint_named_twice_is_refused() {
    let mut r = Rig::new(1, Motion::Pvt);
    let mut t = rows("j1", &[(0.0, 0.0, 0.0), (0.1, 0.0, 0.0)]);
    t.joints = vec!["j1".into(), "j1".into()];
    t.positions = vec![vec![0.0, 2.2], vec![0.0, 2.2]];
    t.velocities = vec![vec![0.0, 0.0], vec![0.0, 0.0]];
    let e = r.m.load(&t, r.now()).unwrap_err();
    assert!(e.to_string().contains("j1 named twice"), "{e}");
    r.finish();
}

#[test]
fn the_acceleration_limit_is_checked_between_rows() {
    let mut r = Rig::new(1, Motion::Pvt);
    // 0.3 rad in 0.3 s, minimum jerk: a peak of 5.77 x 0.3 / 0.09 = 19 rad/s², under 60
    // even as the cubics between its rows play it.
    r.m.load(&minjerk(&["j1"], &[0.0], &[0.3], 0.3), r.now())
        .unwrap();
    r.play();
    // 0.1 rad in 0.09 s: the profile peaks at 71 rad/s² (at 2.1 rad/s), over the limit;
    // the cubics between its 10 ms rows peak higher still.
    let t = minjerk(&["j1"], &[0.3], &[0.4], 0.09);
    let e = r.m.load(&t, r.now()).unwrap_err();
    assert!(
        matches!(&e, MasterError::Limit { what, .. } if what.starts_with("acceleration") && what.ends_with("beyond 60")),
        "{e}"
    );
    r.finish();
}

#[test]
fn start_utime_is_honoured() {
    let mut r = Rig::new(2, Motion::Pvt);
    let wall = |r: &Rig, d: Duration| r.bus.utime() + d.as_micros() as i64;
    let mut t = minjerk(&["j1", "j2"], &[0.0, 0.0], &[0.2, -0.2], 0.3);
    t.start = Start::At(wall(&r, Duration::from_millis(600)));
    let a = r.m.load(&t, r.now()).unwrap();
    let until = a.start - Duration::from_millis(20);
    let before = r.record(until.saturating_duration_since(r.now()));
    assert!(
        before.iter().all(|(_, p)| p.iter().all(|x| x.abs() < 1e-4)),
        "moved before its start"
    );
    let after = r.record(Duration::from_millis(500));
    // It played at its time: halfway (0.1 rad) 150 ms after its start, seen at the first
    // state after (states come every 10 ms SYNC, the motor a step behind its rows); a start
    // ignored would be 600 ms early.
    let half = after.iter().find(|(_, p)| p[0] >= 0.1).expect("it moved").0;
    let due = a.start + Duration::from_millis(150);
    let off = if half > due { half - due } else { due - half };
    assert!(off < Duration::from_millis(20), "{off:?} off");
    assert!((r.positions()[0] - 0.2).abs() < 1e-3);
    // A start that has passed, or beyond the queue's bound, is refused.
    t.start = Start::At(wall(&r, Duration::ZERO) - 2_000_000);
    assert!(r
        .m
        .load(&t, r.now())
        .unwrap_err()
        .to_string()
        .contains("in the past"));
    t.start = Start::At(wall(&r, Duration::from_secs(30)));
    assert!(r
        .m
        .load(&t, r.now())
        .unwrap_err()
        .to_string()
        .contains("queue holds"));
    r.finish();
}

#[test]
fn a_new_trajectory_replaces_what_is_queued_from_its_start() {
    // The finding: 2000 tiny trajectories holding the joint, then a real move: it has to start
    // at once, not after 57 s of queued holds.
    let mut r = Rig::new(1, Motion::Pvt);
    for _ in 0..2000 {
        let hold = rows("j1", &[(0.0, 0.0, 0.0), (0.01, 0.0, 0.0), (0.02, 0.0, 0.0)]);
        r.m.load(&hold, r.now()).unwrap();
        r.m.pump(r.now()).unwrap();
    }
    let t0 = r.now();
    let a =
        r.m.load(&minjerk(&["j1"], &[0.0], &[0.3], 0.3), r.now())
            .unwrap();
    assert!(
        a.start < t0 + Duration::from_millis(150),
        "{:?}",
        a.start - t0
    );
    r.play();
    // No start of a motion cut to one row by the next hold (a drive refuses it, error 7).
    let events = r.m.take_events();
    assert!(events.is_empty(), "{events:?}");
    let took = r.now() - t0;
    assert!(took < Duration::from_secs(1), "{took:?}");
    assert!((r.positions()[0] - 0.3).abs() < 1e-3);
    let c = r.m.status().counters;
    assert_eq!((c.accepted, c.unreported_ends), (2001, 0), "{c:?}");
    assert!(c.replaced_rows > 1000, "{c:?}");
    r.finish();
}

#[test]
fn a_chunk_plays_to_its_end_then_stops_within_the_limits() {
    // The finding: a 1.0 s chunk ending at 0.4 rad/s was quick-stopped 0.51 s after it
    // arrived. It must play to its end, then decelerate at no more than the limit.
    let mut r = Rig::new(1, Motion::Pvt);
    let times: Vec<f64> = (0..=100).map(|k| k as f64 * 0.01).collect();
    let t = stride_elmo::Trajectory {
        joints: vec!["j1".into()],
        positions: times.iter().map(|&x| vec![0.2 * x * x]).collect(),
        velocities: times.iter().map(|&x| vec![0.4 * x]).collect(),
        times,
        start: Start::Now,
    };
    r.m.load(&t, r.now()).unwrap();
    let trace = r.record(Duration::from_millis(1500));
    // It reached the chunk's end (0.2 rad), and the stop after it is v²/2a = 0.16/120 more.
    let end = trace.last().unwrap().1[0];
    assert!((end - (0.2 + 0.16 / 120.0)).abs() < 2e-3, "ended at {end}");
    // No step in it: the speed between states never jumps by more than the acceleration
    // limit allows over a SYNC period (with a margin for the motor's lag). The speeds are
    // taken per SYNC, as the drives sample them, not from when the states happened to
    // arrive (a busy machine delivers two of them a millisecond apart).
    let v: Vec<f64> = trace.windows(2).map(|w| mean_speed(w, 0)).collect();
    let max_dv = v
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .fold(0.0, f64::max);
    assert!(max_dv < 60.0 * 0.02, "a speed step of {max_dv} rad/s");
    let ev = r.m.take_events();
    assert!(
        ev.iter()
            .any(|e| matches!(e, Event::StreamStopped { joints } if joints == &["j1"])),
        "{ev:?}"
    );
    assert!(!ev.iter().any(Event::is_fault), "{ev:?}");
    assert_eq!(r.m.status().counters.stream_stops, 1);
    r.finish();
}

#[test]
fn streamed_chunks_join_without_a_stop() {
    // A stream of 0.2 s chunks, each appended to the last and sent while the one before
    // plays: one continuous motion, and no stop between.
    let mut r = Rig::new(1, Motion::Pvt);
    let v = 0.5;
    for k in 0..6 {
        let t0 = k as f64 * 0.2;
        let mut c = rows(
            "j1",
            &(0..=20)
                .map(|i| {
                    let tt = t0 + i as f64 * 0.01;
                    // Ramp up in the first chunk, then cruise.
                    let (p, vel) = if k == 0 {
                        (v * tt * tt / 0.4, v * tt / 0.2)
                    } else {
                        (v * 0.1 + v * (tt - 0.2), v)
                    };
                    (i as f64 * 0.01, p, vel)
                })
                .collect::<Vec<_>>(),
        );
        c.start = if k == 0 { Start::Now } else { Start::Append };
        r.m.load(&c, r.now()).unwrap();
        r.run(Duration::from_millis(100));
    }
    let trace = r.record(Duration::from_millis(900));
    let ev = r.m.take_events();
    let stops: Vec<_> = ev
        .iter()
        .filter(|e| matches!(e, Event::StreamStopped { .. }))
        .collect();
    assert_eq!(stops.len(), 1, "only the end of the stream stops: {ev:?}");
    // Cruising at 0.5 rad/s through the joins: within 1 % over every 200 ms, and no 50 ms
    // stretch slows as a stop between chunks would.
    let speed = |w: &[(Instant, Vec<f64>)]| mean_speed(w, 0);
    let mean: Vec<f64> = trace.windows(21).take(30).map(speed).collect();
    assert!(mean.iter().all(|s| (s - v).abs() < 0.005), "{mean:?}");
    let short: Vec<f64> = trace.windows(6).take(45).map(speed).collect();
    assert!(short.iter().all(|s| (s - v).abs() < 0.01), "{short:?}");
    r.finish();
}

#[test]
fn after_a_quick_stop_the_next_valid_trajectory_moves() {
    let mut r = Rig::new(2, Motion::Pvt);
    r.m.load(
        &minjerk(&["j1", "j2"], &[0.0, 0.0], &[0.5, 0.5], 1.0),
        r.now(),
    )
    .unwrap();
    r.run(Duration::from_millis(300));
    assert!(r.m.quick_stop("test").is_empty());
    r.run(Duration::from_millis(300));
    assert_eq!(r.m.status().stopped.as_deref(), Some("test"));
    let here = r.positions();
    for (_, s) in r.m.states() {
        assert_eq!(
            DriveState::from_statusword(s.statusword),
            DriveState::QuickStopActive
        );
    }
    // The next valid trajectory, from where the joints stand, enables them again.
    let a =
        r.m.load(&minjerk(&["j1", "j2"], &here, &[0.1, 0.1], 0.5), r.now())
            .unwrap();
    assert!(a.rearmed);
    r.play();
    assert!(
        r.positions().iter().all(|p| (p - 0.1).abs() < 1e-3),
        "{:?}",
        r.positions()
    );
    assert_eq!(r.m.status().stopped, None);
    assert_eq!(r.m.status().counters.rearms, 1);
    r.finish();
}

#[test]
fn a_velocity_past_the_24_bit_field_is_refused_at_start() {
    // The finding: a 17-bit encoder at gear 120 and 6 rad/s; a 4.7 rad/s move panicked the
    // bridge. The configuration itself cannot be represented in PVT.
    let bus = MemBus::new(1_000_000);
    let j = stride_elmo::JointConfig {
        counts_per_rev: 131_072.0,
        gear_ratio: 120.0,
        max_velocity: 6.0,
        ..joint(1)
    };
    let e = Master::new(bus.node(), vec![j], MasterConfig::default()).unwrap_err();
    assert!(e.to_string().contains("24-bit PVT velocity"), "{e}");
}

#[test]
fn shutdown_decelerates_then_disables() {
    let mut r = Rig::new(3, Motion::Pvt);
    r.m.load(
        &minjerk(&["j1", "j2", "j3"], &[0.0; 3], &[1.0; 3], 1.0),
        r.now(),
    )
    .unwrap();
    // Mid-move (a 1 s minimum-jerk move is above 1 rad/s from 0.23 to 0.77 s): the drive's
    // reported velocity is read as it comes.
    let start = r.now();
    r.run(Duration::from_millis(300));
    while r.m.states()[0].1.velocity <= 1.0 && r.now() - start < Duration::from_millis(700) {
        r.run(Duration::from_millis(10));
    }
    let at = r.positions()[0];
    let v = r.m.states()[0].1.velocity;
    assert!(v > 1.0, "moving at {v}");
    let shut = r.m.shutdown();
    assert!(shut.failed.is_empty(), "{:?}", shut.failed);
    assert!(shut.standstill, "{shut:?}");
    // It decelerated (a stop of v²/2a, not a cut) before the torque went off.
    let moved = r.positions()[0] - at;
    assert!(moved > 0.5 * v * v / (2.0 * 60.0), "stopped in {moved} rad");
    assert!(
        shut.stopping >= Duration::from_secs_f64(v / 60.0),
        "{shut:?}"
    );
    for d in r.finish() {
        assert_eq!(d.state, DriveState::SwitchOnDisabled);
    }
}

#[test]
fn quick_stop_and_disable_go_on_past_a_silent_drive() {
    let mut r = Rig::with(
        3,
        MasterConfig {
            sdo_timeout: Duration::from_millis(50),
            ..Default::default()
        },
    );
    r.levers[1]
        .silent
        .store(true, std::sync::atomic::Ordering::Relaxed);
    let failed = r.m.quick_stop("test");
    assert_eq!(failed.len(), 1, "{failed:?}");
    assert!(failed[0].to_string().contains("j2 (node 2)"));
    let failed = r.m.disable();
    assert_eq!(failed.len(), 1, "{failed:?}");
    let drives = r.finish();
    for i in [0, 2] {
        assert_eq!(drives[i].state, DriveState::SwitchOnDisabled);
    }
}

#[test]
fn all_axes_of_a_trajectory_start_together() {
    let mut r = Rig::new(6, Motion::Pvt);
    // A sniffer on the bus: when each start (BG on RPDO2) came off the wire.
    let mut sniff = r.bus.node();
    r.m.load(&bump(6, 0.2, 60), r.now()).unwrap();
    r.play();
    let mut starts = Vec::new();
    while let Some((at, f)) = sniff.try_recv_stamped() {
        if (0x301..=0x306).contains(&f.raw_id()) && f.data()[..2] == *b"BG" {
            starts.push((f.raw_id(), at));
        }
    }
    assert_eq!(starts.len(), 6, "{starts:?}");
    // Back to back: six 8-byte frames take about 0.8 ms at 1 Mbit/s.
    let first = starts.iter().map(|s| s.1).min().unwrap();
    let last = starts.iter().map(|s| s.1).max().unwrap();
    assert!(
        last - first < Duration::from_millis(2),
        "{:?}",
        last - first
    );
    r.finish();
}

#[test]
fn drives_stop_on_their_own_when_the_master_dies() {
    let mut r = Rig::new(3, Motion::Pvt);
    r.m.load(
        &minjerk(&["j1", "j2", "j3"], &[0.0; 3], &[1.0; 3], 2.0),
        r.now(),
    )
    .unwrap();
    r.run(Duration::from_millis(600));
    // The master goes without a word (a SIGKILL): no quick stop, no disable.
    let Rig { bus, drives, m, .. } = r;
    std::mem::forget(m);
    let mut watch = bus.node();
    let t0 = bus.now();
    bus.advance_to(t0 + Duration::from_secs(1));
    let mut stops = Vec::new();
    while let Some((at, f)) = watch.try_recv_stamped() {
        if let Ok(e) = Emcy::decode(&f) {
            if e.code == Emcy::HEARTBEAT_ERROR {
                stops.push((e.node.get(), at - t0));
            }
        }
    }
    assert_eq!(stops.len(), 3, "{stops:?}");
    // Within the consumer time (100 ms) of the last heartbeat (before the master died),
    // judged on the drives' own step of a millisecond.
    assert!(
        stops.iter().all(|s| s.1 <= Duration::from_millis(101)),
        "{stops:?}"
    );
    bus.advance_to(bus.now() + Duration::from_millis(300));
    for p in common::probes(&drives) {
        assert_eq!(p.state, DriveState::QuickStopActive);
        assert!(p.velocity.abs() < 1.0, "{p:?}");
    }
}

#[test]
fn interpolated_position_mode_walks_a_trajectory() {
    let mut r = Rig::new(3, Motion::InterpolatedPosition { period_ms: 10 });
    let t = bump(3, 0.3, 150);
    r.m.load(&t, r.now()).unwrap();
    r.play();
    for (i, (_, s)) in r.m.states().into_iter().enumerate() {
        assert!(s.position.abs() < 1e-3, "joint {i}: {}", s.position);
    }
    assert!(!r.m.take_events().iter().any(Event::is_fault));
    r.finish();
}

#[test]
fn pt_mode_walks_a_move_resampled_at_its_period() {
    let mut r = Rig::new(6, Motion::Pt { period_ms: 8 });
    // 3 s out and back at 10 ms rows, played as 8 ms PT points (376 of them, more than
    // the 256-point rings hold): resampled, refilled, ended at rest.
    let t = bump(6, 0.4, 301);
    r.m.load(&t, r.now()).unwrap();
    let mut peak = [0f64; 6];
    let deadline = r.now() + Duration::from_secs(10);
    while !r.m.idle() && r.now() < deadline {
        r.run(Duration::from_millis(5));
        for (i, p) in r.positions().into_iter().enumerate() {
            peak[i] = peak[i].max(p);
        }
    }
    r.play();
    for (i, (name, s)) in r.m.states().into_iter().enumerate() {
        let top = 0.4 * (i + 1) as f64 / 6.0;
        assert!(s.position.abs() < 1e-3, "{name} ends at {}", s.position);
        assert!(
            (peak[i] - top).abs() < 0.02 * top,
            "{name} peaked at {}",
            peak[i]
        );
    }
    let ev = r.m.take_events();
    assert!(!ev.iter().any(Event::is_fault), "{ev:?}");
    r.m.shutdown();
    r.finish();
}

#[test]
fn a_pt_period_off_the_drive_sample_grid_is_refused_at_bring_up() {
    use stride_fakes::elmo::ElmoConfig;
    let bus = MemBus::modelled(1_000_000);
    // Position loop every 300 µs: 10 ms is not a whole number of them.
    let _drive = common::drives(&bus, 1, &[], |n| ElmoConfig {
        ts_us: 75,
        ..ElmoConfig::new(n)
    });
    let cfg = MasterConfig {
        motion: Motion::Pt { period_ms: 10 },
        ..Default::default()
    };
    let mut m = Master::new(bus.node(), vec![joint(1)], cfg).unwrap();
    let e = m.bring_up().unwrap_err();
    assert!(
        matches!(&e, MasterError::Setup { node: 1, what, .. } if what.contains("300 µs")),
        "{e}"
    );
}

#[test]
fn a_missing_drive_is_a_clear_error() {
    let bus = MemBus::modelled(1_000_000);
    let cfg = MasterConfig {
        sdo_timeout: Duration::from_millis(50),
        ..Default::default()
    };
    let mut m = Master::new(bus.node(), vec![joint(9)], cfg).unwrap();
    let e = m.bring_up().unwrap_err();
    assert!(matches!(e, MasterError::NoAnswer { node: 9, .. }), "{e}");
    assert!(e.to_string().contains("j9 (node 9)"));
}

#[test]
fn faults_become_events_and_recovery_brings_the_drives_back() {
    use std::sync::atomic::Ordering;
    let mut r = Rig::new(2, Motion::Pvt);
    r.run(Duration::from_millis(300));
    assert!(r.m.take_events().is_empty());
    // A drive in fault: its emergency is reported, its statusword shows it.
    r.levers[0].fault.store(true, Ordering::Relaxed);
    r.run(Duration::from_millis(100));
    let ev = r.m.take_events();
    assert!(
        ev.iter().any(|e| matches!(e, Event::Emergency { joint, text, .. } if joint == "j1" && text == "current")),
        "{ev:?}"
    );
    let s = r.m.states()[0].1;
    assert_eq!(DriveState::from_statusword(s.statusword), DriveState::Fault);
    // A drive that stops answering: its heartbeat is declared lost.
    r.levers[1].silent.store(true, Ordering::Relaxed);
    r.run(Duration::from_millis(500));
    let ev = r.m.take_events();
    assert!(
        ev.iter()
            .any(|e| matches!(e, Event::HeartbeatLost { joint } if joint == "j2")),
        "{ev:?}"
    );
    let e = r.m.read(1, 0x1000, 0).unwrap_err();
    assert!(matches!(e, MasterError::NoAnswer { node: 2, .. }), "{e}");
    // Bus-off: every call fails with it, nothing panics.
    r.bus.set_bus_off(true);
    assert!(matches!(
        r.m.pump(r.now()),
        Err(MasterError::Bus(stride_canbus::BusError::BusOff))
    ));
    assert!(r.m.recover().is_err());
    // The bus comes back (and the silent drive with it): recovery brings both drives up
    // again, the faulted one through a fault reset, and they move.
    r.bus.set_bus_off(false);
    r.levers[1].silent.store(false, Ordering::Relaxed);
    r.m.recover().unwrap();
    r.run(Duration::from_millis(50));
    r.m.load(&bump(2, 0.2, 60), r.now()).unwrap();
    r.play();
    for (name, s) in r.m.states() {
        assert_eq!(
            DriveState::from_statusword(s.statusword),
            DriveState::OperationEnabled,
            "{name}"
        );
        assert!(s.position.abs() < 1e-3, "{name}: {}", s.position);
    }
    // A drive that resets (here by NMT, as a power cycle would) is reported once.
    r.m.take_events();
    r.bus
        .node()
        .send(
            &stride_canopen::nmt::encode(stride_canopen::nmt::Command::ResetNode, 2),
            r.now(),
        )
        .unwrap();
    r.run(Duration::from_millis(100));
    let rebooted: Vec<Event> =
        r.m.take_events()
            .into_iter()
            .filter(|e| matches!(e, Event::Rebooted { .. }))
            .collect();
    assert_eq!(rebooted, [Event::Rebooted { joint: "j2".into() }]);
    r.m.recover().unwrap();
    let _ = ElmoEmcy::QueueLow { write: 0, read: 0 };
    emergencies(&[], 0);
    r.finish();
}

#[test]
fn a_move_sent_as_the_last_one_settles_replaces_its_tail_without_an_underflow() {
    for motion in [
        Motion::Pvt,
        Motion::Pt { period_ms: 10 },
        Motion::InterpolatedPosition { period_ms: 10 },
    ] {
        move_right_after_move(motion);
    }
}

/// What scripts/demo does: a move, and the next one as soon as the joints are within 1 mrad
/// of the target (the first is still in its last rows, its end not yet reported by the
/// drives when the next one goes in).
fn move_right_after_move(motion: Motion) {
    let mut r = Rig::new(3, motion);
    let names = ["j1", "j2", "j3"];
    let there = [-0.5, 1.0, -0.5];
    r.m.load(&minjerk(&names, &[0.0; 3], &there, 1.5), r.now())
        .unwrap();
    let deadline = r.now() + Duration::from_secs(5);
    while r
        .positions()
        .iter()
        .zip(&there)
        .any(|(p, q)| (p - q).abs() >= 1e-3)
    {
        assert!(r.now() < deadline, "the first move did not arrive");
        r.run(Duration::from_millis(1));
    }
    let here = r.positions();
    let back = minjerk(&names, &here, &[0.0; 3], 1.5);
    r.m.load(&back, r.now()).unwrap();
    r.play();
    let events = r.m.take_events();
    assert!(
        !events
            .iter()
            .any(|e| matches!(e, Event::Underflow { .. } | Event::StreamStopped { .. })),
        "{motion:?}: {events:?}"
    );
    for p in r.positions() {
        assert!(p.abs() < 1e-3, "{motion:?}: {:?}", r.positions());
    }
    r.finish();
}

#[test]
fn an_interpolated_move_after_another_starts_when_pumped_as_the_bridge_does() {
    // The bridge pumps every few milliseconds: the master ends a motion on its own clock
    // before the drive's report of the end comes, and the next start must still be a rising
    // edge of the controlword's bit 4.
    let mut r = Rig::new(1, Motion::InterpolatedPosition { period_ms: 10 });
    let pump = |r: &mut Rig, d: Duration| {
        let end = r.now() + d;
        while r.now() < end {
            r.m.pump(r.now()).unwrap();
            r.wait(Duration::from_millis(10));
        }
    };
    for to in [0.2, 0.0, 0.2] {
        let from = r.positions()[0];
        r.m.load(&minjerk(&["j1"], &[from], &[to], 0.3), r.now())
            .unwrap();
        pump(&mut r, Duration::from_millis(700));
        assert!(r.m.idle(), "the move to {to} did not end");
        assert!(
            (r.positions()[0] - to).abs() < 1e-3,
            "the move to {to} ended at {}",
            r.positions()[0]
        );
    }
    let events = r.m.take_events();
    assert!(
        !events.iter().any(|e| matches!(e, Event::Underflow { .. })),
        "{events:?}"
    );
    r.finish();
}

#[test]
fn a_move_with_rows_further_apart_than_the_lookahead_starts_on_time() {
    // Two rows 250 ms apart: the start waits for both in the table, so the second must not
    // wait for its lookahead.
    let mut r = Rig::new(1, Motion::Pvt);
    let a =
        r.m.load(&rows("j1", &[(0.0, 0.0, 0.0), (0.25, 0.1, 0.0)]), r.now())
            .unwrap();
    let moved = r
        .record(Duration::from_millis(400))
        .into_iter()
        .find(|(_, p)| p[0] > 1e-3)
        .map(|(t, _)| t)
        .expect("it moved");
    // From rest, the cubic passes 1 mrad 14 ms in; states come every 10 ms. A start that
    // waited for its second row's lookahead would be 150 ms late.
    let late = moved.saturating_duration_since(a.start);
    assert!(late < Duration::from_millis(30), "started {late:?} late");
    r.play();
    r.finish();
}

#[test]
fn an_underflow_is_counted_once() {
    // A master that stops pumping mid-motion lets the drive run out of rows: one underflow,
    // counted once however often the master pumps before its events are taken.
    // (The drives' watch on the master is longer than the stall, or they would stop first.)
    let mut r = Rig::with(
        1,
        MasterConfig {
            drive_watchdog: Duration::from_secs(2),
            ..Default::default()
        },
    );
    r.m.load(&minjerk(&["j1"], &[0.0], &[0.5], 1.0), r.now())
        .unwrap();
    r.run(Duration::from_millis(200));
    r.wait(Duration::from_millis(400));
    r.run(Duration::from_millis(200));
    let underflows =
        r.m.take_events()
            .iter()
            .filter(|e| matches!(e, Event::Underflow { .. }))
            .count();
    assert_eq!(underflows, 1);
    assert_eq!(r.m.status().counters.underflows, 1);
    r.finish();
}

#[test]
fn times_past_any_queue_are_refused_not_overflowed() {
    let mut r = Rig::new(1, Motion::Pvt);
    let far = rows("j1", &[(0.0, 0.0, 0.0), (1e13, 0.0, 0.0)]);
    let e = r.m.load(&far, r.now()).unwrap_err().to_string();
    assert!(e.contains("past any queue"), "{e}");
    let mut late = rows("j1", &[(0.0, 0.0, 0.0), (0.1, 0.0, 0.0)]);
    late.start = Start::At(i64::MAX);
    let e = r.m.load(&late, r.now()).unwrap_err().to_string();
    assert!(e.contains("the queue holds"), "{e}");
    assert_eq!(r.m.status().counters.refused, 2);
    r.finish();
}

#[test]
fn a_state_read_late_keeps_its_speed() {
    // The bridge's velocity was taken from when the states were read: a master descheduled
    // for 100 ms right after a SYNC read that SYNC's answer 100 ms late and reported a
    // tenth of the speed (a CI run saw 0.037 rad/s for a knee moving at 0.36). The drive
    // samples at the SYNC, so the speed is the change over the time between SYNCs.
    // (The drives' watchdog and the rows' lookahead are longer than the stall.)
    let mut r = Rig::with(
        1,
        MasterConfig {
            drive_watchdog: Duration::from_millis(500),
            lookahead: Duration::from_millis(300),
            ..Default::default()
        },
    );
    let v = 0.5;
    let ramp = 0.2;
    let rows_: Vec<(f64, f64, f64)> = (0..=200)
        .map(|i| {
            let t = i as f64 * 0.01;
            if t < ramp {
                (t, v * t * t / (2.0 * ramp), v * t / ramp)
            } else {
                (t, v * ramp / 2.0 + v * (t - ramp), v)
            }
        })
        .collect();
    r.m.load(&rows("j1", &rows_), r.now()).unwrap();
    r.run(Duration::from_millis(600));
    let mut seen = Vec::new();
    for _ in 0..5 {
        // A SYNC goes out (30 ms after the last, so that the drive's own reaction time is
        // small beside it), then the master sleeps past ten periods before it reads.
        r.wait(Duration::from_millis(30));
        r.m.pump(r.now()).unwrap();
        r.wait(Duration::from_millis(100));
        r.m.pump(r.now()).unwrap();
        seen.push(r.m.states()[0].1.velocity);
    }
    assert!(
        seen.iter().all(|s| (s - v).abs() < 0.25 * v),
        "cruising at {v} rad/s, read late: {seen:?}"
    );
    let ev = r.m.take_events();
    assert!(!ev.iter().any(Event::is_fault), "{ev:?}");
    r.finish();
}

#[test]
fn a_replacement_mid_motion_lands_on_the_clock_of_the_rows_it_joins() {
    // The finding: a gait replacing its stream mid-motion (rows on its own 10 ms grid, the
    // replacement 5 ms off it) was refused for an acceleration of 200 rad/s² that no row
    // had: its start was mapped from the wall clock through the clocks' difference read at
    // that moment, against the tick's start, so each trajectory landed shifted by the time
    // the bridge had spent in its tick. One motion cut in two must play as one.
    let mut r = Rig::new(1, Motion::Pvt);
    let wall = r.bus.utime();
    let w = std::f64::consts::TAU;
    let f = |x: f64| (0.3 * (1.0 - (w * x).cos()), 0.3 * w * (w * x).sin());
    let part = |from: f64, to: f64| {
        let n = ((to - from) / 0.01).round() as usize;
        let mut t = rows(
            "j1",
            &(0..=n)
                .map(|i| {
                    let x = from + i as f64 * 0.01;
                    let (p, v) = f(x);
                    (x - from, p, v)
                })
                .collect::<Vec<_>>(),
        );
        t.start = Start::At(wall + 300_000 + (from * 1e6).round() as i64);
        t
    };
    // The first read at once, the second by a tick that began 3 ms before it came to it:
    // the same motion from 5 ms off its grid, sent once more, joins the rows it replaces.
    r.m.load(&part(0.0, 1.0), r.now()).unwrap();
    r.run(Duration::from_millis(100));
    let stale = r.now() - Duration::from_millis(3);
    r.m.load(&part(0.505, 1.0), stale)
        .expect("the same motion joins the rows it replaces");
    r.play();
    assert!(r.positions()[0].abs() < 2e-3, "{:?}", r.positions());
    assert_eq!(r.m.status().counters.refused, 0);
    r.finish();
}

#[test]
fn a_motion_after_another_waits_for_the_drives_report_of_its_end() {
    // The finding: the master ended a motion on its own clock, counted from when it queued
    // the start, but the start had waited on the wire behind a table's worth of rows, so
    // the drives still played the old motion when the next one's rows and start came. The
    // rows ran on in the old motion and the start was refused (interpreter error 24, PV
    // while moving). On a 250 kbit/s bus six tables' rows hold a start back by tens of ms.
    let mut r = Rig::on_bus(6, MasterConfig::default(), 250_000);
    let names = ["j1", "j2", "j3", "j4", "j5", "j6"];
    for to in [0.3, 0.0, 0.3] {
        let from = r.positions();
        r.m.load(&minjerk(&names, &from, &[to; 6], 0.8), r.now())
            .unwrap();
        let deadline = r.now() + Duration::from_secs(5);
        while !r.m.idle() && r.now() < deadline {
            r.run(Duration::from_millis(1));
        }
        assert!(r.m.idle(), "the move to {to} did not end");
    }
    r.run(Duration::from_millis(300));
    let events = r.m.take_events();
    assert!(events.is_empty(), "{events:?}");
    // Every end was reported, and waited for.
    let c = r.m.status().counters;
    assert_eq!((c.underflows, c.unreported_ends), (0, 0), "{c:?}");
    for p in r.positions() {
        assert!((p - 0.3).abs() < 1e-3, "{:?}", r.positions());
    }
    r.finish();
}

#[test]
fn a_resting_master_syncs_less_often_and_its_drives_keep_their_watchdog() {
    let mut r = Rig::with(
        3,
        MasterConfig {
            idle_sync_period: Duration::from_millis(40),
            ..Default::default()
        },
    );
    // Settled: nothing queued, every joint still.
    r.run(Duration::from_millis(200));
    assert!(r.m.resting());
    let mut watch = r.bus.node();
    r.run(Duration::from_secs(1));
    let (mut syncs, mut heartbeats, mut watchdog) = (0, 0, 0);
    while let Ok(Some(f)) = watch.try_recv() {
        match f.raw_id() {
            0x080 => syncs += 1,
            0x77F => heartbeats += 1,
            _ => {}
        }
        if Emcy::decode(&f).is_ok_and(|e| e.code == Emcy::HEARTBEAT_ERROR) {
            watchdog += 1;
        }
    }
    // A SYNC every 40 ms (at most 26 a second, against 100 at the full rate), the master's
    // heartbeat with it, and no drive missed it (their watchdog is 100 ms).
    assert!((1..=26).contains(&syncs), "{syncs} SYNCs in 1 s at rest");
    assert!(
        heartbeats >= syncs,
        "{heartbeats} heartbeats, {syncs} SYNCs"
    );
    assert_eq!(watchdog, 0);
    assert!(r.m.take_events().is_empty());
    // A trajectory brings the full rate back at once and plays from the rested states.
    r.m.load(
        &minjerk(&["j1", "j2", "j3"], &[0.0; 3], &[0.4; 3], 0.5),
        r.now(),
    )
    .unwrap();
    assert!(!r.m.resting());
    r.play();
    assert!(r.positions().iter().all(|p| (p - 0.4).abs() < 1e-3));
    let events = r.m.take_events();
    assert!(events.is_empty(), "{events:?}");
    r.finish();
}

#[test]
fn a_lost_request_is_sent_again_not_a_failed_bring_up() {
    // Under load a gateway dropped an SDO request as stale, and the bridge gave up: "bring-up
    // failed: left_knee (node 4): no answer to a write of 0x1400:2". Requests lost on the
    // wire are sent again, up to the configured retries, and counted.
    let lose = |n: u32| {
        move |l: &[stride_fakes::elmo::Levers]| {
            l[1].lose_requests
                .store(n, std::sync::atomic::Ordering::Relaxed)
        }
    };
    let mut r = Rig::try_new(2, MasterConfig::default(), 1_000_000, lose(2)).unwrap();
    assert_eq!(r.m.status().counters.sdo_retries, 2);
    r.m.load(
        &minjerk(&["j1", "j2"], &[0.0, 0.0], &[0.1, 0.1], 0.3),
        r.now(),
    )
    .unwrap();
    r.play();
    assert!((r.positions()[1] - 0.1).abs() < 1e-3, "{:?}", r.positions());
    r.finish();
    // Without retries the same loss fails the bring-up, naming the drive.
    let cfg = MasterConfig {
        sdo_retries: 0,
        ..Default::default()
    };
    let e = Rig::try_new(2, cfg, 1_000_000, lose(1))
        .err()
        .expect("a failed bring-up");
    assert!(matches!(&e, MasterError::NoAnswer { node: 2, .. }), "{e}");
}
