//! The JSON form of the generated types (`to_json`, `decode_json`) and its schema
//! (`JSON_SCHEMA`), and the MCAP form with arrays of arrays wrapped (`decode_nested_json`,
//! `nested_json_schema`). Needs the features `json` and `random`.

use lcm::{Message, Random, Rng};
use serde_json::{json, Value};
use stride_lcmtypes::stride::*;
use stride_lcmtypes::{
    decode_json, decode_nested_json, json_float, json_schema, nested_json_schema,
    wrap_nested_arrays, TYPES,
};

fn keys(v: &Value) -> Vec<&str> {
    v.as_object().unwrap().keys().map(String::as_str).collect()
}

#[test]
fn nan_and_infinities_are_distinct_strings_not_null() {
    let imu = ImuT {
        orientation: [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, -0.5],
        angular_velocity: [1e300, f64::MIN_POSITIVE, -0.0],
        temperature: f32::NAN,
        ..Default::default()
    };
    let v = imu.to_json();
    assert_eq!(v["orientation"], json!(["NaN", "inf", "-inf", -0.5]));
    assert_eq!(
        v["angular_velocity"],
        json!([1e300, f64::MIN_POSITIVE, -0.0])
    );
    assert_eq!(v["temperature"], "NaN");
    let cloud = PointCloudT {
        num_points: 2,
        points: vec![
            [f32::INFINITY, 0.25, 1.0],
            [f32::NEG_INFINITY, f32::NAN, 0.1],
        ],
        ..Default::default()
    };
    let v = cloud.to_json();
    assert_eq!(
        v["points"],
        json!([["inf", 0.25, 1.0], ["-inf", "NaN", f64::from(0.1f32)]])
    );
    assert_eq!(json_float(f64::NAN), "NaN");
    assert_eq!(json_float(2.5), 2.5);
    // Through decode_json too, as stride-spy sees messages.
    let (ty, v) = decode_json(&imu.encode().unwrap()).unwrap();
    assert_eq!(ty, "stride.imu_t");
    let text = v.unwrap().to_string();
    assert!(
        text.contains(r#""orientation":["NaN","inf","-inf",-0.5]"#),
        "{text}"
    );
    assert!(!text.contains("null"), "{text}");
}

#[test]
fn members_come_in_declaration_order() {
    let js = JointStateT {
        num_joints: 1,
        names: vec!["hip".into()],
        positions: vec![0.5],
        velocities: vec![0.0],
        currents: vec![0.0],
        temperatures: vec![30.0],
        faults: vec![0],
        ..Default::default()
    };
    let v = js.to_json();
    assert_eq!(
        keys(&v),
        [
            "header",
            "num_joints",
            "names",
            "positions",
            "velocities",
            "currents",
            "temperatures",
            "faults"
        ]
    );
    assert_eq!(keys(&v["header"]), ["utime", "sequence", "frame"]);
    let text = decode_json(&js.encode().unwrap())
        .unwrap()
        .1
        .unwrap()
        .to_string();
    assert!(
        text.starts_with(
            r#"{"header":{"utime":0,"sequence":0,"frame":""},"num_joints":1,"names":"#
        ),
        "{text}"
    );
}

/// Checks `v` against `schema` for the keywords the generated schemas use; float members
/// (`number`) may also be one of the three non-finite strings.
fn check(root: &Value, schema: &Value, v: &Value, path: &str) {
    if let Some(r) = schema.get("$ref").and_then(Value::as_str) {
        let target = root
            .pointer(r.trim_start_matches('#'))
            .expect("a resolvable $ref");
        return check(root, target, v, path);
    }
    let ty = schema["type"]
        .as_str()
        .unwrap_or_else(|| panic!("{path}: no type"));
    match ty {
        "object" => {
            let props = schema["properties"].as_object().unwrap();
            let obj = v
                .as_object()
                .unwrap_or_else(|| panic!("{path}: not an object"));
            let names: Vec<&str> = props.keys().map(String::as_str).collect();
            assert_eq!(keys(v), names, "{path}: members or their order");
            let required: Vec<&str> = schema["required"]
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_str().unwrap())
                .collect();
            assert_eq!(required, names, "{path}: required");
            assert_eq!(schema["additionalProperties"], false);
            for (k, s) in props {
                check(root, s, &obj[k], &format!("{path}.{k}"));
            }
        }
        "array" => {
            let a = v
                .as_array()
                .unwrap_or_else(|| panic!("{path}: not an array"));
            if let Some(n) = schema.get("minItems") {
                assert_eq!(a.len() as u64, n.as_u64().unwrap(), "{path}");
                assert_eq!(schema["maxItems"], *n);
            }
            for (i, x) in a.iter().enumerate() {
                check(root, &schema["items"], x, &format!("{path}[{i}]"));
            }
        }
        "integer" => {
            let (min, max) = (&schema["minimum"], &schema["maximum"]);
            if let Some(x) = v.as_i64() {
                assert!(
                    x >= min.as_i64().unwrap() && x <= max.as_i64().unwrap(),
                    "{path}"
                );
            } else {
                let x = v
                    .as_u64()
                    .unwrap_or_else(|| panic!("{path}: not an integer: {v}"));
                assert!(x <= max.as_u64().unwrap(), "{path}");
            }
        }
        "number" => assert!(
            v.is_f64() || matches!(v.as_str(), Some("NaN" | "inf" | "-inf")),
            "{path}: not a float: {v}"
        ),
        "string" => assert!(v.is_string(), "{path}"),
        "boolean" => assert!(v.is_boolean(), "{path}"),
        other => panic!("{path}: type {other}"),
    }
}

