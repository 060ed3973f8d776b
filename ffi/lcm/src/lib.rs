//! Safe Rust interface to the C LCM library (`liblcm`).
//!
//! * [`Lcm`] owns one LCM instance (`udpm://`, `memq://`, `file://`, … URLs), dispatches
//!   received messages to subscription callbacks in [`Lcm::handle`] /
//!   [`Lcm::handle_timeout`], and exposes its file descriptor for `poll`-style loops.
//! * [`Publisher`] is a cheap, cloneable, thread-safe handle for publishing from any thread.
//! * [`Message`] is the trait implemented by the generated LCM types: encoding, decoding and the
//!   lcm-gen fingerprint. Typed subscriptions decode for you and count what does not decode.
//! * [`LogReader`] / [`LogWriter`] read and write LCM event logs (the `lcm-logger` format)
//!   through liblcm's eventlog API.
//!
//! # Threads
//! liblcm's handle functions must only be called from one thread at a time, while publishing
//! is safe from anywhere. The types enforce that: [`Lcm`] is `Send` but not `Sync` (it can move
//! to a thread, handling happens there), [`Publisher`] is `Send + Sync + Clone`, and every
//! callback is `FnMut + Send + 'static`. Publishes are serialised by a lock, because some
//! liblcm providers (`tcpq://`) do not serialise them themselves.
//!
//! # Failures inside callbacks
//! A panic in a callback is caught before it can unwind into C, logged, counted in
//! [`Stats::handler_panics`] and the loop goes on. A message that does not decode on a typed
//! subscription is logged and counted in [`Stats::decode_errors`].
//!
//! # Lost messages
//! liblcm drops messages without a word (a full subscription queue, a full kernel buffer, a
//! lost fragment). For message types that carry a sequence number, typed subscriptions count
//! the gaps: [`SubscriptionStats::lost`] (and [`Stats::lost`], its sum over an instance) is the
//! number of sequence numbers skipped within one publisher's stream on one channel. liblcm does
//! not say who sent a message, so publishers are told apart by their numbers
//! ([`SequenceTracker`]): a number that follows no known stream closely (another publisher, a
//! restart, a log replay, a jump of more than [`SequenceTracker::MAX_GAP`]) starts a stream,
//! counted in [`SubscriptionStats::sequence_streams`], and nothing is counted lost for it.

mod clock;
mod codec;
mod error;
mod eventlog;
mod instance;
mod random;
mod sequence;

pub use clock::now_utime;
pub use codec::{DecodeError, Decoder, EncodeError, Encoder, Message};
pub use error::{Error, Result};
pub use eventlog::{capturing_stderr, event_size, LogEvent, LogReader, LogWriter};
pub use instance::{
    default_url, Lcm, Publisher, RecvInfo, Stats, Subscription, SubscriptionStats, DEFAULT_URL,
    MAX_CHANNEL_LEN,
};
pub use random::{Random, Rng};
pub use sequence::SequenceTracker;

/// True when the linked liblcm can report subscription queue sizes (liblcm >= 1.4).
pub const HAS_QUEUE_SIZE: bool = lcm_sys::HAS_QUEUE_SIZE;
