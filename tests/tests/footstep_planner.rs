//! stride-footstep-planner as a process: plans on request, from a scene or from the mapper's
//! obstacles, and once per change of the world under the plan.

use std::process::Command;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use lcm::Lcm;
use stride_footstep::geom::v2;
use stride_footstep_planner::node::request_at;
use stride_lcmtypes::stride::{
    FootstepPlanRequestT, FootstepPlanT, NodeStatusT, ObstacleListT, ObstacleT,
};
use stride_tests::{bin, handle_until, require_sandbox, udpm_url, Proc};

fn request(id: i64) -> FootstepPlanRequestT {
    request_at(id, 100, v2(0.0, 0.0), 0.0, v2(4.0, 0.0))
}

fn circle(id: i32, x: f64, y: f64, r: f64) -> ObstacleT {
    ObstacleT {
        id,
        kind: ObstacleT::KIND_CIRCLE,
        center: [x, y, 0.0],
        radius: r,
        z_min: 0.0,
        z_max: 1.0,
        ..Default::default()
    }
}

fn obstacles(list: Vec<ObstacleT>) -> ObstacleListT {
    ObstacleListT {
        num_obstacles: list.len() as i32,
        obstacles: list,
        ..Default::default()
    }
}

struct Rig {
    lcm: Lcm,
    plans: Arc<Mutex<Vec<FootstepPlanT>>>,
    _subs: Vec<lcm::Subscription>,
    node: Proc,
}