fn check_type<M: Message + Random>(rng: &mut Rng, to_json: fn(&M) -> Value) -> &'static str {
    let schema: Value = serde_json::from_str(json_schema(M::TYPE_NAME).unwrap()).unwrap();
    assert_eq!(schema["title"], M::TYPE_NAME);
    assert!(schema["$comment"].as_str().unwrap().contains("\"NaN\""));
    let nested: Value = serde_json::from_str(&nested_json_schema(M::TYPE_NAME).unwrap()).unwrap();
    assert_eq!(nested["title"], M::TYPE_NAME);
    for _ in 0..20 {
        rng.set_budget(Rng::DEFAULT_BUDGET);
        let m = M::random(rng);
        let v = to_json(&m);
        check(&schema, &schema, &v, M::TYPE_NAME);
        let data = m.encode().unwrap();
        let (name, decoded) = decode_json(&data).unwrap();
        assert_eq!(name, M::TYPE_NAME);
        assert_eq!(decoded.unwrap(), v);
        // The MCAP form: the same values, arrays of arrays wrapped, against its own schema.
        let w = wrap_nested_arrays(v.clone());
        check(&nested, &nested, &w, M::TYPE_NAME);
        unwrapped_equals(&w, &v, M::TYPE_NAME);
        let (name, decoded) = decode_nested_json(&data).unwrap();
        assert_eq!(name, M::TYPE_NAME);
        assert_eq!(decoded.unwrap(), w);
    }
    M::TYPE_NAME
}

/// `wrapped` is `plain` value by value, each inner array of an array of arrays in an object
/// `{"values": <it>}` and nothing else changed.
fn unwrapped_equals(wrapped: &Value, plain: &Value, path: &str) {
    match (wrapped, plain) {
        (Value::Object(w), Value::Object(p)) => {
            assert_eq!(keys(wrapped), keys(plain), "{path}");
            for (k, x) in p {
                unwrapped_equals(&w[k], x, &format!("{path}.{k}"));
            }
        }
        (Value::Array(w), Value::Array(p)) => {
            assert_eq!(w.len(), p.len(), "{path}");
            for (i, (x, y)) in w.iter().zip(p).enumerate() {
                let at = format!("{path}[{i}]");
                if y.is_array() {
                    assert_eq!(keys(x), ["values"], "{at}");
                    unwrapped_equals(&x["values"], y, &format!("{at}.values"));
                } else {
                    assert!(!x.is_array(), "{at}");
                    unwrapped_equals(x, y, &at);
                }
            }
        }
        (w, p) => assert_eq!(w, p, "{path}"),
    }
}

