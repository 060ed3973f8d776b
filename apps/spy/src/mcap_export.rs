//! Export of an LCM log to one MCAP file, for the `mcap` tool and viewers such as Foxglove.
//!
//! Every event of the log on a matching channel becomes one MCAP message, in log order:
//!
//! - a message of a type this build knows is JSON (message encoding `json`), as
//!   `stride_lcmtypes`'s `to_json` writes it: members in declaration order, NaN and infinities
//!   as the strings `"NaN"`, `"inf"`, `"-inf"`. Its MCAP channel has the LCM channel as topic
//!   and a schema named after the LCM type (`stride.joint_state_t`), encoding `jsonschema`,
//!   holding that type's JSON Schema. Foxglove's JSON Schema reader takes no array of arrays,
//!   so in both the message and the schema every array of arrays (a member with two or more
//!   dimensions) is an array of objects, each holding one inner array under the key `values`
//!   (for three dimensions, nested again the same way): `positions: [[..], [..]]` is written
//!   `positions: [{"values": [..]}, {"values": [..]}]`, read as `.positions[1].values[0]`
//!   (`stride_lcmtypes::nested`). `echo` and the JSON and CSV exports keep the plain arrays;
//! - a message this build cannot decode (unknown fingerprint, or broken) keeps its LCM bytes,
//!   as logged, on a channel with the same topic, message encoding `lcm` and no schema; nothing
//!   is dropped, and the export counts these messages per channel.
//!
//! An LCM channel that carries several types gets one MCAP channel per type, all with its name
//! as topic. Log time and publish time are both the event's log timestamp (µs, written in ns);
//! the sequence is the event's number in the log (its low 32 bits). Chunks are not compressed.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use anyhow::Context;
use mcap::records::MessageHeader;

use crate::export::ChannelExport;

/// The schema encoding of the JSON messages' schemas.
pub const SCHEMA_ENCODING: &str = "jsonschema";
/// The message encoding of decoded messages.
pub const JSON_ENCODING: &str = "json";
/// The message encoding of messages kept as LCM bytes (no schema).
pub const LCM_ENCODING: &str = "lcm";

/// The MCAP file for `log` in `dir`: the log's name with `.mcap` for its extension
/// (`rec.lcmlog` gives `rec.mcap`), or added to it when the extension is lcm-logger's numeric
/// suffix (`lcmlog-2024-05-01.00` gives `lcmlog-2024-05-01.00.mcap`).
pub fn mcap_path(log: &Path, dir: &Path) -> PathBuf {
    let name = log
        .file_name()
        .map_or_else(|| "log".into(), |n| n.to_string_lossy().into_owned());
    let numeric = log
        .extension()
        .is_some_and(|e| e.to_string_lossy().bytes().all(|b| b.is_ascii_digit()));
    let stem = match log.file_stem() {
        Some(s) if !numeric => s.to_string_lossy().into_owned(),
        _ => name,
    };
    dir.join(format!("{stem}.mcap"))
}

/// The event's log timestamp (µs) in ns, as MCAP keeps it.
fn nanoseconds(e: &lcm::LogEvent) -> anyhow::Result<u64> {
    u64::try_from(e.timestamp)
        .ok()
        .and_then(|us| us.checked_mul(1000))
        .with_context(|| {
            format!(
                "event {} on {}: its timestamp ({} µs) does not fit MCAP's time (ns since 1970, unsigned 64 bits)",
                e.number, e.channel, e.timestamp
            )
        })
}

/// Writes the events of `log` on channels matching `filter` into the MCAP file `path`; returns
/// the messages written per channel. The file appears whole or not at all (it is written
/// beside `path` and renamed).
pub fn export_mcap(
    log: &Path,
    path: &Path,
    filter: &regex::Regex,
) -> anyhow::Result<Vec<ChannelExport>> {
    let partial = path.with_extension("mcap.partial");
    let result = write_mcap(log, &partial, path, filter);
    match result {
        Ok(counts) if !counts.is_empty() => {
            std::fs::rename(&partial, path)
                .with_context(|| format!("renaming {} to {}", partial.display(), path.display()))?;
            Ok(counts)
        }
        other => {
            let _ = std::fs::remove_file(&partial);
            other
        }
    }
}

