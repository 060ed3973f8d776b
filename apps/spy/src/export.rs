//! Export of a log: one file per channel, CSV (one column per scalar, in declaration order;
//! short arrays spread over columns, long ones kept as a JSON cell) or JSON lines; or one MCAP
//! file for the whole log ([`crate::mcap_export`]).
//!
//! Floats that are NaN or infinite are the strings `"NaN"`, `"inf"`, `"-inf"` in JSON and the
//! cells `NaN`, `inf`, `-inf` in CSV.

use std::collections::{BTreeMap, HashMap};
use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::Context;
use serde_json::Value;

/// Arrays longer than this stay one JSON cell in CSV instead of one column per element.
pub const MAX_SPREAD_ARRAY: usize = 16;

/// The output format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// Comma-separated values with a header row, a file per channel (CHANNEL.csv).
    Csv,
    /// One JSON object per line, a file per channel (CHANNEL.jsonl).
    Json,
    /// One MCAP file for the whole log (LOG.mcap): JSON messages with their JSON Schemas.
    Mcap,
}

/// What the export wrote for one channel.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ChannelExport {
    /// The LCM channel.
    pub channel: String,
    /// The file its messages went to.
    pub path: PathBuf,
    /// Messages written.
    pub messages: u64,
    /// Of those, messages this build could not decode (unknown type, or broken).
    pub undecoded: u64,
}

/// A channel's CSV columns, in order, and where each one is.
#[derive(Debug, Default)]
struct Columns {
    order: Vec<String>,
    index: HashMap<String, usize>,
}

impl Columns {
    /// Adds a row's columns: one not seen before goes right after the row's previous column,
    /// so columns keep the rows' order (declaration order) even when a later row has more
    /// array elements.
    fn merge<'a>(&mut self, row: impl Iterator<Item = &'a str>) {
        let mut prev: Option<usize> = None;
        for k in row {
            let i = match self.index.get(k) {
                Some(&i) => i,
                None => {
                    let i = prev.map_or(self.order.len(), |p| p + 1);
                    for j in self.index.values_mut() {
                        if *j >= i {
                            *j += 1;
                        }
                    }
                    self.order.insert(i, k.to_owned());
                    self.index.insert(k.to_owned(), i);
                    i
                }
            };
            prev = Some(i);
        }
    }
}

/// Flattens a JSON value into `(column, cell)` pairs: `a.b`, `a[0]`, ...
pub fn flatten(prefix: &str, v: &Value, out: &mut Vec<(String, String)>) {
    match v {
        Value::Object(map) => {
            for (k, x) in map {
                let key = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                flatten(&key, x, out);
            }
        }
        Value::Array(a) if a.len() <= MAX_SPREAD_ARRAY => {
            for (i, x) in a.iter().enumerate() {
                flatten(&format!("{prefix}[{i}]"), x, out);
            }
        }
        Value::String(s) => out.push((prefix.to_owned(), s.clone())),
        Value::Null => out.push((prefix.to_owned(), String::new())),
        other => out.push((prefix.to_owned(), other.to_string())),
    }
}

fn file_name(channel: &str, ext: &str) -> String {
    let safe: String = channel
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    format!("{safe}.{ext}")
}

