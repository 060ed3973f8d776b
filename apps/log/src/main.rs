//! `stride-log`: what is in an LCM event log.

use std::path::PathBuf;

use clap::{Parser, Subcommand};
use lcm::LogReader;

/// Inspect LCM event logs (the files lcm-logger writes).
#[derive(Parser, Debug)]
#[command(version, about, long_about)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// Per channel: events, bytes, mean rate and message type (recognised by fingerprint).
    Summary {
        /// The log file.
        file: PathBuf,
    },
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    stride_node::init_logging("warn");
    match cli.cmd {
        Cmd::Summary { file } => {
            let rows = stride_log::summarize(LogReader::open(&file)?);
            if rows.is_empty() {
                anyhow::bail!("{} holds no events", file.display());
            }
            print!("{}", stride_log::render_table(&rows));
        }
    }
    Ok(())
}
