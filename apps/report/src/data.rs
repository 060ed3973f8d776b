//! What a log holds, gathered for the report.

use std::collections::BTreeMap;
use std::path::Path;

use lcm::{LogReader, Message};
use stride_lcmtypes::stride::{
    ElevationMapT, FootstepPlanRequestT, FootstepPlanT, JointStateT, JointTrajectoryT,
    ObstacleListT, ObstacleT, PoseStampedT, SimReportT,
};

/// A foot on the ground: side (0 left, 1 right), x, y (m), heading (rad).
pub type Foot = (i8, f64, f64, f64);

/// One channel's events.
#[derive(Debug, Clone, Default)]
pub struct Channel {
    /// The LCM type, if this build knows its fingerprint (any of its events').
    pub ty: Option<&'static str>,
    /// Events.
    pub count: u64,
    /// Events whose fingerprint this build does not know (on a channel of a known type:
    /// messages that do not decode, not another type).
    pub unknown: u64,
    /// Arrival at the logger less the header's stamp, ms (types with a header).
    pub latency_ms: Vec<f64>,
}

/// What the report shows, gathered from a log.
#[derive(Debug, Clone, Default)]
pub struct Data {
    /// Events read.
    pub events: u64,
    /// The channels, by name.
    pub channels: BTreeMap<String, Channel>,
    /// What the report could not show, or shows only in part.
    pub warnings: Vec<String>,
    /// The last obstacle list.
    pub obstacles: Vec<ObstacleT>,
    /// The last elevation map.
    pub map: Option<ElevationMapT>,
    /// The last goal (x, y).
    pub goal: Option<[f64; 2]>,
    /// The body's trace (x, y), from the true pose, else the odometry.
    pub trace: Vec<[f64; 2]>,
    /// Every plan's footsteps.
    pub plans: Vec<Vec<Foot>>,
    /// The feet where they touched down.
    pub touchdowns: Vec<Foot>,
    /// Per joint: the commanded rows (s from the log's start, rad).
    pub commanded: BTreeMap<String, BTreeMap<i64, f64>>,
    /// Per joint: the measured positions (s from the log's start, rad).
    pub measured: BTreeMap<String, Vec<(f64, f64)>>,
    /// From each plan request to its plan, ms.
    pub plan_latency_ms: Vec<f64>,
    /// The first event's time, µs.
    pub t0: i64,
    /// From the first event to the last, s.
    pub span_s: f64,
    /// The last simulated world's report.
    pub report: Option<SimReportT>,
}

/// The header stamp of a message whose type starts with a header (µs), read from its bytes.
fn stamp(data: &[u8]) -> Option<i64> {
    Some(i64::from_be_bytes(data.get(8..16)?.try_into().ok()?))
}

/// Whether a type's first member is its header: decoded once, its stamp compared with the
/// bytes after the fingerprint.
fn has_header(data: &[u8]) -> bool {
    match stride_lcmtypes::decode_json(data) {
        Some((_, Ok(v))) => v
            .get("header")
            .and_then(|h| h.get("utime"))
            .and_then(|u| u.as_i64())
            .is_some_and(|u| Some(u) == stamp(data)),
        _ => false,
    }
}

