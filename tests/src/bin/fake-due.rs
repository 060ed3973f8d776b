//! `fake-due`: the fake Arduino Due board (the firmware's own sketch run on the host, with
//! simulated joints and IMU) on a pseudo-terminal, as a process, for the end-to-end tests. A symlink at `--link` points to the terminal, as
//! `/dev/serial/by-id/` names do. SIGUSR1 pulls the cable and plugs it back a second later (a
//! new terminal behind the same link, a freshly reset board), printing where the joints were. Each time it is plugged in, the
//! board spends `--boot-ms` in its boot loader first, deaf to the link, as a Due does when its
//! port is opened. At SIGINT/SIGTERM it prints which joints are braked.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use clap::Parser;
use stride_fakes::due::{DueConfig, DueLevers, FakeDue};
use stride_serial::{Paced, Port};

/// A fake Due on a pty.
#[derive(Parser, Debug)]
struct Cli {
    /// Where to put the symlink to the terminal.
    #[arg(long)]
    link: PathBuf,
    /// Line baud rate.
    #[arg(long, default_value_t = 115_200)]
    baud: u32,
    /// The board's tilt, roll and pitch in rad.
    #[arg(long, value_delimiter = ',', default_value = "0,0")]
    tilt: Vec<f64>,
    /// Time in the boot loader after each plug-in, ms.
    #[arg(long, default_value_t = 0)]
    boot_ms: u64,
}

fn plug(
    cli: &Cli,
    levers: &DueLevers,
) -> anyhow::Result<(
    Arc<AtomicBool>,
    std::thread::JoinHandle<FakeDue>,
    serialport::TTYPort,
)> {
    let (dev, host_end) = serialport::TTYPort::pair()?;
    let path = serialport::SerialPort::name(&host_end).unwrap_or_default();
    let tmp = cli.link.with_extension("new");
    let _ = std::fs::remove_file(&tmp);
    std::os::unix::fs::symlink(&path, &tmp)?;
    std::fs::rename(&tmp, &cli.link)?;
    // The boot loader: what the host sends meanwhile is lost.
    let mut dev = Port::new(dev, cli.baud);
    let boot_end = std::time::Instant::now() + Duration::from_millis(cli.boot_ms);
    let mut sink = [0u8; 256];
    while std::time::Instant::now() < boot_end {
        let _ = stride_serial::Transport::read_until(&mut dev, &mut sink, boot_end);
    }
    let dev = dev.into_inner();
    let stop = Arc::new(AtomicBool::new(false));
    let board = FakeDue::new(DueConfig::default()).spawn(
        Paced::new(Port::new(dev, cli.baud)),
        levers.clone(),
        stop.clone(),
    );
    Ok((stop, board, host_end))
}

fn main() -> anyhow::Result<()> {
    // A device's processor is not held up by the host's load: the fake runs at the
    // real-time priority STRIDE_RT_PRIORITY names, if any.
    if let Err(why) = stride_node::realtime::request_from_env() {
        eprintln!("fake-due: {why}");
    }
    let cli = Cli::parse();
    let levers = DueLevers::default();
    levers.tilt(cli.tilt[0], *cli.tilt.get(1).unwrap_or(&0.0));
    let quit = Arc::new(AtomicBool::new(false));
    let unplug = Arc::new(AtomicBool::new(false));
    signal_hook::flag::register(signal_hook::consts::SIGTERM, quit.clone())?;
    signal_hook::flag::register(signal_hook::consts::SIGINT, quit.clone())?;
    signal_hook::flag::register(signal_hook::consts::SIGUSR1, unplug.clone())?;
    let (mut stop, mut board, mut host_end) = plug(&cli, &levers)?;
    while !quit.load(Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(10));
        if unplug.swap(false, Ordering::Relaxed) {
            // The cable comes out: the terminal and the link go away.
            stop.store(true, Ordering::Relaxed);
            if let Ok(b) = board.join() {
                let at: Vec<f64> = (0..6).map(|j| b.position(j)).collect();
                println!("unplugged; positions: {at:?}");
            }
            let _ = std::fs::remove_file(&cli.link);
            drop(host_end);
            std::thread::sleep(Duration::from_secs(1));
            (stop, board, host_end) = plug(&cli, &levers)?;
        }
    }
    stop.store(true, Ordering::Relaxed);
    let board = board
        .join()
        .map_err(|_| anyhow::anyhow!("the board panicked"))?;
    let braked: Vec<bool> = (0..6).map(|j| board.braked(j)).collect();
    println!("braked: {braked:?}");
    drop(host_end);
    Ok(())
}
