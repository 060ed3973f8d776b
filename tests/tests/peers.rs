//! Conformance against third-party peers: python-can's `slcan` interface, python-canopen as a
//! CANopen master (NMT, SDO, PDO, SYNC, the CiA 402 state machine, EMCY) and ROBOTIS's
//! `dynamixel_sdk` (Protocol 1.0 and 2.0) drive the fake devices over pseudo-terminals; and
//! the project's own SLCAN bus and SDO client (and the Elmo master's bring-up) run against
//! python-canopen's LocalNode; and python-canopen's client and LocalNode, between themselves,
//! give the frames of segmented SDO transfers that stride's client and server must put on the
//! bus too. What passes here is what a real device's peer software expects of a device, and
//! what a real server expects of our host side.
//!
//! The peers are the pinned packages of `tests/peers/requirements.txt`, which `scripts/test`
//! installs into `target/peers/`. A missing install fails here rather than skipping, unless
//! the caller opts out by name with `STRIDE_SKIP_PEERS=1`.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use stride_canopen::frame::NodeId;
use stride_canopen::sdo::{
    AbortCode, ClientRequest, Dictionary, Download, SdoError, Server, ServerResponse, Step, Upload,
};
use stride_canopen_host::{ignore, sdo_read, sdo_write, HostError};
use stride_tests::{pty_rig, wait_pty, Proc};

/// The peers' Python, or `None` when the caller opted out by name (`STRIDE_SKIP_PEERS=1`).
/// A missing install fails the test: a skip would pass tests that ran nothing.
fn python() -> Option<PathBuf> {
    if std::env::var_os("STRIDE_SKIP_PEERS").is_some_and(|v| v == "1") {
        eprintln!("skipped: STRIDE_SKIP_PEERS=1");
        return None;
    }
    let p = std::env::var_os("STRIDE_PEERS_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/peers/bin/python")
        });
    assert!(
        p.exists(),
        "the third-party peers are not installed at {} (scripts/test installs them; \
         STRIDE_SKIP_PEERS=1 skips these tests by name)",
        p.display()
    );
    Some(p)
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

/// A dictionary for stride's SDO server: 0x1008:00 (read-only) holding a name, 0x2000:00 a
/// writable domain.
struct NameAndDomain {
    name: Vec<u8>,
    domain: Vec<u8>,
}

impl Dictionary for NameAndDomain {
    fn upload(&mut self, index: u16, sub: u8) -> Result<Vec<u8>, AbortCode> {
        match (index, sub) {
            (0x1008, 0) => Ok(self.name.clone()),
            (0x2000, 0) => Ok(self.domain.clone()),
            _ => Err(AbortCode::NO_OBJECT),
        }
    }
    fn may_download(&mut self, index: u16, sub: u8, _: Option<u32>) -> Result<(), AbortCode> {
        match (index, sub) {
            (0x2000, 0) => Ok(()),
            (0x1008, 0) => Err(AbortCode::READ_ONLY),
            _ => Err(AbortCode::NO_OBJECT),
        }
    }
    fn download(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.may_download(index, sub, None)?;
        self.domain = data.to_vec();
        Ok(())
    }
}

/// A client transfer of stride's (first request `req`, answers through `step`) against
/// stride's server, node 1: every frame on the bus as `ID#DATA`.
fn stride_trace(
    od: &mut NameAndDomain,
    mut req: ClientRequest,
    mut step: impl FnMut(&ServerResponse) -> Result<Step, SdoError>,
) -> (Vec<String>, Vec<u8>) {
    let node = NodeId::new(1).unwrap();
    let line = |f: &stride_canopen::CanFrame| {
        let hex: String = f.data().iter().map(|b| format!("{b:02X}")).collect();
        format!("{:03X}#{hex}", f.raw_id())
    };
    let mut server = Server::new();
    let mut lines = Vec::new();
    loop {
        let f = req.encode(node).unwrap();
        lines.push(line(&f));
        let (_, r) = ClientRequest::decode(&f).unwrap();
        let f = server.on_request(&r, od).unwrap().encode(node).unwrap();
        lines.push(line(&f));
        match step(&ServerResponse::decode(&f).unwrap().1).unwrap() {
            Step::Send(r) => req = r,
            Step::Done(d) => return (lines, d),
        }
    }
}