/// Reads a log. A log that cannot be opened is an error; what it holds, however little or
/// torn, is a report with warnings.
pub fn read_log(path: &Path) -> anyhow::Result<Data> {
    let size = std::fs::metadata(path)
        .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", path.display()))?
        .len();
    let mut reader = LogReader::open(path)
        .map_err(|e| anyhow::anyhow!("cannot open {} as an LCM log: {e}", path.display()))?;
    let mut d = Data::default();
    let mut consumed = 0u64;
    let mut headers: BTreeMap<String, bool> = BTreeMap::new();
    let mut requests: BTreeMap<i64, i64> = BTreeMap::new();
    let mut touchdowns = None::<i64>;
    let mut true_pose = false;
    let mut undecodable: BTreeMap<String, u64> = BTreeMap::new();
    let mut chunk_end: BTreeMap<String, Option<i64>> = BTreeMap::new();
    while let Some(e) = reader.read_event() {
        consumed += lcm::event_size(&e);
        if d.events == 0 {
            d.t0 = e.timestamp;
        }
        d.events += 1;
        d.span_s = (e.timestamp - d.t0) as f64 * 1e-6;
        let ty = stride_lcmtypes::type_name_of(&e.data);
        let ch = d.channels.entry(e.channel.clone()).or_default();
        ch.ty = ch.ty.or(ty);
        ch.count += 1;
        ch.unknown += u64::from(ty.is_none());
        let Some(ty) = ty else { continue };
        let with_header = *headers
            .entry(e.channel.clone())
            .or_insert_with(|| has_header(&e.data));
        if with_header {
            if let Some(s) = stamp(&e.data) {
                ch.latency_ms.push((e.timestamp - s) as f64 * 1e-3);
            }
        }
        let name = e.channel.as_str();
        let mut broken = || *undecodable.entry(e.channel.clone()).or_default() += 1;
        match ty {
            "stride.obstacle_list_t" => match ObstacleListT::decode(&e.data) {
                Ok(m) => d.obstacles = m.obstacles,
                Err(_) => broken(),
            },
            "stride.elevation_map_t" => match ElevationMapT::decode(&e.data) {
                Ok(m) => d.map = Some(m),
                Err(_) => broken(),
            },
            "stride.pose_stamped_t" => match PoseStampedT::decode(&e.data) {
                Ok(m) if name.contains("GOAL") => {
                    d.goal = Some([m.pose.position[0], m.pose.position[1]]);
                }
                Ok(m) => {
                    // The true pose wins over any other: the trace is where the body was.
                    let truth = name.starts_with("SIM_");
                    if truth && !true_pose {
                        d.trace.clear();
                        true_pose = true;
                    }
                    if truth || !true_pose {
                        d.trace.push([m.pose.position[0], m.pose.position[1]]);
                    }
                }
                Err(_) => broken(),
            },
            "stride.odometry_t" if !true_pose => {
                if let Ok(m) = stride_lcmtypes::stride::OdometryT::decode(&e.data) {
                    d.trace.push([m.pose.position[0], m.pose.position[1]]);
                }
            }
            "stride.footstep_plan_request_t" => match FootstepPlanRequestT::decode(&e.data) {
                Ok(m) => {
                    requests.insert(m.request_id, e.timestamp);
                }
                Err(_) => broken(),
            },
            "stride.footstep_plan_t" => match FootstepPlanT::decode(&e.data) {
                Ok(m) => {
                    if let Some(at) = requests.remove(&m.request_id) {
                        d.plan_latency_ms.push((e.timestamp - at) as f64 * 1e-3);
                    }
                    let steps: Vec<Foot> = m
                        .steps
                        .iter()
                        .map(|s| (s.foot.side, s.foot.x, s.foot.y, s.foot.yaw))
                        .collect();
                    if !steps.is_empty() {
                        d.plans.push(steps);
                    }
                }
                Err(_) => broken(),
            },
            "stride.sim_report_t" => match SimReportT::decode(&e.data) {
                Ok(m) => {
                    if touchdowns.is_some_and(|n| m.touchdowns > n) {
                        let f = m.feet[m.anchor.clamp(0, 1) as usize];
                        d.touchdowns.push((m.anchor, f[0], f[1], f[3]));
                    }
                    touchdowns = Some(m.touchdowns);
                    d.report = Some(m);
                }
                Err(_) => broken(),
            },
            "stride.joint_trajectory_t" => match JointTrajectoryT::decode(&e.data) {
                Ok(m) => {
                    // An appended chunk starts where the channel's last one ended.
                    let end = chunk_end.entry(e.channel.clone()).or_default();
                    let base = if m.queue == JointTrajectoryT::QUEUE_APPEND || m.start_utime == 0 {
                        *end
                    } else {
                        Some(m.start_utime)
                    };
                    let Some(base) = base else { continue };
                    *end = m
                        .time_from_start
                        .last()
                        .map(|t| base + (t * 1e6).round() as i64);
                    for (j, joint) in m.joint_names.iter().enumerate() {
                        let rows = d.commanded.entry(joint.clone()).or_default();
                        for (k, dt) in m.time_from_start.iter().enumerate() {
                            let at = base + (dt * 1e6).round() as i64 - d.t0;
                            if let Some(p) = m.positions.get(k).and_then(|r| r.get(j)) {
                                rows.insert(at, *p);
                            }
                        }
                    }
                }
                Err(_) => broken(),
            },
            // The drives' positions as the bridges report them (not the simulated world's).
            "stride.joint_state_t" if !name.starts_with("SIM_") => {
                match JointStateT::decode(&e.data) {
                    Ok(m) => {
                        let at = (m.header.utime - d.t0) as f64 * 1e-6;
                        for (n, p) in m.names.iter().zip(&m.positions) {
                            d.measured.entry(n.clone()).or_default().push((at, *p));
                        }
                    }
                    Err(_) => broken(),
                }
            }
            _ => {}
        }
    }
    if consumed < size {
        let unread = size - consumed;
        d.warnings.push(format!(
            "the log could not be read past byte {consumed} of {size} (a torn or unreadable \
             event after {} events; {unread} bytes, {:.0} % of the file, unread): the report \
             covers what came before",
            d.events,
            100.0 * unread as f64 / size.max(1) as f64
        ));
    }
    let unknown: Vec<&str> = d
        .channels
        .iter()
        // liblcm's own self-test, not a message of anybody's.
        .filter(|(n, c)| c.ty.is_none() && n.as_str() != "LCM_SELF_TEST")
        .map(|(n, _)| n.as_str())
        .collect();
    if !unknown.is_empty() {
        d.warnings.push(format!(
            "channels of types this build does not know (left out): {}",
            unknown.join(", ")
        ));
    }
    // A channel of a known type whose other events carry no known fingerprint: messages
    // that do not decode (garbage on it), not another type.
    for (name, c) in &d.channels {
        if c.ty.is_some() && c.unknown > 0 {
            *undecodable.entry(name.clone()).or_default() += c.unknown;
        }
    }
    for (ch, n) in undecodable {
        let ty = d.channels.get(&ch).and_then(|c| c.ty).unwrap_or("?");
        d.warnings.push(format!(
            "{ch}: {n} messages that do not decode as {ty} (left out)"
        ));
    }
    for (what, missing) in [
        ("the top view has no obstacles", d.obstacles.is_empty()),
        ("the top view has no body trace", d.trace.is_empty()),
        ("no plans", d.plans.is_empty()),
        ("no joint rows commanded", d.commanded.is_empty()),
        ("no joint states measured", d.measured.is_empty()),
        ("no elevation map", d.map.is_none()),
    ] {
        if missing {
            d.warnings.push(format!("{what} in this log"));
        }
    }
    Ok(d)
}
