//! A host session against the fake Due board (the firmware's own sketch, run on the host) on a
//! pty.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use stride_fakes::due::{DueConfig, DueLevers, FakeDue};
use stride_link::{fault, nack, JointCommand, Message, Mode};
use stride_link_host::Session;
use stride_serial::{pty_pair, Paced, Port};

type Line = Port<serialport::TTYPort>;

fn rig() -> (
    Session<Line>,
    DueLevers,
    Arc<AtomicBool>,
    std::thread::JoinHandle<FakeDue>,
) {
    let (host, dev) = pty_pair(115_200).unwrap();
    let levers = DueLevers::default();
    let stop = Arc::new(AtomicBool::new(false));
    let board =
        FakeDue::new(DueConfig::default()).spawn(Paced::new(dev), levers.clone(), stop.clone());
    (Session::new(host), levers, stop, board)
}

/// Collects the board's messages for `d`, sending heartbeats every 20 ms.
fn listen(s: &mut Session<Line>, d: Duration, heartbeat: bool) -> Vec<Message> {
    let end = Instant::now() + d;
    let mut out = Vec::new();
    let mut next_hb = Instant::now();
    while Instant::now() < end {
        if heartbeat && Instant::now() >= next_hb {
            s.send(&Message::Heartbeat(0)).unwrap();
            next_hb += Duration::from_millis(20);
        }
        out.extend(
            s.receive((Instant::now() + Duration::from_millis(5)).min(end))
                .unwrap(),
        );
    }
    out
}

fn last_state(msgs: &[Message]) -> Option<&Message> {
    msgs.iter()
        .rev()
        .find(|m| matches!(m, Message::State { .. }))
}

#[test]
fn handshake_commands_state_and_nacks() {
    let (mut s, _levers, stop, board) = rig();
    // Before the handshake a command is refused.
    let cmd = Message::Command(vec![JointCommand {
        joint: 0,
        mode: Mode::Duty,
        value: 2000,
    }]);
    let seq = s.send(&cmd).unwrap();
    let msgs = listen(&mut s, Duration::from_millis(100), false);
    assert!(
        msgs.contains(&Message::Nack {
            seq,
            reason: nack::NO_HANDSHAKE
        }),
        "{msgs:?}"
    );
    let b = s
        .handshake(Duration::from_secs(2), Duration::from_millis(200))
        .unwrap();
    assert_eq!(
        (b.joints, b.watchdog_ms, b.firmware.as_str()),
        (6, 100, "stride-due 1.0")
    );
    // Duty on joint 0: the state acknowledges the command and reports the driver's current
    // (300 mA idle and 6 A per unit of duty in the plant); the joint moves (the firmware does
    // not read positions yet: the plant says so).
    let seq = s.send(&cmd).unwrap();
    let msgs = listen(&mut s, Duration::from_millis(300), true);
    let Some(Message::State { ack, joints, .. }) = last_state(&msgs) else {
        panic!("no state: {msgs:?}");
    };
    assert_eq!(*ack, seq);
    assert_eq!(joints[0].duty, 2000);
    assert!(
        (1400..=1600).contains(&joints[0].current),
        "{:?}",
        joints[0]
    );
    assert!(msgs.iter().any(|m| matches!(m, Message::Imu { .. })));
    // Beyond the board's max duty: refused, nothing applied.
    let too_much = Message::Command(vec![JointCommand {
        joint: 1,
        mode: Mode::Duty,
        value: 9500,
    }]);
    let seq = s.send(&too_much).unwrap();
    let msgs = listen(&mut s, Duration::from_millis(60), true);
    assert!(
        msgs.contains(&Message::Nack {
            seq,
            reason: nack::RANGE
        }),
        "{msgs:?}"
    );
    stop.store(true, Ordering::Relaxed);
    let board = board.join().unwrap();
    assert_eq!(board.duty(1), 0);
    assert!(board.position(0) > 0.1, "{}", board.position(0));
}

