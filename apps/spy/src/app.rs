//! The command line of `stride-spy` and its subcommands.

use std::collections::BTreeMap;
use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use clap::Subcommand;
use lcm::{Lcm, LogReader};
use stride_node::outln;

use crate::export::{export_log, Format};
use crate::summary::{render_table, summarize, type_of};
use crate::{channel_filter, message_json};

/// See what is on an LCM bus, or in an LCM log, without a display: channels with their rate,
/// bandwidth and type (recognised by fingerprint), messages decoded as JSON lines, and logs
/// exported to CSV or JSON lines (one file per channel) or to one MCAP file.
///
/// Decoded messages list their members in the order the .lcm file declares them. JSON has no
/// number for NaN or infinity: a float that is NaN, +infinity or -infinity is written as the
/// string "NaN", "inf" or "-inf" (in JSON lines and MCAP) and as the cell NaN, inf or -inf (in
/// CSV), so the three stay apart.
#[derive(clap::Parser, Debug)]
#[command(name = "stride-spy", version, about, long_about)]
pub struct Cli {
    /// LCM URL of the bus (empty: $LCM_DEFAULT_URL, then liblcm's default).
    #[arg(long, env = "STRIDE_LCM_URL", default_value = "", global = true)]
    lcm_url: String,
    /// Log filter: error, warn, info, debug, trace, or a tracing directive. RUST_LOG, when
    /// set, takes precedence.
    #[arg(long, default_value = "warn", global = true)]
    log_level: String,
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// Channels with events, rate, bandwidth and type: live (refreshed every second), or for
    /// a whole log with --log.
    List {
        /// Read this LCM log instead of the live bus.
        #[arg(long)]
        log: Option<PathBuf>,
        /// Only channels matching this regular expression (anchored).
        #[arg(long, default_value = ".*")]
        channel: String,
        /// Stop after this many seconds (live; default: until Ctrl-C).
        #[arg(long)]
        duration: Option<f64>,
    },
    /// Decoded messages as JSON lines, from the live bus or from a log (NaN and infinities as
    /// the strings "NaN", "inf", "-inf").
    Echo {
        /// Read this LCM log instead of the live bus.
        #[arg(long)]
        log: Option<PathBuf>,
        /// Only channels matching this regular expression (anchored).
        #[arg(long, default_value = ".*")]
        channel: String,
        /// Stop after this many messages.
        #[arg(long)]
        count: Option<u64>,
        /// Stop after this many seconds (live).
        #[arg(long)]
        duration: Option<f64>,
    },
    /// Exports a log: one file per channel, CSV (a column per field, in declaration order) or
    /// JSON lines, or one MCAP file for the whole log.
    ///
    /// MCAP: <OUT>/<log name>.mcap (rec.lcmlog gives rec.mcap), a channel per LCM channel,
    /// messages in log order with the log's timestamps as log and publish time. A message of a
    /// type this build knows is JSON (encoding "json") with its type's JSON Schema (encoding
    /// "jsonschema", named after the LCM type); float members are "number" in the schema, and
    /// NaN and infinities the strings "NaN", "inf", "-inf". Foxglove's schema reader takes no
    /// array of arrays, so in MCAP (only) each inner array of a 2-D member sits in an object
    /// under "values" (3-D: nested again): positions: [{"values": [..]}, ..], read as
    /// .positions[2].values[0]. A message it cannot decode keeps its LCM bytes on a channel
    /// with encoding "lcm" and no schema; their count is printed.
    Export {
        /// The LCM log.
        log: PathBuf,
        /// Output directory.
        #[arg(long, short)]
        out: PathBuf,
        /// Output format.
        #[arg(long, value_enum, default_value = "csv")]
        format: Format,
        /// Only channels matching this regular expression (anchored).
        #[arg(long, default_value = ".*")]
        channel: String,
    },
}

/// Runs the subcommand. A closed stdout (`| head`) ends it quietly.
pub fn run(cli: Cli) -> anyhow::Result<std::process::ExitCode> {
    stride_node::check_log_filter(&cli.log_level)?;
    stride_node::init_logging(&cli.log_level);
    match cli.cmd {
        Cmd::List {
            log,
            channel,
            duration,
        } => {
            let filter = channel_filter(&channel)?;
            match log {
                Some(file) => {
                    let rows =
                        summarize(LogReader::open(&file)?.filter(|e| filter.is_match(&e.channel)));
                    if rows.is_empty() {
                        anyhow::bail!("{} holds no events on {channel}", file.display());
                    }
                    write!(std::io::stdout().lock(), "{}", render_table(&rows))?;
                }
                None => live_list(&cli.lcm_url, filter, duration)?,
            }
        }
        Cmd::Echo {
            log,
            channel,
            count,
            duration,
        } => {
            let filter = channel_filter(&channel)?;
            let limit = count.unwrap_or(u64::MAX);
            let mut out = std::io::stdout().lock();
            match log {
                Some(file) => {
                    for e in LogReader::open(&file)?
                        .filter(|e| filter.is_match(&e.channel))
                        .take(limit as usize)
                    {
                        writeln!(out, "{}", message_json(&e.channel, e.timestamp, &e.data))?;
                    }
                }
                None => live_echo(&cli.lcm_url, filter, limit, duration)?,
            }
        }
        Cmd::Export {
            log,
            out,
            format,
            channel,
        } => {
            let filter = channel_filter(&channel)?;
            // liblcm's reader says what it finds wrong with the log's bytes on stderr: taken,
            // and said as warnings of its own.
            // A log that ends torn (or cannot be read past a bad event) is said so: the
            // export holds what came before.
            let (done, liblcm) = lcm::capturing_stderr(|| -> anyhow::Result<_> {
                let files = export_log(&log, &out, format, &filter)?;
                let read: u64 = lcm::LogReader::open(&log)?
                    .map(|e| lcm::event_size(&e))
                    .sum();
                Ok((files, read))
            })?;
            for l in liblcm.iter().take(10) {
                eprintln!("warning: liblcm's log reader: {l}");
            }
            let (files, read) = done?;
            if files.is_empty() {
                anyhow::bail!("{} holds no events on {channel}", log.display());
            }
            let size = std::fs::metadata(&log).map_or(0, |m| m.len());
            if read < size {
                eprintln!(
                    "warning: {} could not be read past byte {read} of {size} (a torn or \
                     unreadable event; {} bytes unread): the export holds what came before",
                    log.display(),
                    size - read
                );
            }
            for c in files {
                let undecoded = match (c.undecoded, format) {
                    (0, _) => String::new(),
                    (n, Format::Mcap) => format!(" ({n} not decoded, kept as LCM bytes)"),
                    (n, _) => format!(" ({n} not decoded)"),
                };
                outln!(
                    "{}: {} messages{undecoded} -> {}",
                    c.channel,
                    c.messages,
                    c.path.display()
                )?;
            }
        }
    }
    Ok(std::process::ExitCode::SUCCESS)
}

