//! stride-plan on Archie's scenes: every plan found, an SVG per scene and mode, a CSV of
//! every metric.

use std::process::Command;

use stride_tests::bin;

#[test]
fn stride_plan_writes_pictures_and_metrics() {
    let out = tempfile::tempdir().unwrap();
    let scenes =
        std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../config/scenes/archie");
    let run = Command::new(bin("stride-plan"))
        .arg(&scenes)
        .arg("--out")
        .arg(out.path())
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let csv = std::fs::read_to_string(out.path().join("plans.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    assert_eq!(rows.len(), 33, "11 scenes, 3 modes");
    assert!(
        rows.iter().all(|r| r.split(',').nth(2) == Some("ok")),
        "{csv}"
    );
    let svg = std::fs::read_to_string(out.path().join("archie-09-improved.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    assert!(svg.contains("<polyline") && svg.matches("<polygon").count() > 20);
}

#[test]
fn the_summary_counts_right_refusals_apart_and_never_prints_an_infinite_cost() {
    let dir = tempfile::tempdir().unwrap();
    let scene = |name: &str, goal: (f64, f64), obstacles: &[(f64, f64, f64)]| {
        let mut t = format!(
            "name = \"{name}\"\nstart = {{ x = 0.0, y = 0.0, yaw = 0.0 }}\ngoal = {{ x = {}, y = {} }}\n",
            goal.0, goal.1
        );
        for (x, y, r) in obstacles {
            t += &format!("[[obstacle]]\nshape = \"circle\"\nx = {x}\ny = {y}\nradius = {r}\n");
        }
        std::fs::write(dir.path().join(format!("{name}.toml")), t).unwrap();
    };
    // The goal inside an obstacle, and a goal walled in: both refusals are right.
    scene("x-in-collision", (2.0, 0.0), &[(2.0, 0.0, 0.5)]);
    let ring: Vec<(f64, f64, f64)> = (0..12)
        .map(|k| {
            let a = k as f64 * std::f64::consts::TAU / 12.0;
            (3.0 + 1.0 * a.cos(), 1.0 * a.sin(), 0.4)
        })
        .collect();
    scene("x-walled-in", (3.0, 0.0), &ring);
    let out = dir.path().join("out");
    let run = Command::new(bin("stride-plan"))
        .arg(dir.path())
        .args(["--no-svg", "--table", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&run.stdout);
    assert!(run.status.success(), "{text}");
    assert!(!text.contains("inf"), "{text}");
    assert!(text.contains("0 failures, 6 right refusals"), "{text}");
    assert!(text.contains("not shown (0 of"), "{text}");
}