#[test]
fn the_board_brakes_when_the_host_stalls_and_on_over_current() {
    let (mut s, levers, stop, board) = rig();
    s.handshake(Duration::from_secs(2), Duration::from_millis(200))
        .unwrap();
    s.send(&Message::Command(vec![
        JointCommand {
            joint: 2,
            mode: Mode::Duty,
            value: 3000,
        },
        JointCommand {
            joint: 3,
            mode: Mode::Duty,
            value: 3000,
        },
    ]))
    .unwrap();
    listen(&mut s, Duration::from_millis(50), true);
    // The host stalls: no commands, no heartbeats. The watchdog brakes everything.
    let msgs = listen(&mut s, Duration::from_millis(250), false);
    assert!(
        msgs.contains(&Message::Fault {
            joint: 0xff,
            bits: fault::WATCHDOG,
            detail: 100
        }),
        "{msgs:?}"
    );
    let Some(Message::State { joints, .. }) = last_state(&msgs) else {
        panic!()
    };
    assert!(
        joints.iter().all(|j| j.flags & 1 == 1 && j.duty == 0),
        "{joints:?}"
    );
    // A new command wakes it; then joint 3 jams and trips its over-current.
    s.send(&Message::Command(vec![JointCommand {
        joint: 3,
        mode: Mode::Duty,
        value: 3000,
    }]))
    .unwrap();
    listen(&mut s, Duration::from_millis(50), true);
    levers.extra_current(3, 7000.0);
    let msgs = listen(&mut s, Duration::from_millis(100), true);
    assert!(
        msgs.iter().any(|m| matches!(
            m,
            Message::Fault {
                joint: 3,
                bits: fault::OVER_CURRENT,
                ..
            }
        )),
        "{msgs:?}"
    );
    stop.store(true, Ordering::Relaxed);
    let board = board.join().unwrap();
    assert!(board.braked(3));
}

#[test]
fn the_board_master_brakes_a_joint_over_the_hosts_current_limit_once_and_takes_silence_as_a_lost_link(
) {
    use stride_link_host::{Board, BoardConfig, BoardEvent};
    let (host, dev) = pty_pair(115_200).unwrap();
    let levers = DueLevers::default();
    let stop = Arc::new(AtomicBool::new(false));
    let fake =
        FakeDue::new(DueConfig::default()).spawn(Paced::new(dev), levers.clone(), stop.clone());
    let cfg = BoardConfig {
        current_limit_a: 3.0,
        joints: vec![2, 3],
        ..BoardConfig::default()
    };
    let (mut board, info) = Board::connect(
        host,
        cfg,
        Duration::from_secs(2),
        Duration::from_millis(200),
    )
    .unwrap();
    assert!(info.joints >= 4);
    let duty = |j| JointCommand {
        joint: j,
        mode: Mode::Duty,
        value: 3000,
    };
    board
        .command(vec![duty(2), duty(3)], Instant::now())
        .unwrap();
    // Joint 3 draws 4 A more (over the host's 3 A, under the board's own trip): braked by the
    // host, once, however many states say so.
    levers.extra_current(3, 4000.0);
    let mut braked = Vec::new();
    let mut states_over = 0;
    // Until the brake and 300 ms beyond it (at most 10 s: a loaded machine is slow).
    let give_up = Instant::now() + Duration::from_secs(10);
    let mut end = give_up;
    while Instant::now() < end {
        if braked.len() == 1 && end == give_up {
            end = Instant::now() + Duration::from_millis(300);
        }
        let now = Instant::now();
        for e in board.pump(now, 0, now + Duration::from_millis(5)).unwrap() {
            match e {
                BoardEvent::Braked { joint, current_a } => braked.push((joint, current_a)),
                BoardEvent::Message(Message::State { joints, .. }) => {
                    states_over += (joints[3].current_a() > 3.0) as u32;
                }
                _ => {}
            }
        }
    }
    assert_eq!(braked.len(), 1, "{braked:?}");
    assert_eq!(braked[0].0, 3);
    assert!(braked[0].1 > 3.0 && states_over >= 1);
    // The board falls silent: half a second later by the caller's clock, the link is lost.
    levers.hold(true);
    // What it wrote before it fell silent is read first.
    let t = Instant::now();
    while !board
        .pump(t, 0, Instant::now() + Duration::from_millis(20))
        .unwrap()
        .is_empty()
    {}
    let later = t + Duration::from_millis(600);
    let mut lost = None;
    for _ in 0..50 {
        match board.pump(later, 0, Instant::now() + Duration::from_millis(5)) {
            Ok(_) => continue,
            Err(e) => {
                lost = Some(e);
                break;
            }
        }
    }
    let e = lost.expect("a silent board is a lost link");
    assert_eq!(e.kind(), std::io::ErrorKind::TimedOut, "{e}");
    levers.hold(false);
    stop.store(true, Ordering::Relaxed);
    let fake = fake.join().unwrap();
    assert!(fake.braked(3));
}