fn deadline(duration: Option<f64>) -> Option<Instant> {
    duration.map(|s| Instant::now() + Duration::from_secs_f64(s.max(0.0)))
}

#[derive(Default)]
struct Live {
    total: u64,
    window_count: u64,
    window_bytes: u64,
    type_name: String,
}

fn live_list(url: &str, filter: regex::Regex, duration: Option<f64>) -> anyhow::Result<()> {
    let stop = stride_node::shutdown_on_signals()?;
    let lcm = Lcm::new(url)?;
    let channels: Arc<Mutex<BTreeMap<String, Live>>> = Arc::default();
    let c = channels.clone();
    let _sub = lcm.subscribe_raw(".*", move |info, data| {
        if !filter.is_match(info.channel) {
            return;
        }
        let mut map = c.lock().unwrap_or_else(|p| p.into_inner());
        let live = map.entry(info.channel.to_owned()).or_default();
        if live.total == 0 {
            live.type_name = type_of(data);
        }
        live.total += 1;
        live.window_count += 1;
        live.window_bytes += data.len() as u64;
    })?;
    let end = deadline(duration);
    let tty = std::io::stdout().is_terminal();
    let mut window_start = Instant::now();
    while !stop.load(Ordering::Relaxed)
        && end.is_none_or(|e| Instant::now() < e)
        && !stride_node::stdout_closed()
    {
        lcm.handle_timeout(Duration::from_millis(50))?;
        let elapsed = window_start.elapsed();
        if elapsed < Duration::from_secs(1) {
            continue;
        }
        window_start = Instant::now();
        let mut map = channels.lock().unwrap_or_else(|p| p.into_inner());
        let mut text = String::new();
        if tty {
            text.push_str("\x1b[2J\x1b[H");
        }
        let w = map.keys().map(String::len).max().unwrap_or(0).max(24);
        text += &format!(
            "{:<w$} {:>8} {:>9} {:>10}  {}   ({})\n",
            "channel",
            "events",
            "rate Hz",
            "kB/s",
            "type",
            lcm.url()
        );
        for (name, live) in map.iter_mut() {
            let secs = elapsed.as_secs_f64();
            text += &format!(
                "{:<w$} {:>8} {:>9.1} {:>10.2}  {}\n",
                name,
                live.total,
                live.window_count as f64 / secs,
                live.window_bytes as f64 / secs / 1e3,
                live.type_name
            );
            live.window_count = 0;
            live.window_bytes = 0;
        }
        if !tty {
            text.push('\n');
        }
        let mut out = std::io::stdout().lock();
        out.write_all(text.as_bytes())?;
        out.flush()?;
    }
    Ok(())
}

fn live_echo(
    url: &str,
    filter: regex::Regex,
    limit: u64,
    duration: Option<f64>,
) -> anyhow::Result<()> {
    let stop = stride_node::shutdown_on_signals()?;
    let lcm = Lcm::new(url)?;
    // Messages seen, and the first write error (a closed stdout ends the loop with it).
    let seen = Arc::new(Mutex::new((0u64, None::<std::io::Error>)));
    let s = seen.clone();
    let _sub = lcm.subscribe_raw(".*", move |info, data| {
        let mut st = s.lock().unwrap_or_else(|p| p.into_inner());
        if st.0 >= limit || st.1.is_some() || !filter.is_match(info.channel) {
            return;
        }
        st.0 += 1;
        let line = message_json(info.channel, info.recv_utime, data);
        let mut out = std::io::stdout().lock();
        if let Err(e) = writeln!(out, "{line}").and_then(|()| out.flush()) {
            st.1 = Some(e);
        }
    })?;
    let end = deadline(duration);
    loop {
        {
            let mut st = seen.lock().unwrap_or_else(|p| p.into_inner());
            if let Some(e) = st.1.take() {
                return Err(e.into());
            }
            if st.0 >= limit {
                return Ok(());
            }
        }
        if stop.load(Ordering::Relaxed)
            || end.is_some_and(|e| Instant::now() >= e)
            || stride_node::stdout_closed()
        {
            return Ok(());
        }
        lcm.handle_timeout(Duration::from_millis(50))?;
    }
}