/// python-canopen's client and LocalNode, against each other in one process, write and
/// read the segmented transfers of drivers/canopen/tests/sdo_golden.rs (tests/peers/
/// sdo_frames.py); stride's Download and Upload against stride's Server must put the same
/// frames on the bus, byte for byte.
#[test]
fn segmented_sdo_frames_are_python_canopens() {
    let Some(py) = python() else { return };
    let out = script(&py, "sdo_frames.py", &[]);
    let traces: std::collections::BTreeMap<&str, Vec<String>> = out
        .lines()
        .filter_map(|l| l.strip_prefix("trace "))
        .map(|l| {
            let mut w = l.split_whitespace();
            (w.next().unwrap(), w.map(str::to_owned).collect())
        })
        .collect();
    let downloads: [(&str, &[u8]); 5] = [
        ("download-10", b"0123456789"),
        ("download-7", b"ABCDEFG"),
        ("download-14", b"Harmonica Gold"),
        ("download-13", b"A long string"),
        ("download-0", b""),
    ];
    for (name, data) in downloads {
        let mut od = NameAndDomain {
            name: Vec::new(),
            domain: b"old".to_vec(),
        };
        let mut dl = Download::new(0x2000, 0, data.to_vec());
        let first = dl.start();
        let (lines, _) = stride_trace(&mut od, first, |r| dl.on_response(r));
        assert_eq!(Some(&lines), traces.get(name), "{name}");
        assert_eq!(od.domain, data, "{name}");
    }
    let uploads: [(&str, &[u8]); 2] = [
        ("upload-14", b"Elmo Harmonica"),
        ("upload-26", b"Tiny Node - Mega Domains !"),
    ];
    for (name, text) in uploads {
        let mut od = NameAndDomain {
            name: text.to_vec(),
            domain: Vec::new(),
        };
        let mut up = Upload::new(0x1008, 0, 64);
        let first = up.start();
        let (lines, got) = stride_trace(&mut od, first, |r| up.on_response(r));
        assert_eq!(Some(&lines), traces.get(name), "{name}");
        assert_eq!(got, text, "{name}");
    }
}

#[test]
fn the_preview_controllers_gains_equal_numpys_riccati_solution() {
    // The gains of the ZMP preview controller (integral, state, and the N preview gains),
    // computed by the Rust controller and by an independent NumPy program (the discrete
    // Riccati equation iterated to convergence, the published way), for Archie's COM height
    // and another, at the shipped period, weights and horizon.
    use stride_gait::preview::{Preview, PreviewConfig};
    let Some(py) = python() else { return };
    let numpy =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../libs/gait/benches/preview_numpy.py");
    let cfg = PreviewConfig::default();
    for z_c in [0.6, 0.4] {
        let rust = Preview::new(cfg, z_c, 9.80665).unwrap();
        let mut c = Command::new(&py);
        c.arg(&numpy).args([
            "--gains",
            &format!("--z-c={z_c}"),
            &format!("--horizon={}", cfg.horizon),
            &format!("--dt={}", cfg.period),
            &format!("--q-e={}", cfg.q_e),
            &format!("--r={}", cfg.r),
        ]);
        let (status, out) = Proc::spawn(c).wait(Duration::from_secs(120));
        assert!(status.success(), "{out}");
        let line = out.lines().find(|l| l.starts_with('{')).expect(&out);
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        let num = |v: &serde_json::Value| v.as_f64().unwrap();
        let (gi, gx) = rust.gains();
        let gp = rust.preview_gains();
        let np_gp: Vec<f64> = v["gp"].as_array().unwrap().iter().map(num).collect();
        assert_eq!(gp.len(), np_gp.len(), "z_c {z_c}: N");
        let close = |a: f64, b: f64, scale: f64| (a - b).abs() <= 1e-7 * scale;
        assert!(
            close(gi, num(&v["gi"]), gi.abs()),
            "z_c {z_c}: G_i {gi} against {}",
            v["gi"]
        );
        for (i, g) in gx.iter().enumerate() {
            let n = num(&v["gx"][i]);
            assert!(close(*g, n, g.abs()), "z_c {z_c}: G_x[{i}] {g} against {n}");
        }
        let scale = np_gp.iter().fold(0.0f64, |m, g| m.max(g.abs()));
        for (j, (a, b)) in gp.iter().zip(&np_gp).enumerate() {
            assert!(
                close(*a, *b, scale),
                "z_c {z_c}: G_p({}) {a} against {b}",
                j + 1
            );
        }
        eprintln!(
            "z_c {z_c}: G_i {gi:.6}, G_x {gx:?}, {} preview gains equal",
            gp.len()
        );
    }
}
