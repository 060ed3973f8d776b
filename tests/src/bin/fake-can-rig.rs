//! `fake-can-rig`: a USB2CAN dongle on a pseudo-terminal with fake Elmo drives behind it, as a
//! process, for the end-to-end tests. Writes the terminal's path to `--pty-file`, then runs
//! until killed. SIGUSR1 puts the first drive in fault (an over-current), as a bench would.

use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use clap::Parser;
use serialport::SerialPort;
use stride_canbus::MemBus;
use stride_fakes::dongle::FakeDongle;
use stride_fakes::elmo::{ElmoConfig, FakeElmo, Levers};

/// A fake SLCAN dongle and fake drives.
#[derive(Parser, Debug)]
struct Cli {
    /// Where to write the path of the dongle's terminal.
    #[arg(long)]
    pty_file: std::path::PathBuf,
    /// Node ids of the fake drives.
    #[arg(long, value_delimiter = ',', default_value = "1,2,3,4,5,6")]
    nodes: Vec<u8>,
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    let (mut dongle_end, host_end) = serialport::TTYPort::pair()?;
    dongle_end.set_timeout(Duration::from_millis(2))?;
    let path = host_end.name().unwrap_or_default();
    let bus = MemBus::new(1_000_000);
    let stop = Arc::new(AtomicBool::new(false));
    let _dongle = FakeDongle::new(dongle_end, bus.node()).spawn(stop.clone());
    // The drives power up once the dongle is open (the gateway opened it).
    std::fs::write(&cli.pty_file, &path)?;
    let fault = Arc::new(AtomicBool::new(false));
    signal_hook::flag::register(signal_hook::consts::SIGUSR1, fault.clone())?;
    let mut started = false;
    let mut first = Levers::default();
    loop {
        std::thread::sleep(Duration::from_millis(200));
        if !started {
            started = true;
            for (i, &n) in cli.nodes.iter().enumerate() {
                let levers = Levers::default();
                if i == 0 {
                    first = levers.clone();
                }
                FakeElmo::new(ElmoConfig::new(n), levers).spawn(bus.node(), stop.clone());
            }
        }
        if fault.swap(false, std::sync::atomic::Ordering::Relaxed) {
            first
                .fault
                .store(true, std::sync::atomic::Ordering::Relaxed);
        }
        // Keep the terminal's other end open for as long as the rig runs.
        let _ = &host_end;
    }
}
