//! stride-spy on an LCM log (written with liblcm's own log writer, as lcm-logger writes them):
//! `echo --log` and `export` to CSV, JSON lines and MCAP.

use std::path::{Path, PathBuf};
use std::process::Command;

use lcm::Message;
use serde_json::{json, Value};
use stride_lcmtypes::stride::{HeaderT, ImuT, JointStateT, PingT, PointCloudT};

const T0: i64 = 1_700_000_000_000_000;

fn spy(args: &[&str], paths: &[&Path]) -> String {
    let mut c = Command::new(env!("CARGO_BIN_EXE_stride-spy"));
    c.args(args).args(paths);
    let out = c.output().unwrap();
    assert!(
        out.status.success(),
        "stride-spy {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

fn header(seq: i64) -> HeaderT {
    HeaderT {
        utime: T0 + seq,
        sequence: seq,
        frame: "pelvis".into(),
    }
}

/// Joint states of 1, 2 and 3 joints; the positions hold NaN, +inf and -inf.
fn joints(n: usize) -> JointStateT {
    let specials = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY];
    JointStateT {
        header: header(n as i64),
        num_joints: n as i32,
        names: (0..n).map(|i| format!("j{i}")).collect(),
        positions: (0..n).map(|i| specials[i]).collect(),
        velocities: (0..n).map(|i| i as f64 * 0.5).collect(),
        currents: vec![-1.25; n],
        temperatures: (0..n)
            .map(|i| [f32::NAN, 30.5, f32::NEG_INFINITY][i])
            .collect(),
        faults: (0..n).map(|i| i as i32).collect(),
    }
}

fn imu(i: i64) -> ImuT {
    ImuT {
        header: header(i),
        orientation: [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, -0.0],
        angular_velocity: [1e-300, 1e300, 0.1],
        linear_acceleration: [0.0, 0.0, 9.81],
        temperature: [f32::NAN, f32::INFINITY, 21.25][i as usize % 3],
    }
}

fn cloud(i: i64) -> PointCloudT {
    PointCloudT {
        header: header(i),
        num_points: 2,
        points: vec![
            [0.1, f32::NAN, 2.0],
            [f32::INFINITY, -3.5, f32::NEG_INFINITY],
        ],
        num_intensities: 1,
        intensities: vec![f32::MAX],
    }
}

/// A log of known types (with NaN and infinities), an unknown type and a broken message; the
/// events' timestamps are not in order, as a log's need not be.
fn write_log(dir: &Path) -> (PathBuf, Vec<(i64, String, Vec<u8>)>) {
    let path = dir.join("walk.lcmlog");
    let mut events = Vec::new();
    for i in 0..3 {
        events.push((
            T0 + 10 * i,
            "JOINT_STATE".to_owned(),
            joints(i as usize + 1).encode().unwrap(),
        ));
        events.push((T0 + 10 * i + 1, "IMU".to_owned(), imu(i).encode().unwrap()));
        events.push((
            T0 + 10 * i + 2,
            "CLOUD".to_owned(),
            cloud(i).encode().unwrap(),
        ));
        events.push((
            T0 + 10 * i + 3,
            "RAW".to_owned(),
            format!("not lcm {i}").into_bytes(),
        ));
    }
    let ping = PingT::default().encode().unwrap();
    events.push((T0 - 5, "BROKEN".to_owned(), ping[..ping.len() - 1].to_vec()));
    events.push((T0 + 100, "PING".to_owned(), ping.clone()));
    let mut w = lcm::LogWriter::create(&path).unwrap();
    for (t, ch, data) in &events {
        w.write(*t, ch, data).unwrap();
    }
    drop(w);
    (path, events)
}

fn keys(v: &Value) -> Vec<&str> {
    v.as_object().unwrap().keys().map(String::as_str).collect()
}

const JOINT_MEMBERS: [&str; 8] = [
    "header",
    "num_joints",
    "names",
    "positions",
    "velocities",
    "currents",
    "temperatures",
    "faults",
];

fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let mut r = csv::Reader::from_path(path).unwrap();
    let header = r.headers().unwrap().iter().map(str::to_owned).collect();
    let rows = r
        .records()
        .map(|x| x.unwrap().iter().map(str::to_owned).collect())
        .collect();
    (header, rows)
}

