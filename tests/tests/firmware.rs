//! The Due firmware and the link's C codec compile cleanly (`scripts/firmware`: with
//! arduino-cli when installed, else on the host against stub Arduino headers).

use std::path::PathBuf;
use std::process::Command;

#[test]
fn the_due_firmware_builds() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let out = Command::new("bash")
        .arg(root.join("scripts/firmware"))
        .output()
        .expect("running scripts/firmware");
    assert!(
        out.status.success(),
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}
