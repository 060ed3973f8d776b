//! The stride LCM message types.
//!
//! The `.lcm` sources in `lcmtypes/lcm/stride/` are the single definition shared by C, Rust,
//! Java and Python. Each Rust type here encodes byte for byte as `lcm-gen`'s C code does and
//! carries the same fingerprint (checked by the tests against vectors produced by `lcm-gen -c`).

pub mod stride;

/// Looks up a stride type name by the fingerprint found in the first 8 bytes of a message.
pub fn type_name_for_fingerprint(fingerprint: u64) -> Option<&'static str> {
    use lcm::Message;
    use stride::*;
    [
        (HeaderT::FINGERPRINT, HeaderT::TYPE_NAME),
        (NodeStatusT::FINGERPRINT, NodeStatusT::TYPE_NAME),
        (PingT::FINGERPRINT, PingT::TYPE_NAME),
    ]
    .into_iter()
    .find(|(f, _)| *f == fingerprint)
    .map(|(_, n)| n)
}
