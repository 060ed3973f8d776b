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
