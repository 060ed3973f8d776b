//! `stride-report`: a walk's report from an lcm-logger log, as one self-contained HTML page.
//!
//! What it shows, from whatever the log holds:
//! - a top view (SVG): the map's extent, the obstacles, every plan's footsteps, the feet as
//!   they touched down, the body's trace and the goal;
//! - the elevation map (PNG);
//! - each joint's tracking (SVG): the rows commanded against the positions the drives
//!   measured, and the error between them;
//! - latencies (SVG histograms): from a plan request to its plan, and for every channel from
//!   the message's header stamp to its arrival at the logger.
//!
//! A log that ends in a torn event, channels of unknown types and missing channels give a
//! partial report and a warning, never an error; a log that cannot be opened is one.

mod data;
mod png;
mod render;

pub use data::{read_log, Data};
pub use png::{base64, gray_png};
pub use render::html;

use std::path::PathBuf;
use std::process::ExitCode;

/// A walk's report from an lcm-logger log (e.g. `scripts/demo`'s out/demo/demo.lcmlog): a top
/// view of the map, obstacles, planned and executed footsteps and the body's trace; the
/// elevation map; each joint's tracking (commanded rows against the drives' positions, and
/// the error); latency histograms (plan request to plan, and header stamp to arrival for
/// every channel). One self-contained HTML page (SVG and PNG inside), opened by nobody: the
/// command prints where it is. A torn log end, unknown channels and missing data give a
/// partial report and a warning.
#[derive(clap::Parser, Debug)]
#[command(name = "stride-report", version, about, long_about)]
pub struct Cli {
    /// The lcm-logger log.
    log: PathBuf,
    /// Where to write the page (default: the log's path with .html).
    #[arg(long, short)]
    out: Option<PathBuf>,
}

/// Runs the command line.
pub fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    // liblcm's reader says what it finds wrong with a log's bytes on stderr: taken, and said
    // as a warning of its own.
    let (data, liblcm) = lcm::capturing_stderr(|| read_log(&cli.log))?;
    let mut data = data?;
    data.warnings.extend(
        liblcm
            .into_iter()
            .map(|l| format!("liblcm's log reader: {l}")),
    );
    if data.events == 0 {
        anyhow::bail!(
            "{} holds no LCM event: nothing to report (an empty file, or not an lcm-logger log)",
            cli.log.display()
        );
    }
    let page = html(&data, &cli.log.display().to_string());
    let out = cli.out.unwrap_or_else(|| cli.log.with_extension("html"));
    std::fs::write(&out, page)
        .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", out.display()))?;
    for w in &data.warnings {
        eprintln!("warning: {w}");
    }
    stride_node::outln!(
        "report of {} events ({} channels{}): {}",
        data.events,
        data.channels.len(),
        if data.warnings.is_empty() {
            String::new()
        } else {
            format!(", {} warnings", data.warnings.len())
        },
        out.display()
    )?;
    Ok(ExitCode::SUCCESS)
}
