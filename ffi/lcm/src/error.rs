//! Errors of the LCM wrapper.

use std::path::PathBuf;

/// Result alias for this crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// What went wrong in a call into liblcm.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// `lcm_create` refused the URL.
    #[error(
        "could not create an LCM instance for URL {url:?}: check the provider and its options \
         (udpm://ADDR:PORT?ttl=N&recv_buf_size=N, memq://, file://PATH?mode=r|w); for udpm a \
         multicast route must exist (e.g. `ip route add 224.0.0.0/4 dev lo`)"
    )]
    Create {
        /// The URL as given (after the default was substituted).
        url: String,
    },
    /// `lcm_create` found no `tcpq://` server to connect to (or refused the URL's host or
    /// port; liblcm prints which).
    #[error("LCM URL {url}: cannot reach the server")]
    Connect {
        /// The URL.
        url: String,
    },
    /// The instance has no file descriptor to wait on: a `tcpq://` connection broke, or
    /// `udpm://` could not set up receiving.
    #[error(
        "LCM URL {url}: the instance has no descriptor to wait on (a tcpq:// server connection \
         broke, or udpm:// could not set up receiving)"
    )]
    NoDescriptor {
        /// The instance's URL.
        url: String,
    },
    /// A channel name is empty, longer than 63 bytes or contains a NUL byte.
    #[error("invalid channel name {channel:?}: {reason}")]
    Channel {
        /// The offending name.
        channel: String,
        /// Why it was refused.
        reason: &'static str,
    },
    /// A local bus's channel pattern is not a regular expression.
    #[error("local bus channel pattern {pattern:?}: {reason}")]
    Route {
        /// The pattern.
        pattern: String,
        /// Why it was refused.
        reason: String,
    },
    /// A subscription pattern contains a NUL byte or was refused by liblcm.
    #[error("could not subscribe to {pattern:?}")]
    Subscribe {
        /// The channel regex.
        pattern: String,
    },
    /// `lcm_publish` returned an error.
    #[error("publishing {len} bytes on channel {channel:?} failed")]
    Publish {
        /// The channel.
        channel: String,
        /// The payload size.
        len: usize,
    },
    /// A message is larger than liblcm accepts (`LCM_MAX_MESSAGE_SIZE`).
    #[error("message of {len} bytes on {channel:?} exceeds LCM's limit of {max} bytes")]
    TooLarge {
        /// The channel.
        channel: String,
        /// The payload size.
        len: usize,
        /// The limit.
        max: usize,
    },
    /// Encoding a typed message failed.
    #[error("encoding for channel {channel:?} failed: {source}")]
    Encode {
        /// The channel.
        channel: String,
        /// The cause.
        #[source]
        source: crate::EncodeError,
    },
    /// `lcm_handle` returned an error (a `file://` reader also returns this at the end of the log).
    #[error("lcm_handle failed on {url:?} (end of log for file:// readers)")]
    Handle {
        /// The instance's URL.
        url: String,
    },
    /// An event log could not be opened.
    #[error("could not open LCM log {path:?} (mode {mode}): {cause}")]
    LogOpen {
        /// The file.
        path: PathBuf,
        /// `r`, `w` or `a`.
        mode: &'static str,
        /// The OS error (in the message, not again as a source: one line says it once).
        cause: std::io::Error,
    },
    /// Writing an event to a log failed.
    #[error("writing an event to LCM log {path:?} failed")]
    LogWrite {
        /// The file.
        path: PathBuf,
    },
    /// Seeking in a log failed.
    #[error("seeking to timestamp {timestamp} in LCM log {path:?} failed")]
    LogSeek {
        /// The file.
        path: PathBuf,
        /// The target (µs since the epoch).
        timestamp: i64,
    },
}