fn write_mcap(
    log: &Path,
    partial: &Path,
    path: &Path,
    filter: &regex::Regex,
) -> anyhow::Result<Vec<ChannelExport>> {
    let file = std::fs::File::create(partial)
        .with_context(|| format!("creating {}", partial.display()))?;
    let options = mcap::WriteOptions::new()
        .compression(None)
        .library(concat!("stride-spy ", env!("CARGO_PKG_VERSION")));
    let mut out = options.create(std::io::BufWriter::new(file))?;
    // MCAP channel by (LCM channel, type; None for the LCM bytes).
    let mut channels: HashMap<(String, Option<&'static str>), u16> = HashMap::new();
    let mut counts: BTreeMap<String, ChannelExport> = BTreeMap::new();
    for e in lcm::LogReader::open(log)?.filter(|e| filter.is_match(&e.channel)) {
        let (ty, data) = match stride_lcmtypes::decode_nested_json(&e.data) {
            Some((ty, Ok(value))) => (Some(ty), serde_json::to_vec(&value)?),
            _ => (None, e.data.clone()),
        };
        let key = (e.channel.clone(), ty);
        let channel_id = match channels.get(&key) {
            Some(&id) => id,
            None => {
                let id = match ty {
                    Some(ty) => {
                        let schema = stride_lcmtypes::nested_json_schema(ty)
                            .with_context(|| format!("no JSON Schema for {ty}"))?;
                        let schema_id = out.add_schema(ty, SCHEMA_ENCODING, schema.as_bytes())?;
                        out.add_channel(schema_id, &e.channel, JSON_ENCODING, &BTreeMap::new())?
                    }
                    None => out.add_channel(0, &e.channel, LCM_ENCODING, &BTreeMap::new())?,
                };
                channels.insert(key, id);
                id
            }
        };
        let time = nanoseconds(&e)?;
        out.write_to_known_channel(
            &MessageHeader {
                channel_id,
                sequence: e.number as u32,
                log_time: time,
                publish_time: time,
            },
            &data,
        )?;
        let c = counts
            .entry(e.channel.clone())
            .or_insert_with(|| ChannelExport {
                channel: e.channel.clone(),
                path: path.to_owned(),
                messages: 0,
                undecoded: 0,
            });
        c.messages += 1;
        c.undecoded += u64::from(ty.is_none());
    }
    out.finish()?;
    out.into_inner()
        .into_inner()
        .map_err(|e| e.into_error())
        .and_then(|f| f.sync_all())
        .with_context(|| format!("writing {}", partial.display()))?;
    Ok(counts.into_values().collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mcap_file_names() {
        let d = Path::new("out");
        assert_eq!(mcap_path(Path::new("/x/rec.lcmlog"), d), d.join("rec.mcap"));
        assert_eq!(
            mcap_path(Path::new("lcmlog-2024-05-01.00"), d),
            d.join("lcmlog-2024-05-01.00.mcap")
        );
        assert_eq!(mcap_path(Path::new("walk"), d), d.join("walk.mcap"));
    }

    #[test]
    fn a_time_mcap_cannot_hold_is_refused_and_leaves_no_file() {
        let dir = tempfile::tempdir().unwrap();
        let log = dir.path().join("old.lcmlog");
        let mut w = lcm::LogWriter::create(&log).unwrap();
        w.write(5, "A", b"first").unwrap();
        w.write(-1, "A", b"before 1970").unwrap();
        drop(w);
        let out = dir.path().join("old.mcap");
        let all = crate::channel_filter(".*").unwrap();
        let e = export_mcap(&log, &out, &all).unwrap_err().to_string();
        assert!(e.contains("event 1 on A") && e.contains("-1 µs"), "{e}");
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            1,
            "only the log"
        );
    }
}