#[test]
fn json_and_csv_keep_nan_and_infinities_apart() {
    let dir = tempfile::tempdir().unwrap();
    let (log, _) = write_log(dir.path());

    let out = spy(&["echo", "--channel", "IMU|JOINT_STATE", "--log"], &[&log]);
    let lines: Vec<Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 6, "{out}");
    let imu0 = &lines[1]["message"];
    assert_eq!(
        imu0["orientation"],
        json!(["NaN", "inf", "-inf", -0.0]),
        "{out}"
    );
    assert_eq!(imu0["temperature"], "NaN");
    assert_eq!(lines[3]["message"]["temperature"], "inf");
    assert_eq!(lines[5]["message"]["temperature"], 21.25);
    assert_eq!(
        lines[4]["message"]["positions"],
        json!(["NaN", "inf", "-inf"])
    );
    assert!(!out.contains("null"), "{out}");

    let json_dir = dir.path().join("json");
    spy(
        &["export", "--format", "json", "--channel", "CLOUD", "--out"],
        &[&json_dir, &log],
    );
    let text = std::fs::read_to_string(json_dir.join("CLOUD.jsonl")).unwrap();
    let first: Value = serde_json::from_str(text.lines().next().unwrap()).unwrap();
    assert_eq!(
        first["message"]["points"],
        json!([[f64::from(0.1f32), "NaN", 2.0], ["inf", -3.5, "-inf"]])
    );

    let csv_dir = dir.path().join("csv");
    spy(&["export", "--out"], &[&csv_dir, &log]);
    let (header, rows) = read_csv(&csv_dir.join("IMU.csv"));
    let cell =
        |row: &[String], col: &str| row[header.iter().position(|h| h == col).unwrap()].clone();
    assert_eq!(
        [
            "orientation[0]",
            "orientation[1]",
            "orientation[2]",
            "orientation[3]"
        ]
        .map(|c| cell(&rows[0], c)),
        ["NaN", "inf", "-inf", "-0.0"]
    );
    let temps: Vec<String> = rows.iter().map(|r| cell(r, "temperature")).collect();
    assert_eq!(temps, ["NaN", "inf", "21.25"]);
    let (header, rows) = read_csv(&csv_dir.join("CLOUD.csv"));
    let cell =
        |row: &[String], col: &str| row[header.iter().position(|h| h == col).unwrap()].clone();
    assert_eq!(cell(&rows[2], "points[0][1]"), "NaN");
    assert_eq!(cell(&rows[2], "points[1][0]"), "inf");
    assert_eq!(cell(&rows[2], "points[1][2]"), "-inf");
}

#[test]
fn json_and_csv_follow_declaration_order() {
    let dir = tempfile::tempdir().unwrap();
    let (log, _) = write_log(dir.path());

    let out = spy(&["echo", "--channel", "JOINT_STATE", "--log"], &[&log]);
    for line in out.lines() {
        let v: Value = serde_json::from_str(line).unwrap();
        assert_eq!(keys(&v), ["channel", "utime", "type", "message"]);
        assert_eq!(keys(&v["message"]), JOINT_MEMBERS, "{line}");
        assert_eq!(
            keys(&v["message"]["header"]),
            ["utime", "sequence", "frame"]
        );
    }

    let csv_dir = dir.path().join("csv");
    spy(
        &["export", "--channel", "JOINT_STATE|IMU", "--out"],
        &[&csv_dir, &log],
    );
    // The first row has one joint, the last three: every array's columns stay together.
    let (header, rows) = read_csv(&csv_dir.join("JOINT_STATE.csv"));
    let mut want = vec![
        "event",
        "log_utime",
        "header.utime",
        "header.sequence",
        "header.frame",
        "num_joints",
    ]
    .into_iter()
    .map(str::to_owned)
    .collect::<Vec<_>>();
    for m in &JOINT_MEMBERS[2..] {
        want.extend((0..3).map(|i| format!("{m}[{i}]")));
    }
    assert_eq!(header, want);
    assert_eq!(
        rows[0][header.iter().position(|h| h == "names[0]").unwrap()],
        "j0"
    );
    assert_eq!(
        rows[0][header.iter().position(|h| h == "names[1]").unwrap()],
        ""
    );
    let (header, _) = read_csv(&csv_dir.join("IMU.csv"));
    let members: Vec<&str> = header[2..]
        .iter()
        .map(|h| h.split(['.', '[']).next().unwrap())
        .fold(Vec::new(), |mut v, m| {
            if v.last() != Some(&m) {
                v.push(m);
            }
            v
        });
    assert_eq!(
        members,
        [
            "header",
            "orientation",
            "angular_velocity",
            "linear_acceleration",
            "temperature"
        ]
    );
}

/// A JSON float as written: a number, or one of the strings for NaN and the infinities.
fn float(v: &Value) -> f64 {
    match v {
        Value::String(s) if s == "NaN" => f64::NAN,
        Value::String(s) if s == "inf" => f64::INFINITY,
        Value::String(s) if s == "-inf" => f64::NEG_INFINITY,
        v => v.as_f64().unwrap_or_else(|| panic!("not a float: {v}")),
    }
}

