//! `fake-can-rig`: a USB2CAN dongle on a pseudo-terminal with fake Elmo drives behind it, as a
//! process, for the end-to-end and peer tests. Writes the terminal's path to `--pty-file`,
//! then runs until killed. SIGUSR1 puts the first drive in fault (an over-current), as a bench
//! would. With `--echo`, a node on the same bus answers standard frames 0x6A0..=0x6AF and
//! extended frames 0x1ABCDE00..=0x1ABCDEFF with a frame one identifier up (same data), and a
//! remote request to 0x6B0 (or 0x1ABCDF00) with a data frame of the length asked, 00 01 02 ...

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use clap::Parser;
use serialport::SerialPort;
use stride_canbus::{CanBus, CanFrame, MemBus};
use stride_fakes::dongle::FakeDongle;
use stride_fakes::elmo::{ElmoConfig, FakeElmo, Levers};

/// A fake SLCAN dongle and fake drives.
#[derive(Parser, Debug)]
struct Cli {
    /// Where to write the path of the dongle's terminal.
    #[arg(long)]
    pty_file: std::path::PathBuf,
    /// Node ids of the fake drives (none: `--nodes ''`).
    #[arg(long, value_delimiter = ',', default_value = "1,2,3,4,5,6")]
    nodes: Vec<String>,
    /// The drives power up (and send their boot-up messages) this long after the start, ms.
    #[arg(long, default_value_t = 200)]
    drives_after_ms: u64,
    /// Also put the echo node on the bus.
    #[arg(long)]
    echo: bool,
}

/// The echo node's answer to `f`, if it answers.
fn echo(f: &CanFrame) -> Option<CanFrame> {
    let id = f.raw_id();
    match (f.is_extended(), f.is_remote()) {
        (false, false) if (0x6a0..=0x6af).contains(&id) => {
            CanFrame::standard(id as u16 + 1, f.data()).ok()
        }
        (true, false) if (0x1abc_de00..=0x1abc_deff).contains(&id) => {
            CanFrame::extended(id + 1, f.data()).ok()
        }
        (false, true) if id == 0x6b0 => {
            CanFrame::standard(0x6b0, &(0..f.dlc() as u8).collect::<Vec<_>>()).ok()
        }
        (true, true) if id == 0x1abc_df00 => {
            CanFrame::extended(0x1abc_df00, &(0..f.dlc() as u8).collect::<Vec<_>>()).ok()
        }
        _ => None,
    }
}

fn main() -> anyhow::Result<()> {
    // A device's processor is not held up by the host's load: the fake runs at the
    // real-time priority STRIDE_RT_PRIORITY names, if any.
    if let Err(why) = stride_node::realtime::request_from_env() {
        eprintln!("fake-can-rig: {why}");
    }
    let cli = Cli::parse();
    let nodes: Vec<u8> = cli
        .nodes
        .iter()
        .filter(|s| !s.is_empty())
        .map(|s| s.parse())
        .collect::<Result<_, _>>()?;
    let (mut dongle_end, host_end) = serialport::TTYPort::pair()?;
    dongle_end.set_timeout(Duration::from_millis(2))?;
    let path = host_end.name().unwrap_or_default();
    let bus = MemBus::new(1_000_000);
    let stop = Arc::new(AtomicBool::new(false));
    let _dongle = FakeDongle::new(dongle_end, bus.node()).spawn(stop.clone());
    if cli.echo {
        let mut node = bus.node();
        let stop = stop.clone();
        std::thread::spawn(move || {
            while !stop.load(Ordering::Relaxed) {
                if let Ok(f) = node.recv(Instant::now() + Duration::from_millis(5)) {
                    if let Some(answer) = echo(&f) {
                        let _ = node.send(&answer, Instant::now() + Duration::from_millis(10));
                    }
                }
            }
        });
    }
    std::fs::write(&cli.pty_file, &path)?;
    let fault = Arc::new(AtomicBool::new(false));
    signal_hook::flag::register(signal_hook::consts::SIGUSR1, fault.clone())?;
    std::thread::sleep(Duration::from_millis(cli.drives_after_ms));
    let mut first = Levers::default();
    for (i, &n) in nodes.iter().enumerate() {
        let levers = Levers::default();
        if i == 0 {
            first = levers.clone();
        }
        FakeElmo::new(ElmoConfig::new(n), levers).spawn(bus.node(), stop.clone());
    }
    loop {
        std::thread::sleep(Duration::from_millis(20));
        if fault.swap(false, Ordering::Relaxed) {
            first.fault.store(true, Ordering::Relaxed);
        }
        // Keep the terminal's other end open for as long as the rig runs.
        let _ = &host_end;
    }
}