/// Fails on any array schema whose `items` is an array schema, anywhere in `schema`.
fn no_array_of_arrays(schema: &Value, path: &str) {
    match schema {
        Value::Object(m) => {
            if m.get("type") == Some(&json!("array")) {
                let items = &m["items"];
                assert_ne!(items["type"], "array", "{path}: an array of arrays");
            }
            for (k, v) in m {
                no_array_of_arrays(v, &format!("{path}/{k}"));
            }
        }
        Value::Array(a) => {
            for (i, v) in a.iter().enumerate() {
                no_array_of_arrays(v, &format!("{path}/{i}"));
            }
        }
        _ => {}
    }
}

#[test]
fn mcap_schemas_have_no_array_of_arrays() {
    let mut wrapped = Vec::new();
    for (name, _) in TYPES {
        let text = nested_json_schema(name).unwrap_or_else(|| panic!("no MCAP schema for {name}"));
        let schema: Value = serde_json::from_str(&text).unwrap();
        no_array_of_arrays(&schema, name);
        let plain: Value = serde_json::from_str(json_schema(name).unwrap()).unwrap();
        if schema != plain {
            wrapped.push(*name);
        }
    }
    wrapped.sort_unstable();
    // Every type with a multi-dimensional array, directly or through a member.
    assert_eq!(
        wrapped,
        [
            "stride.joint_trajectory_t",
            "stride.obstacle_list_t",
            "stride.obstacle_t",
            "stride.point_cloud_t",
            "stride.sim_report_t"
        ]
    );
    assert_eq!(nested_json_schema("stride.no_such_t"), None);
    let cloud = PointCloudT {
        num_points: 2,
        points: vec![[1.0, 2.0, 3.0], [f32::INFINITY, 0.5, -1.0]],
        ..Default::default()
    };
    let v = wrap_nested_arrays(cloud.to_json());
    assert_eq!(
        v["points"],
        json!([{"values": [1.0, 2.0, 3.0]}, {"values": ["inf", 0.5, -1.0]}])
    );
}

#[test]
fn every_type_matches_its_json_schema() {
    let mut rng = Rng::new(7);
    let mut seen = Vec::new();
    macro_rules! all {
        ($($t:ident),* $(,)?) => { $( seen.push(check_type::<$t>(&mut rng, $t::to_json)); )* };
    }
    all!(
        ArduinoJointStateT,
        CanBusStatusT,
        CanFrameBatchT,
        CanFrameT,
        DynamixelStateT,
        ElevationMapT,
        FootT,
        FootstepPlanRequestT,
        FootstepPlanT,
        FootstepT,
        GaitCommandT,
        HeaderT,
        ImageT,
        ImuT,
        JointCommandT,
        JointStateT,
        JointTrajectoryT,
        LaunchAppT,
        LaunchConsoleT,
        LaunchOrderT,
        LaunchStatusT,
        NodeStatusT,
        ObstacleListT,
        ObstacleT,
        OdometryT,
        PingT,
        PointCloudT,
        PoseStampedT,
        PoseT,
        SimReportT,
        StepCounterT,
        StereoImageT,
        TrajectoryStatusT,
        WalkParamsT,
    );
    let mut all: Vec<&str> = TYPES.iter().map(|(n, _)| *n).collect();
    all.sort_unstable();
    seen.sort_unstable();
    assert_eq!(seen, all, "every type is checked");
    assert_eq!(json_schema("stride.no_such_t"), None);
}