/// Writes the log's messages on channels matching `filter` into `dir`: a file per channel
/// (CSV, JSON lines) or one MCAP file; returns what went where, by channel.
pub fn export_log(
    log: &Path,
    dir: &Path,
    format: Format,
    filter: &regex::Regex,
) -> anyhow::Result<Vec<ChannelExport>> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    if format == Format::Mcap {
        return crate::mcap_export::export_mcap(
            log,
            &crate::mcap_export::mcap_path(log, dir),
            filter,
        );
    }
    let events = || -> anyhow::Result<_> {
        Ok(lcm::LogReader::open(log)?.filter(|e| filter.is_match(&e.channel)))
    };
    // A message's cells, and whether it decoded.
    let rows_of = |e: &lcm::LogEvent| -> (Vec<(String, String)>, bool) {
        let v = crate::message_json(&e.channel, e.timestamp, &e.data);
        let mut cells = vec![
            ("event".to_owned(), e.number.to_string()),
            ("log_utime".to_owned(), e.timestamp.to_string()),
        ];
        match v.get("message") {
            Some(m) => {
                flatten("", m, &mut cells);
                (cells, true)
            }
            None => {
                cells.push(("size".into(), e.data.len().to_string()));
                if let Some(err) = v.get("error").and_then(Value::as_str) {
                    cells.push(("error".into(), err.to_owned()));
                }
                (cells, false)
            }
        }
    };
    let mut counts: BTreeMap<String, ChannelExport> = BTreeMap::new();
    let mut count = |channel: &str, path: &Path, decoded: bool| {
        let c = counts
            .entry(channel.to_owned())
            .or_insert_with(|| ChannelExport {
                channel: channel.to_owned(),
                path: path.to_owned(),
                messages: 0,
                undecoded: 0,
            });
        c.messages += 1;
        c.undecoded += u64::from(!decoded);
    };
    match format {
        Format::Json => {
            let mut files: HashMap<String, (PathBuf, std::io::BufWriter<std::fs::File>)> =
                HashMap::new();
            for e in events()? {
                if !files.contains_key(&e.channel) {
                    let path = dir.join(file_name(&e.channel, "jsonl"));
                    let f = std::fs::File::create(&path)
                        .with_context(|| format!("creating {}", path.display()))?;
                    files.insert(e.channel.clone(), (path, std::io::BufWriter::new(f)));
                }
                let v = crate::message_json(&e.channel, e.timestamp, &e.data);
                let (path, f) = files.get_mut(&e.channel).expect("opened");
                writeln!(f, "{v}")?;
                count(&e.channel, path, v.get("message").is_some());
            }
            for (_, (_, mut f)) in files {
                f.flush()?;
            }
        }
        Format::Csv => {
            // First pass: the columns of each channel, in the rows' order.
            let mut columns: HashMap<String, Columns> = HashMap::new();
            for e in events()? {
                let c = columns.entry(e.channel.clone()).or_default();
                c.merge(rows_of(&e).0.iter().map(|(k, _)| k.as_str()));
            }
            let mut writers: HashMap<String, (PathBuf, csv::Writer<std::fs::File>)> =
                HashMap::new();
            for e in events()? {
                let Columns { order, index } = &columns[&e.channel];
                if !writers.contains_key(&e.channel) {
                    let path = dir.join(file_name(&e.channel, "csv"));
                    let mut w = csv::Writer::from_path(&path)
                        .with_context(|| format!("creating {}", path.display()))?;
                    w.write_record(order)?;
                    writers.insert(e.channel.clone(), (path, w));
                }
                let (cells, decoded) = rows_of(&e);
                let mut row = vec![String::new(); order.len()];
                for (k, v) in cells {
                    row[index[&k]] = v;
                }
                let (path, w) = writers.get_mut(&e.channel).expect("opened");
                w.write_record(&row)?;
                count(&e.channel, path, decoded);
            }
            for (_, (_, mut w)) in writers {
                w.flush()?;
            }
        }
        Format::Mcap => unreachable!("exported above"),
    }
    Ok(counts.into_values().collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use lcm::Message;
    use stride_lcmtypes::stride::{JointStateT, PingT};

    #[test]
    fn flatten_spreads_short_arrays_only() {
        let v = serde_json::json!({"a": {"b": 1}, "s": "x", "short": [1, 2], "long": vec![0; 20]});
        let mut out = Vec::new();
        flatten("", &v, &mut out);
        let keys: Vec<_> = out.iter().map(|(k, _)| k.as_str()).collect();
        assert_eq!(keys, ["a.b", "s", "short[0]", "short[1]", "long"]);
    }

    #[test]
    fn new_columns_go_after_their_row_neighbour() {
        let mut c = Columns::default();
        c.merge(["event", "a[0]", "b[0]", "c"].into_iter());
        c.merge(["event", "a[0]", "a[1]", "b[0]", "b[1]", "c"].into_iter());
        c.merge(["event", "size"].into_iter());
        let want = ["event", "size", "a[0]", "a[1]", "b[0]", "b[1]", "c"];
        assert_eq!(c.order, want);
        for (i, k) in want.iter().enumerate() {
            assert_eq!(c.index[*k], i, "{k}");
        }
    }

    #[test]
    fn exports_csv_and_json_per_channel() {
        let dir = tempfile::tempdir().unwrap();
        let log = dir.path().join("x.lcmlog");
        let mut w = lcm::LogWriter::create(&log).unwrap();
        for i in 0..3 {
            let js = JointStateT {
                num_joints: 2,
                names: vec!["a".into(), "b".into()],
                positions: vec![i as f64, -1.0],
                velocities: vec![0.0; 2],
                currents: vec![0.0; 2],
                temperatures: vec![20.0; 2],
                faults: vec![0; 2],
                ..Default::default()
            };
            w.write(1000 + i, "JOINT_STATE", &js.encode().unwrap())
                .unwrap();
            w.write(1000 + i, "PING", &PingT::default().encode().unwrap())
                .unwrap();
            w.write(1000 + i, "RAW", b"not lcm").unwrap();
        }
        drop(w);
        let all = crate::channel_filter(".*").unwrap();
        let out = dir.path().join("csv");
        let files = export_log(&log, &out, Format::Csv, &all).unwrap();
        assert_eq!(files.len(), 3);
        let text = std::fs::read_to_string(out.join("JOINT_STATE.csv")).unwrap();
        let mut lines = text.lines();
        let header = lines.next().unwrap();
        assert!(header.starts_with("event,log_utime,"), "{header}");
        assert!(header.contains("positions[1]"), "{header}");
        assert_eq!(lines.count(), 3);
        let raw = std::fs::read_to_string(out.join("RAW.csv")).unwrap();
        assert!(raw.starts_with("event,log_utime,size"), "{raw}");

        let only = crate::channel_filter("PING").unwrap();
        let out = dir.path().join("json");
        let files = export_log(&log, &out, Format::Json, &only).unwrap();
        assert_eq!(files.len(), 1);
        let text = std::fs::read_to_string(out.join("PING.jsonl")).unwrap();
        assert_eq!(text.lines().count(), 3);
        assert!(text.contains("\"type\":\"stride.ping_t\""));
    }
}
