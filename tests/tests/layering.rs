//! The layering rule, checked on the workspace's own dependency graph: the robot's algorithms
//! in libs/ know no bus.

use std::collections::{BTreeSet, HashMap};

use serde_json::Value;

/// Crates that put a library on the LCM bus.
const LCM_CRATES: &[&str] = &[
    "lcm",
    "lcm-sys",
    "stride-lcmtypes",
    "stride-node",
    "stride-can-lcm",
];

fn metadata() -> Value {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = std::process::Command::new(cargo)
        .args(["metadata", "--format-version", "1", "--offline"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("cargo metadata runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("cargo metadata prints JSON")
}

/// Every crate `id` depends on to build (normal and build dependencies, transitively).
fn closure(nodes: &HashMap<String, &Value>, id: &str) -> BTreeSet<String> {
    let mut seen = BTreeSet::new();
    let mut todo = vec![id.to_owned()];
    while let Some(n) = todo.pop() {
        for d in nodes[&n]["deps"].as_array().into_iter().flatten() {
            let kinds = d["dep_kinds"].as_array().into_iter().flatten();
            let builds = kinds
                .clone()
                .any(|k| k["kind"].is_null() || k["kind"] == "build");
            let pkg = d["pkg"].as_str().unwrap().to_owned();
            if builds && seen.insert(pkg.clone()) {
                todo.push(pkg);
            }
        }
    }
    seen
}

#[test]
fn no_library_in_libs_depends_on_an_lcm_crate() {
    let m = metadata();
    let root = m["workspace_root"].as_str().unwrap().to_owned();
    let names: HashMap<String, String> = m["packages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            (
                p["id"].as_str().unwrap().to_owned(),
                p["name"].as_str().unwrap().to_owned(),
            )
        })
        .collect();
    let nodes: HashMap<String, &Value> = m["resolve"]["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| (n["id"].as_str().unwrap().to_owned(), n))
        .collect();
    let libs: Vec<&Value> = m["packages"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| {
            p["manifest_path"]
                .as_str()
                .unwrap()
                .starts_with(&format!("{root}/libs/"))
        })
        .collect();
    assert!(libs.len() >= 2, "libs/world and libs/footstep at least");
    for p in libs {
        let id = p["id"].as_str().unwrap();
        let bad: Vec<&String> = closure(&nodes, id)
            .iter()
            .map(|d| &names[d])
            .filter(|n| LCM_CRATES.contains(&n.as_str()))
            .collect();
        assert!(
            bad.is_empty(),
            "{} (libs/) depends on {bad:?}: the algorithms must know no bus",
            p["name"]
        );
    }
}