/// The same float, bit for bit (any NaN matching any NaN).
fn same(v: &Value, x: f64) -> bool {
    let y = float(v);
    (x.is_nan() && y.is_nan()) || x.to_bits() == y.to_bits()
}

fn floats<T: Copy + Into<f64>>(v: &Value, xs: &[T]) {
    let a = v.as_array().unwrap();
    assert_eq!(a.len(), xs.len(), "{v}");
    for (j, x) in a.iter().zip(xs) {
        assert!(same(j, (*x).into()), "{j} is not {}", (*x).into());
    }
}

fn check_header(v: &Value, h: &HeaderT) {
    assert_eq!(keys(v), ["utime", "sequence", "frame"]);
    assert_eq!(v["utime"], h.utime);
    assert_eq!(v["sequence"], h.sequence);
    assert_eq!(v["frame"], h.frame.as_str());
}

/// Every member of the MCAP message `v` against the LCM decode of `data`.
fn check_value(ty: &str, v: &Value, data: &[u8]) {
    match ty {
        "stride.joint_state_t" => {
            let m = JointStateT::decode(data).unwrap();
            assert_eq!(keys(v), JOINT_MEMBERS);
            check_header(&v["header"], &m.header);
            assert_eq!(v["num_joints"], m.num_joints);
            assert_eq!(v["names"], json!(m.names));
            floats(&v["positions"], &m.positions);
            floats(&v["velocities"], &m.velocities);
            floats(&v["currents"], &m.currents);
            floats(&v["temperatures"], &m.temperatures);
            assert_eq!(v["faults"], json!(m.faults));
        }
        "stride.imu_t" => {
            let m = ImuT::decode(data).unwrap();
            assert_eq!(
                keys(v),
                [
                    "header",
                    "orientation",
                    "angular_velocity",
                    "linear_acceleration",
                    "temperature"
                ]
            );
            check_header(&v["header"], &m.header);
            floats(&v["orientation"], &m.orientation);
            floats(&v["angular_velocity"], &m.angular_velocity);
            floats(&v["linear_acceleration"], &m.linear_acceleration);
            assert!(same(&v["temperature"], m.temperature.into()));
        }
        "stride.point_cloud_t" => {
            let m = PointCloudT::decode(data).unwrap();
            assert_eq!(
                keys(v),
                [
                    "header",
                    "num_points",
                    "points",
                    "num_intensities",
                    "intensities"
                ]
            );
            check_header(&v["header"], &m.header);
            assert_eq!(v["num_points"], m.num_points);
            // An array of arrays: each point an object holding its coordinates under "values".
            let points = v["points"].as_array().unwrap();
            assert_eq!(points.len(), m.points.len());
            assert!(!points.is_empty());
            for (p, q) in points.iter().zip(&m.points) {
                assert_eq!(keys(p), ["values"], "{p}");
                floats(&p["values"], q);
            }
            assert_eq!(
                v["points"][1]["values"][0], "inf",
                "the path .points[1].values[0]"
            );
            assert_eq!(v["num_intensities"], m.num_intensities);
            floats(&v["intensities"], &m.intensities);
        }
        "stride.ping_t" => {
            let m = PingT::decode(data).unwrap();
            check_header(&v["header"], &m.header);
            assert_eq!(v["payload"], json!(m.payload));
        }
        other => panic!("unexpected type {other}"),
    }
}

