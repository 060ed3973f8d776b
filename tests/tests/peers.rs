//! Conformance against third-party peers: python-can's `slcan` interface, python-canopen as a
//! CANopen master (NMT, SDO, PDO, SYNC, the CiA 402 state machine, EMCY) and ROBOTIS's
//! `dynamixel_sdk` (Protocol 1.0 and 2.0) drive the fake devices over pseudo-terminals; and
//! the project's own SLCAN bus and SDO client (and the Elmo master's bring-up) run against
//! python-canopen's LocalNode. What passes here is what a real device's peer software expects
//! of a device, and what a real server expects of our host side.
//!
//! The peers are the pinned packages of `tests/peers/requirements.txt`, which `scripts/test`
//! installs into `target/peers/` (and says so with `STRIDE_REQUIRE_PEERS`, so that a missing
//! install fails here rather than skipping).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use stride_canopen::frame::NodeId;
use stride_canopen::sdo::{AbortCode, SdoError};
use stride_canopen_host::{ignore, sdo_read, sdo_write, HostError};
use stride_tests::{pty_rig, wait_pty, Proc};

/// The peers' Python, or `None` (and a note) when they are not installed.
fn python() -> Option<PathBuf> {
    let p = std::env::var_os("STRIDE_PEERS_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/peers/bin/python")
        });
    if p.exists() {
        return Some(p);
    }
    assert!(
        std::env::var_os("STRIDE_REQUIRE_PEERS").is_none(),
        "the third-party peers are not installed at {} (scripts/test installs them)",
        p.display()
    );
    eprintln!(
        "skipped: no third-party peers at {}; run scripts/test",
        p.display()
    );
    None
}

fn peers_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("peers")
}

/// Runs a peer script with `args`; its report, which must say every check passed.
fn script(py: &Path, name: &str, args: &[&str]) -> String {
    let mut c = Command::new(py);
    c.arg(peers_dir().join(name))
        .args(args)
        .current_dir(peers_dir())
        .env("PYTHONDONTWRITEBYTECODE", "1");
    let (status, out) = Proc::spawn(c).wait(Duration::from_secs(120));
    eprintln!("{out}");
    assert!(status.success(), "{name} failed:\n{out}");
    assert!(out.contains(" 0 failed"), "{out}");
    out
}

#[test]
fn python_can_slcan_drives_the_fake_dongle() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let (_rig, pty) = pty_rig(dir.path(), "fake-can-rig", &["--echo", "--nodes", ""]);
    let out = script(&py, "slcan_pycan.py", &[&pty]);
    assert!(out.contains("listen-only does not transmit"));
}

#[test]
fn python_canopen_masters_the_fake_elmo_drives() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    // The drives boot once python-can has opened the dongle, so their boot-up is seen.
    let (_rig, pty) = pty_rig(
        dir.path(),
        "fake-can-rig",
        &["--nodes", "1,2", "--drives-after-ms", "1500"],
    );
    let out = script(&py, "canopen_master.py", &[&pty]);
    assert!(out.contains("a block upload is refused with 0x05040001"));
}

#[test]
fn dynamixel_sdk_protocol_1_against_a_fake_ax12a_chain() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let (_rig, pty) = pty_rig(
        dir.path(),
        "fake-dynamixel-chain",
        &["--model", "AX-12A", "--ids", "1-18"],
    );
    script(&py, "dxl_p1.py", &[&pty]);
}

#[test]
fn dynamixel_sdk_protocol_2_against_a_fake_xm430_chain() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let (_rig, pty) = pty_rig(
        dir.path(),
        "fake-dynamixel-chain",
        &["--model", "XM430-W350", "--ids", "1-6"],
    );
    script(&py, "dxl_p2.py", &[&pty]);
}

fn aborted(e: HostError) -> AbortCode {
    match e {
        HostError::Sdo(SdoError::Aborted { code, .. }) => code,
        e => panic!("not an abort: {e}"),
    }
}

#[test]
fn our_slcan_bus_and_sdo_client_against_python_canopen_local_node() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let pty_file = dir.path().join("localnode.pty");
    let mut c = Command::new(&py);
    c.arg(peers_dir().join("localnode_server.py"))
        .arg(&pty_file)
        .current_dir(peers_dir())
        .env("PYTHONDONTWRITEBYTECODE", "1");
    let _server = Proc::spawn(c);
    let pty = wait_pty(&pty_file);
    // What slcand does: close, bit rate, open.
    let mut bus = stride_canbus::slcan::open_path(&pty, 1_000_000).unwrap();
    let node = NodeId::new(5).unwrap();
    let t = Duration::from_millis(500);
    let read = |bus: &mut _, i, s| sdo_read(bus, node, i, s, t, &mut ignore);
    assert_eq!(
        read(&mut bus, 0x1000, 0).unwrap(),
        0x0002_0192u32.to_le_bytes()
    );
    assert_eq!(read(&mut bus, 0x1018, 1).unwrap(), 0x9au32.to_le_bytes());
    assert_eq!(
        read(&mut bus, 0x1008, 0).unwrap(),
        b"python-canopen LocalNode"
    );
    for (index, value) in [
        (0x1017u16, 250u32.to_le_bytes()[..2].to_vec()),
        (0x6065, 4321u32.to_le_bytes().to_vec()),
    ] {
        sdo_write(&mut bus, node, index, 0, value.clone(), t, &mut ignore).unwrap();
        assert_eq!(read(&mut bus, index, 0).unwrap(), value, "{index:#06x}");
    }
    // A segmented download and upload of a domain.
    let blob: Vec<u8> = (0..20).collect();
    sdo_write(&mut bus, node, 0x2500, 0, blob.clone(), t, &mut ignore).unwrap();
    assert_eq!(read(&mut bus, 0x2500, 0).unwrap(), blob);
    // Its aborts, decoded.
    assert_eq!(
        aborted(read(&mut bus, 0x2222, 0).unwrap_err()),
        AbortCode::NO_OBJECT
    );
    assert_eq!(
        aborted(read(&mut bus, 0x1018, 9).unwrap_err()),
        AbortCode::NO_SUBINDEX
    );
    assert_eq!(
        aborted(sdo_write(&mut bus, node, 0x1008, 0, b"x".to_vec(), t, &mut ignore).unwrap_err()),
        AbortCode::READ_ONLY
    );
    // The Elmo master's bring-up goes through everything CANopen (identity, heartbeats both
    // ways, windows, the PDO mappings written and read back, NMT start) and stops where an
    // Elmo drive's binary interpreter would answer, which LocalNode has not.
    let joint = stride_elmo::JointConfig {
        name: "j".into(),
        node: 5,
        counts_per_rev: 4096.0,
        gear_ratio: 100.0,
        min_position: -1.0,
        max_position: 1.0,
        max_velocity: 3.0,
        max_acceleration: 30.0,
        tolerance: 0.01,
    };
    let cfg = stride_elmo::MasterConfig {
        sdo_timeout: Duration::from_millis(300),
        ..Default::default()
    };
    let mut m = stride_elmo::Master::new(bus, vec![joint], cfg).unwrap();
    let e = m.bring_up().unwrap_err();
    assert!(
        matches!(&e, stride_elmo::MasterError::NoAnswer { what, .. } if what == "MP[1]=1"),
        "{e}"
    );
}