fn start(port: u16, scene: Option<&str>) -> Rig {
    let url = udpm_url(port);
    let lcm = Lcm::new(&url).unwrap();
    let plans = Arc::new(Mutex::new(Vec::new()));
    let up = Arc::new(Mutex::new(false));
    let (p, u) = (plans.clone(), up.clone());
    let subs = vec![
        {
            let s = lcm
                .subscribe("FOOTSTEP_PLAN", move |_, m: FootstepPlanT| {
                    p.lock().unwrap().push(m)
                })
                .unwrap();
            // A burst of answers must wait for the test's loop, not be dropped.
            s.set_queue_capacity(100_000).unwrap();
            s
        },
        lcm.subscribe("STRIDE_STATUS", move |_, m: NodeStatusT| {
            if m.node == "stride-footstep-planner" && m.state == NodeStatusT::STATE_RUNNING {
                *u.lock().unwrap() = true;
            }
        })
        .unwrap(),
    ];
    let mut c = Command::new(bin("stride-footstep-planner"));
    c.args(["--lcm-url", &url, "--log-level", "warn"]);
    if let Some(s) = scene {
        c.arg("--scene")
            .arg(std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(s));
    }
    let node = Proc::spawn(c);
    assert!(
        handle_until(&lcm, Duration::from_secs(10), || *up.lock().unwrap()),
        "never up"
    );
    Rig {
        lcm,
        plans,
        _subs: subs,
        node,
    }
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn plans_from_a_scene() {
    require_sandbox();
    let r = start(7781, Some("../config/scenes/archie/archie-09.toml"));
    let mut req = request(1);
    req.goal_x = 1.0;
    req.goal_y = -3.0;
    r.lcm.publish("FOOTSTEP_PLAN_REQUEST", &req).unwrap();
    assert!(handle_until(&r.lcm, Duration::from_secs(5), || !r
        .plans
        .lock()
        .unwrap()
        .is_empty()));
    let plan = r.plans.lock().unwrap()[0].clone();
    assert_eq!(
        (plan.request_id, plan.step_number, plan.status),
        (1, 100, FootstepPlanT::STATUS_OK)
    );
    assert!(plan.num_steps > 10 && plan.steps[0].step_number == 101);
    assert!((plan.cost - 4.29).abs() < 0.05, "{}", plan.cost);
    // The footstep planners answer through the same node, in the same world.
    for (id, planner) in [
        (2, FootstepPlanRequestT::PLANNER_KAIST),
        (3, FootstepPlanRequestT::PLANNER_LOLA),
    ] {
        let mut other = req.clone();
        other.request_id = id;
        other.planner = planner;
        r.lcm.publish("FOOTSTEP_PLAN_REQUEST", &other).unwrap();
        assert!(handle_until(&r.lcm, Duration::from_secs(10), || r
            .plans
            .lock()
            .unwrap()
            .iter()
            .any(|p| p.request_id == id)));
        let got = r.plans.lock().unwrap().last().unwrap().clone();
        // A plan, or the best part of one when the budget ends first (how far a search gets
        // within its budget depends on the machine).
        assert!(
            [FootstepPlanT::STATUS_OK, FootstepPlanT::STATUS_PARTIAL].contains(&got.status),
            "{planner}: {} {}",
            got.status,
            got.detail
        );
        assert!(got.num_steps >= 3);
    }
    // An unknown planner: a clear refusal, with steps in place.
    let mut unknown = request(4);
    unknown.planner = 9;
    r.lcm.publish("FOOTSTEP_PLAN_REQUEST", &unknown).unwrap();
    assert!(handle_until(&r.lcm, Duration::from_secs(5), || r
        .plans
        .lock()
        .unwrap()
        .iter()
        .any(|p| p.request_id == 4)));
    let refused = r.plans.lock().unwrap().last().unwrap().clone();
    assert_eq!(refused.status, FootstepPlanT::STATUS_BAD_REQUEST);
    assert!(refused.num_steps >= 3);
    let (st, _) = r.node.interrupt();
    assert!(st.success());
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn replans_once_when_the_world_blocks_the_plan() {
    require_sandbox();
    let r = start(7782, None);
    let world = vec![circle(1, 2.0, 1.5, 0.3)];
    r.lcm
        .publish("OBSTACLES", &obstacles(world.clone()))
        .unwrap();
    handle_until(&r.lcm, Duration::from_millis(200), || false);
    r.lcm.publish("FOOTSTEP_PLAN_REQUEST", &request(9)).unwrap();
    assert!(handle_until(&r.lcm, Duration::from_secs(5), || r
        .plans
        .lock()
        .unwrap()
        .len()
        == 1));
    let straight = r.plans.lock().unwrap()[0].cost;
    assert!((straight - 4.0).abs() < 1e-6, "{straight}");
    // An obstacle appears on the way, reported five times: one new plan around it.
    let mut blocked = world;
    blocked.push(circle(2, 2.0, 0.0, 0.4));
    for _ in 0..5 {
        r.lcm
            .publish("OBSTACLES", &obstacles(blocked.clone()))
            .unwrap();
        handle_until(&r.lcm, Duration::from_millis(100), || false);
    }
    handle_until(&r.lcm, Duration::from_secs(1), || false);
    let plans = r.plans.lock().unwrap().clone();
    assert_eq!(
        plans.len(),
        2,
        "{:?}",
        plans.iter().map(|p| p.cost).collect::<Vec<_>>()
    );
    assert_eq!(plans[1].request_id, 9);
    assert!(plans[1].cost > straight + 0.05);
    drop(plans);
    let (st, _) = r.node.interrupt();
    assert!(st.success());
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn ask_prints_the_running_planners_answer() {
    require_sandbox();
    let r = start(7783, Some("../config/scenes/kaist/kaist-b6.toml"));
    let url = udpm_url(7783);
    for planner in ["archie", "kaist", "lola"] {
        let out = Command::new(bin("stride-footstep-planner"))
            .args(["--lcm-url", &url, "--log-level", "warn", "--ask", "4,0"])
            .args(["--planner", planner])
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{planner}: {text} {}",
            String::from_utf8_lossy(&out.stderr)
        );
        // A plan (0), or its best part when the budget ends first (1).
        assert!(
            (text.contains("status 0") || text.contains("status 1")) && text.contains("step "),
            "{planner}: {text}"
        );
    }
    // Nobody to answer: a clear error.
    let out = Command::new(bin("stride-footstep-planner"))
        .args(["--lcm-url", &url, "--ask", "1,0", "--wait-s", "0.5"])
        .args(["--plan-channel", "NOBODY"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("is stride-footstep-planner running?"));
    let (st, _) = r.node.interrupt();
    assert!(st.success());
}

/// Waits for the answer to request `id`.
fn answer(r: &Rig, id: i64, within: Duration) -> FootstepPlanT {
    let found = || {
        r.plans
            .lock()
            .unwrap()
            .iter()
            .find(|p| p.request_id == id)
            .cloned()
    };
    assert!(
        handle_until(&r.lcm, within, || found().is_some()),
        "request {id} not answered within {within:?}"
    );
    found().unwrap()
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn an_infinite_or_huge_obstacle_is_refused_and_the_planner_keeps_answering() {
    require_sandbox();
    let r = start(7784, None);
    for (k, radius) in [f64::INFINITY, 1e9, f64::NAN].into_iter().enumerate() {
        let mut bad = circle(1, 2.0, 0.0, radius);
        if radius.is_nan() {
            bad = circle(1, f64::NAN, 0.0, 0.3);
        }
        r.lcm.publish("OBSTACLES", &obstacles(vec![bad])).unwrap();
        // KAIST's grid is the one a huge world would have blown up; every planner answers.
        for (j, planner) in [
            FootstepPlanRequestT::PLANNER_KAIST,
            FootstepPlanRequestT::PLANNER_ARCHIE,
        ]
        .into_iter()
        .enumerate()
        {
            let id = 10 * k as i64 + j as i64 + 1;
            let mut req = request(id);
            req.goal_x = 1.0;
            req.planner = planner;
            req.header.frame = format!("client-{id}");
            r.lcm.publish("FOOTSTEP_PLAN_REQUEST", &req).unwrap();
            let got = answer(&r, id, Duration::from_secs(5));
            // The bad list was refused: the world is still empty, so the plan goes straight.
            assert!(
                [FootstepPlanT::STATUS_OK, FootstepPlanT::STATUS_PARTIAL].contains(&got.status),
                "radius {radius}: {} {}",
                got.status,
                got.detail
            );
        }
    }
    let (st, _) = r.node.interrupt();
    assert!(st.success());
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn a_goal_beyond_the_limit_is_refused_with_its_reason() {
    require_sandbox();
    let r = start(7785, None);
    for (id, x) in [(1, 1e6), (2, 1e8)] {
        let mut req = request(id);
        req.goal_x = x;
        r.lcm.publish("FOOTSTEP_PLAN_REQUEST", &req).unwrap();
        let got = answer(&r, id, Duration::from_secs(5));
        assert_eq!(
            got.status,
            FootstepPlanT::STATUS_BAD_REQUEST,
            "{}",
            got.detail
        );
        assert!(got.detail.contains("away"), "{}", got.detail);
        assert!(got.num_steps <= 3, "{}", got.num_steps);
    }
    // A budget beyond the configured longest is refused too.
    let mut long = request(3);
    long.max_time_us = 60_000_000;
    r.lcm.publish("FOOTSTEP_PLAN_REQUEST", &long).unwrap();
    let got = answer(&r, 3, Duration::from_secs(5));
    assert_eq!(
        got.status,
        FootstepPlanT::STATUS_BAD_REQUEST,
        "{}",
        got.detail
    );
    let (st, _) = r.node.interrupt();
    assert!(st.success());
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn every_request_is_answered_superseded_ones_too() {
    require_sandbox();
    let r = start(7786, Some("../config/scenes/archie/archie-09.toml"));
    let n = 1000;
    for id in 1..=n {
        let mut req = request(id);
        req.goal_x = 1.0;
        req.goal_y = -3.0;
        r.lcm.publish("FOOTSTEP_PLAN_REQUEST", &req).unwrap();
        std::thread::sleep(Duration::from_micros(500));
    }
    assert!(
        handle_until(&r.lcm, Duration::from_secs(20), || r
            .plans
            .lock()
            .unwrap()
            .iter()
            .map(|p| p.request_id)
            .collect::<std::collections::BTreeSet<_>>()
            .len()
            == n as usize),
        "{} of {n} answered",
        r.plans.lock().unwrap().len()
    );
    let plans = r.plans.lock().unwrap().clone();
    assert_eq!(plans.len(), n as usize, "each answered once");
    // How many are superseded depends on how fast the planner is against the sender (none
    // when every search ends before the next request comes): it is not asserted here. That a
    // newer request supersedes a waiting or running one is shown without timing in
    // a_long_search_is_cancelled_by_its_requesters_next_request_and_by_shutdown and in the
    // planner node's unit tests.
    assert!(plans
        .iter()
        .all(|p| [FootstepPlanT::STATUS_OK, FootstepPlanT::STATUS_SUPERSEDED].contains(&p.status)));
    // The last request is always planned.
    assert_eq!(
        plans.iter().find(|p| p.request_id == n).unwrap().status,
        FootstepPlanT::STATUS_OK
    );
    let (st, _) = r.node.interrupt();
    assert!(st.success());
}

#[test]
#[ignore = "multicast: scripts/test runs it in a private network namespace"]
fn a_long_search_is_cancelled_by_its_requesters_next_request_and_by_shutdown() {
    require_sandbox();
    let r = start(7787, None);
    // A wall across the way: LOLA's thesis mode (a tree search) runs to its budget, 9 s.
    let wall = (0..30)
        .map(|k| circle(k, 2.0, -6.0 + 0.4 * k as f64, 0.3))
        .collect();
    r.lcm.publish("OBSTACLES", &obstacles(wall)).unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let mut long = request(1);
    long.planner = FootstepPlanRequestT::PLANNER_LOLA;
    long.faithful = true;
    long.max_time_us = 9_000_000;
    r.lcm.publish("FOOTSTEP_PLAN_REQUEST", &long).unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let mut next = request(2);
    next.goal_x = 1.0;
    r.lcm.publish("FOOTSTEP_PLAN_REQUEST", &next).unwrap();
    let got = answer(&r, 2, Duration::from_secs(5));
    assert_eq!(got.status, FootstepPlanT::STATUS_OK, "{}", got.detail);
    let first = answer(&r, 1, Duration::from_secs(1));
    assert_eq!(
        first.status,
        FootstepPlanT::STATUS_SUPERSEDED,
        "{}",
        first.detail
    );
    // (SUPERSEDED, not a plan after the 9 s budget: the search was cut short.)
    // Another long search, then SIGINT: the process ends without waiting for it, and the
    // search is answered.
    let mut again = long.clone();
    again.request_id = 3;
    r.lcm.publish("FOOTSTEP_PLAN_REQUEST", &again).unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let node = r.node;
    let stop = std::thread::spawn(move || node.interrupt());
    let last = answer(
        &Rig {
            lcm: r.lcm,
            plans: r.plans,
            _subs: r._subs,
            node: Proc::spawn(Command::new("true")),
        },
        3,
        Duration::from_secs(5),
    );
    let (st, _) = stop.join().unwrap();
    assert!(st.success());
    assert_eq!(
        last.status,
        FootstepPlanT::STATUS_SUPERSEDED,
        "{}",
        last.detail
    );
}
