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
    // The workspace's own manifests are enough (no crate outside it depends on ours), and
    // need nothing downloaded: the tests run without a network.
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = std::process::Command::new(cargo)
        .args([
            "metadata",
            "--format-version",
            "1",
            "--no-deps",
            "--offline",
        ])
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

#[test]
fn no_library_in_libs_depends_on_an_lcm_crate() {
    let m = metadata();
    let root = m["workspace_root"].as_str().unwrap().to_owned();
    let packages = m["packages"].as_array().unwrap();
    // Each workspace crate's normal and build dependencies, by name.
    let deps: HashMap<String, Vec<String>> = packages
        .iter()
        .map(|p| {
            let names = p["dependencies"]
                .as_array()
                .into_iter()
                .flatten()
                .filter(|d| d["kind"].is_null() || d["kind"] == "build")
                .map(|d| d["name"].as_str().unwrap().to_owned())
                .collect();
            (p["name"].as_str().unwrap().to_owned(), names)
        })
        .collect();
    let closure = |from: &str| {
        let mut seen = BTreeSet::new();
        let mut todo = vec![from.to_owned()];
        while let Some(n) = todo.pop() {
            for d in deps.get(&n).into_iter().flatten() {
                if seen.insert(d.clone()) {
                    todo.push(d.clone());
                }
            }
        }
        seen
    };
    let libs: Vec<&str> = packages
        .iter()
        .filter(|p| {
            p["manifest_path"]
                .as_str()
                .unwrap()
                .starts_with(&format!("{root}/libs/"))
        })
        .map(|p| p["name"].as_str().unwrap())
        .collect();
    assert!(libs.len() >= 2, "libs/world and libs/footstep at least");
    for name in libs {
        let bad: Vec<String> = closure(name)
            .into_iter()
            .filter(|n| LCM_CRATES.contains(&n.as_str()))
            .collect();
        assert!(
            bad.is_empty(),
            "{name} (libs/) depends on {bad:?}: the algorithms must know no bus"
        );
    }
}
