//! The logic of `stride-spy`: channel statistics, messages as JSON, log export (CSV, JSON
//! lines, MCAP), and its command line ([`Cli`], [`run`]).
//!
//! Messages are decoded by `stride_lcmtypes`'s `to_json`: members in the `.lcm` declaration
//! order, and floats that are NaN or infinite (JSON has no number for them) as the strings
//! `"NaN"`, `"inf"` and `"-inf"`, so the three stay apart. CSV cells are `NaN`, `inf`, `-inf`.

mod app;
pub mod export;
pub mod mcap_export;
pub mod summary;

pub use app::{run, Cli};

use serde_json::{json, Value};

/// One message as a JSON object: channel, receive time, type and decoded value (or, for a type
/// this build does not know, its fingerprint and size). The value's members come in
/// declaration order; NaN and infinities are the strings `"NaN"`, `"inf"`, `"-inf"`.
pub fn message_json(channel: &str, utime: i64, data: &[u8]) -> Value {
    match stride_lcmtypes::decode_json(data) {
        Some((ty, Ok(value))) => json!({
            "channel": channel, "utime": utime, "type": ty, "message": value,
        }),
        Some((ty, Err(e))) => json!({
            "channel": channel, "utime": utime, "type": ty, "size": data.len(),
            "error": format!("does not decode: {e}"),
        }),
        None => json!({
            "channel": channel, "utime": utime, "type": null, "size": data.len(),
            "fingerprint": data.get(..8).map(|b| b.iter().map(|x| format!("{x:02x}")).collect::<String>()),
        }),
    }
}

/// A channel filter: a regular expression anchored at both ends, as in LCM subscriptions.
pub fn channel_filter(pattern: &str) -> Result<regex::Regex, regex::Error> {
    regex::Regex::new(&format!("^(?:{pattern})$"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use lcm::Message;

    #[test]
    fn json_of_known_unknown_and_broken() {
        let ping = stride_lcmtypes::stride::PingT {
            payload_size: 1,
            payload: vec![7],
            ..Default::default()
        }
        .encode()
        .unwrap();
        let v = message_json("P", 5, &ping);
        assert_eq!(v["type"], "stride.ping_t");
        assert_eq!(v["message"]["payload"][0], 7);
        let v = message_json("X", 5, b"0123456789");
        assert!(v["type"].is_null());
        assert_eq!(v["fingerprint"], "3031323334353637");
        let v = message_json("P", 5, &ping[..ping.len() - 1]);
        assert!(v["error"].as_str().unwrap().contains("does not decode"));
        let f = channel_filter("JOINT_.*").unwrap();
        assert!(f.is_match("JOINT_STATE") && !f.is_match("XJOINT_STATE"));
    }
}
