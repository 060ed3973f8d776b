//! Export of a log, one file per channel: CSV (one column per scalar; short arrays spread over
//! columns, long ones kept as a JSON cell) or JSON lines.

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
    /// Comma-separated values with a header row.
    Csv,
    /// One JSON object per line.
    Json,
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

/// Writes one file per channel of the log into `dir`; returns `(channel, file, rows)`.
pub fn export_log(
    log: &Path,
    dir: &Path,
    format: Format,
    filter: &regex::Regex,
) -> anyhow::Result<Vec<(String, PathBuf, u64)>> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let events = || -> anyhow::Result<_> {
        Ok(lcm::LogReader::open(log)?.filter(|e| filter.is_match(&e.channel)))
    };
    let rows_of = |e: &lcm::LogEvent| -> Vec<(String, String)> {
        let v = crate::message_json(&e.channel, e.timestamp, &e.data);
        let mut cells = vec![
            ("event".to_owned(), e.number.to_string()),
            ("log_utime".to_owned(), e.timestamp.to_string()),
        ];
        match v.get("message") {
            Some(m) => flatten("", m, &mut cells),
            None => {
                cells.push(("size".into(), e.data.len().to_string()));
                if let Some(err) = v.get("error").and_then(Value::as_str) {
                    cells.push(("error".into(), err.to_owned()));
                }
            }
        }
        cells
    };
    let mut counts: BTreeMap<String, (PathBuf, u64)> = BTreeMap::new();
    match format {
        Format::Json => {
            let mut files: HashMap<String, std::io::BufWriter<std::fs::File>> = HashMap::new();
            for e in events()? {
                if !files.contains_key(&e.channel) {
                    let path = dir.join(file_name(&e.channel, "jsonl"));
                    let f = std::fs::File::create(&path)
                        .with_context(|| format!("creating {}", path.display()))?;
                    files.insert(e.channel.clone(), std::io::BufWriter::new(f));
                    counts.insert(e.channel.clone(), (path, 0));
                }
                let v = crate::message_json(&e.channel, e.timestamp, &e.data);
                writeln!(files.get_mut(&e.channel).expect("opened"), "{v}")?;
                counts.get_mut(&e.channel).expect("counted").1 += 1;
            }
            for (_, mut f) in files {
                f.flush()?;
            }
        }
        Format::Csv => {
            // First pass: the columns of each channel, in order of first appearance.
            let mut columns: HashMap<String, (Vec<String>, HashMap<String, usize>)> =
                HashMap::new();
            for e in events()? {
                let (order, index) = columns.entry(e.channel.clone()).or_default();
                for (k, _) in rows_of(&e) {
                    if !index.contains_key(&k) {
                        index.insert(k.clone(), order.len());
                        order.push(k);
                    }
                }
            }
            let mut writers: HashMap<String, csv::Writer<std::fs::File>> = HashMap::new();
            for e in events()? {
                let (order, index) = &columns[&e.channel];
                if !writers.contains_key(&e.channel) {
                    let path = dir.join(file_name(&e.channel, "csv"));
                    let mut w = csv::Writer::from_path(&path)
                        .with_context(|| format!("creating {}", path.display()))?;
                    w.write_record(order)?;
                    writers.insert(e.channel.clone(), w);
                    counts.insert(e.channel.clone(), (path, 0));
                }
                let mut row = vec![String::new(); order.len()];
                for (k, v) in rows_of(&e) {
                    row[index[&k]] = v;
                }
                writers
                    .get_mut(&e.channel)
                    .expect("opened")
                    .write_record(&row)?;
                counts.get_mut(&e.channel).expect("counted").1 += 1;
            }
            for (_, mut w) in writers {
                w.flush()?;
            }
        }
    }
    Ok(counts.into_iter().map(|(c, (p, n))| (c, p, n)).collect())
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
        assert_eq!(keys, ["a.b", "long", "s", "short[0]", "short[1]"]);
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