#[test]
fn mcap_export_keeps_every_message_in_order_with_its_time_and_values() {
    let dir = tempfile::tempdir().unwrap();
    let (log, events) = write_log(dir.path());
    let out_dir = dir.path().join("mcap");
    let out = spy(&["export", "--format", "mcap", "--out"], &[&out_dir, &log]);
    let path = out_dir.join("walk.mcap");
    assert!(
        out.contains("RAW: 3 messages (3 not decoded, kept as LCM bytes) -> "),
        "{out}"
    );
    assert!(out.contains("BROKEN: 1 messages (1 not decoded"), "{out}");
    assert!(
        out.contains(&format!("IMU: 3 messages -> {}", path.display())),
        "{out}"
    );
    assert_eq!(
        std::fs::read_dir(&out_dir).unwrap().count(),
        1,
        "only the MCAP file"
    );

    let bytes = std::fs::read(&path).unwrap();
    let messages: Vec<mcap::Message> = mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(Result::unwrap)
        .collect();
    assert_eq!(messages.len(), events.len());
    for (i, (m, (t, channel, data))) in messages.iter().zip(&events).enumerate() {
        assert_eq!(&m.channel.topic, channel, "message {i}");
        assert_eq!(m.log_time, *t as u64 * 1000, "message {i}");
        assert_eq!(m.publish_time, m.log_time);
        assert_eq!(m.sequence, i as u32, "the log's event number");
        match stride_lcmtypes::type_name_of(data).filter(|_| channel != "BROKEN") {
            Some(ty) => {
                assert_eq!(m.channel.message_encoding, "json");
                let schema = m.channel.schema.as_ref().expect("a schema");
                assert_eq!(schema.name, ty);
                assert_eq!(schema.encoding, "jsonschema");
                let s: Value = serde_json::from_slice(&schema.data).unwrap();
                assert_eq!(s["title"], ty);
                assert_eq!(s["type"], "object");
                let v: Value = serde_json::from_slice(&m.data).unwrap();
                assert_eq!(keys(&s["properties"]), keys(&v), "schema and message agree");
                if ty == "stride.point_cloud_t" {
                    assert_eq!(
                        s["properties"]["points"]["items"],
                        json!({"type": "object",
                               "properties": {"values": {"type": "array", "items": {"type": "number"},
                                                         "minItems": 3, "maxItems": 3}},
                               "required": ["values"], "additionalProperties": false})
                    );
                }
                check_value(ty, &v, data);
            }
            None => {
                assert_eq!(m.channel.message_encoding, "lcm");
                assert!(m.channel.schema.is_none());
                assert_eq!(&m.data[..], &data[..], "the LCM bytes as logged");
            }
        }
    }

    // The summary: one channel per LCM channel, the statistics of the whole log.
    let summary = mcap::Summary::read(&bytes).unwrap().expect("a summary");
    let mut topics: Vec<&str> = summary
        .channels
        .values()
        .map(|c| c.topic.as_str())
        .collect();
    topics.sort_unstable();
    assert_eq!(
        topics,
        ["BROKEN", "CLOUD", "IMU", "JOINT_STATE", "PING", "RAW"]
    );
    let stats = summary.stats.unwrap();
    assert_eq!(stats.message_count, events.len() as u64);
    assert_eq!(stats.message_start_time, (T0 - 5) as u64 * 1000);
    assert_eq!(stats.message_end_time, (T0 + 100) as u64 * 1000);
    assert_eq!(stats.schema_count, 4);

    // Only the chosen channels; nothing on none.
    let one = dir.path().join("one");
    spy(
        &["export", "--format", "mcap", "--channel", "IMU", "--out"],
        &[&one, &log],
    );
    let bytes = std::fs::read(one.join("walk.mcap")).unwrap();
    assert_eq!(mcap::MessageStream::new(&bytes).unwrap().count(), 3);
    let none = Command::new(env!("CARGO_BIN_EXE_stride-spy"))
        .args([
            "export",
            "--format",
            "mcap",
            "--channel",
            "NOTHING",
            "--out",
        ])
        .arg(dir.path().join("none"))
        .arg(&log)
        .output()
        .unwrap();
    assert!(!none.status.success());
    assert_eq!(
        std::fs::read_dir(dir.path().join("none")).unwrap().count(),
        0
    );
}

/// D12 of the reliability findings: `stride-spy export` of a torn log wrote a valid MCAP and
/// said nothing of the torn end; liblcm's reader put its own unprefixed lines on stderr; a
/// missing log's error said "No such file or directory" twice.
#[test]
fn an_export_of_a_torn_log_says_so_and_liblcms_lines_are_its_own() {
    let dir = tempfile::tempdir().unwrap();
    let (log, _) = write_log(dir.path());
    let whole = std::fs::read(&log).unwrap();
    let torn = dir.path().join("torn.lcmlog");
    std::fs::write(&torn, &whole[..whole.len() - 7]).unwrap();
    for format in ["mcap", "json"] {
        let out = Command::new(env!("CARGO_BIN_EXE_stride-spy"))
            .args(["export", "--format", format, "--out"])
            .arg(dir.path().join(format))
            .arg(&torn)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{err}");
        assert!(
            err.contains("could not be read past byte") && err.contains("bytes unread"),
            "{format}: {err}"
        );
        assert!(
            err.lines().all(|l| l.starts_with("warning: ")),
            "{format}: an unprefixed line in {err}"
        );
    }
    let missing = Command::new(env!("CARGO_BIN_EXE_stride-spy"))
        .args(["export", "--out"])
        .arg(dir.path().join("x"))
        .arg(dir.path().join("absent.lcmlog"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&missing.stderr);
    assert_eq!(err.matches("No such file or directory").count(), 1, "{err}");
}
